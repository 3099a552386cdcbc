#pragma once
// What the command lines of vslam-eval and vslam-import share on top of
// CLI11: option values that must parse completely (finite numbers, pixel
// sizes, named choices, number lists). The parse itself is
// util/command_line.hpp's, as for every binary.

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

namespace vslam::eval {

// A finite number (not nan or inf), or one that is also > 0.
CLI::Validator finiteNumber();
CLI::Validator positiveNumber();

// "WxH" (e.g. 640x480) into *size, at least `minimum`; the default shown is *size's value.
CLI::Option* addSizeOption(CLI::App& app, const std::string& name, cv::Size* size,
                           const std::string& description, cv::Size minimum = {1, 1});
CLI::Option* addSizeOption(CLI::App& app, const std::string& name, std::optional<cv::Size>* size,
                           const std::string& description);

// Exactly three comma-separated finite numbers, e.g. 0.1,0,0.3.
CLI::Option* addTripleOption(CLI::App& app, const std::string& name, Eigen::Vector3d* values,
                             const std::string& description);

// A word that `parse` turns into a value; `expected` lists the words for the
// error message.
template <class T>
CLI::Option* addChoiceOption(CLI::App& app, const std::string& name, T* value,
                             std::optional<T> (*parse)(const std::string&),
                             const std::string& expected, const std::string& description) {
  return app
      .add_option_function<std::string>(
          name,
          [=](const std::string& word) {
            const std::optional<T> v = parse(word);
            if (!v) throw CLI::ValidationError(name, "'" + word + "': expected " + expected);
            *value = *v;
          },
          description)
      ->type_name("WORD");
}

}  // namespace vslam::eval
