#pragma once
// Small helpers shared by the command lines of vslam-eval and vslam-import:
// option values that must parse completely, or a UsageError naming the option.

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "eval/errors.hpp"

namespace vslam::eval::cli {

// Walks argv; value() takes the next argument as the value of the current option.
class ArgCursor {
 public:
  explicit ArgCursor(std::vector<std::string> args) : args_(std::move(args)) {}
  bool done() const { return i_ >= args_.size(); }
  const std::string& next() { return args_[i_++]; }
  std::string value(const std::string& option) {
    if (done()) throw UsageError(option + " needs a value");
    return next();
  }

 private:
  std::vector<std::string> args_;
  std::size_t i_ = 0;
};

inline double parseDouble(const std::string& option, const std::string& text) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE || !std::isfinite(v)) {
    throw UsageError(option + " '" + text + "' is not a number");
  }
  return v;
}

inline double parsePositive(const std::string& option, const std::string& text) {
  const double v = parseDouble(option, text);
  if (!(v > 0)) throw UsageError(option + " must be > 0, got " + text);
  return v;
}

// "WxH", e.g. 640x480.
inline cv::Size parseSize(const std::string& option, const std::string& text) {
  const auto x = text.find('x');
  const auto bad = [&] {
    return UsageError(option + " '" + text + "' is not WIDTHxHEIGHT (e.g. 640x480)");
  };
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
  return size;
}

// Comma-separated numbers, exactly n of them.
inline std::vector<double> parseList(const std::string& option, const std::string& text,
                                     std::size_t n) {
  std::vector<double> out;
  std::size_t start = 0;
  while (start <= text.size()) {
    const auto comma = text.find(',', start);
    const std::string part =
        text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    out.push_back(parseDouble(option, part));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (out.size() != n) {
    throw UsageError(option + " '" + text + "' needs " + std::to_string(n) +
                     " comma-separated numbers");
  }
  return out;
}

}  // namespace vslam::eval::cli
