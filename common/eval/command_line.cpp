#include "eval/command_line.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <ostream>

namespace vslam::eval {
namespace {

// The whole text as a finite number, or nothing.
std::optional<double> toFinite(const std::string& text) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE || !std::isfinite(v)) {
    return std::nullopt;
  }
  return v;
}

cv::Size parseSize(const std::string& name, const std::string& text, cv::Size minimum) {
  const auto bad = [&] {
    return CLI::ValidationError(name, "'" + text + "' is not WIDTHxHEIGHT (e.g. 640x480)");
  };
  const auto x = text.find('x');
  if (x == std::string::npos) throw bad();
  const std::string w = text.substr(0, x), h = text.substr(x + 1);
  for (const auto& part : {w, h}) {
    if (part.empty() || part.size() > 5 ||
        part.find_first_not_of("0123456789") != std::string::npos) {
      throw bad();
    }
  }
  const cv::Size size(std::stoi(w), std::stoi(h));
  if (size.width < 1 || size.height < 1) throw bad();
  if (size.width < minimum.width || size.height < minimum.height) {
    throw CLI::ValidationError(name, "must be at least " + std::to_string(minimum.width) + "x" +
                                         std::to_string(minimum.height));
  }
  return size;
}

std::string sizeText(cv::Size size) {
  return std::to_string(size.width) + "x" + std::to_string(size.height);
}

}  // namespace

CLI::Validator finiteNumber() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        return toFinite(text) ? "" : "'" + text + "' is not a number";
      },
      "NUMBER");
}

CLI::Validator positiveNumber() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        const auto v = toFinite(text);
        if (!v) return "'" + text + "' is not a number";
        return *v > 0 ? "" : "must be > 0, got " + text;
      },
      "POSITIVE");
}

CLI::Option* addSizeOption(CLI::App& app, const std::string& name, cv::Size* size,
                           const std::string& description, cv::Size minimum) {
  return app
      .add_option_function<std::string>(
          name, [=](const std::string& text) { *size = parseSize(name, text, minimum); },
          description)
      ->type_name("WxH")
      ->default_str(sizeText(*size));
}

CLI::Option* addSizeOption(CLI::App& app, const std::string& name, std::optional<cv::Size>* size,
                           const std::string& description) {
  return app
      .add_option_function<std::string>(
          name,
          [=](const std::string& text) {
            *size = parseSize(name, text, {1, 1});
          },
          description)
      ->type_name("WxH");
}

CLI::Option* addTripleOption(CLI::App& app, const std::string& name, Eigen::Vector3d* values,
                             const std::string& description) {
  return app
      .add_option_function<std::string>(
          name,
          [=](const std::string& text) {
            Eigen::Vector3d v;
            std::size_t n = 0, start = 0;
            for (bool more = true; more; ++n) {
              const auto comma = text.find(',', start);
              more = comma != std::string::npos;
              const auto part = toFinite(text.substr(start, more ? comma - start : comma));
              if (!part) throw CLI::ValidationError(name, "'" + text + "' is not a number list");
              if (n < 3) v[static_cast<Eigen::Index>(n)] = *part;
              start = comma + 1;
            }
            if (n != 3) {
              throw CLI::ValidationError(name, "'" + text + "' needs 3 comma-separated numbers");
            }
            *values = v;
          },
          description)
      ->type_name("X,Y,Z");
}

}  // namespace vslam::eval
