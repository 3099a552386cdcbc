#pragma once
// Typed, self-validating access to a YAML configuration.
//
// Every read names the key it wants and what it expects; a ConfigNode
// remembers which keys were read so that, once a parameter struct has taken
// what it knows, requireAllKeysUsed() turns a misspelt or obsolete key into an
// error instead of a silently ignored setting. Errors are ConfigError, which
// carries the file and the full key path; processes turn it into exit code 2.
//
//   ConfigNode cfg = ConfigNode::loadFile("config/vslam.yaml");
//   ConfigNode prefilter = cfg.child("backend").child("prefilter");
//   double max_err = prefilter.getDouble("max_proj_err_rms", InRange{0.0, 100.0});
//   prefilter.requireAllKeysUsed();

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <limits>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace vslam::config {

class ConfigError : public std::runtime_error {
 public:
  // line: 1-based line of the offending key in `file`, 0 if unknown.
  ConfigError(std::string file, std::string key, std::string problem, int line = 0);
  const std::string& file() const { return file_; }
  int line() const { return line_; }
  const std::string& key() const { return key_; }
  const std::string& problem() const { return problem_; }

 private:
  std::string file_, key_, problem_;
  int line_ = 0;
};

// Closed interval check for numbers; open ends with +-infinity.
struct InRange {
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
};
// "[a, b]", ">= a", "> 0", "<= b" or "" (no bound).
std::string rangeText(const InRange& range);
inline InRange positive() { return {std::numeric_limits<double>::min(), InRange{}.max}; }
inline InRange nonNegative() { return {0.0, InRange{}.max}; }

// A path as a config may write it: a leading "~/" is the home directory and a
// leading "$XDG_DATA_HOME/" the user's data folder (that variable when it is
// an absolute path, else ~/.local/share, as the XDG base directory spec
// says), so that what the live stack writes stays out of the checkout.
// Anything else is returned as it is. std::runtime_error when $HOME is
// needed and not set.
std::filesystem::path expandUserPath(const std::string& path);

// A value a parameter struct read, as printed at start-up.
struct ResolvedValue {
  std::string key;    // full key path, e.g. processes.deadreckon.sigma_rotation
  std::string value;  // as text
  bool is_default;    // the key was absent and the documented default applied
};

class ConfigNode {
 public:
  // Parses a YAML file; a missing file or a syntax error is a ConfigError.
  static ConfigNode loadFile(const std::filesystem::path& file);
  // Parses YAML text; `origin` stands for the file name in messages and
  // relative paths resolve against `base_dir`.
  static ConfigNode loadString(const std::string& yaml, const std::string& origin,
                               const std::filesystem::path& base_dir = ".");

  const std::string& file() const { return doc_->file; }
  const std::string& keyPath() const { return path_; }
  std::filesystem::path baseDir() const { return doc_->base_dir; }

  bool has(const std::string& key) const;
  // Keys of this mapping in file order.
  std::vector<std::string> keys() const;

  // Required mapping / sequence children.
  ConfigNode child(const std::string& key) const;
  std::vector<ConfigNode> sequence(const std::string& key) const;

  // Required scalars. Numbers must be numbers, booleans true/false (not
  // strings), strings non-empty unless allow_empty.
  double getDouble(const std::string& key, InRange range = {}) const;
  int64_t getInt(const std::string& key, InRange range = {}) const;
  bool getBool(const std::string& key) const;
  std::string getString(const std::string& key, bool allow_empty = false) const;
  // One of a fixed set of words.
  std::string getEnum(const std::string& key, const std::vector<std::string>& allowed) const;
  // A path, resolved relative to the directory of the file it appears in
  // (never an absolute path in shipped configs) after expandUserPath; must
  // exist if must_exist.
  std::filesystem::path getPath(const std::string& key, bool must_exist = true) const;
  // An LCM channel name: UPPER_SNAKE_CASE.
  std::string getChannel(const std::string& key) const;
  // A fixed-length list of numbers.
  std::vector<double> getDoubles(const std::string& key, size_t expected_size,
                                 InRange range = {}) const;
  std::vector<std::string> getStrings(const std::string& key) const;
  // A list of fixed-length rows of numbers, e.g. waypoints [[x, y], ...].
  std::vector<std::vector<double>> getDoubleRows(const std::string& key, size_t row_size,
                                                 InRange range = {}) const;

  // Optional scalars: the documented default when the key is absent; a key
  // that is present is validated exactly like the required form.
  double getDouble(const std::string& key, double fallback, InRange range) const;
  int64_t getInt(const std::string& key, int64_t fallback, InRange range) const;
  bool getBool(const std::string& key, bool fallback) const;
  std::string getString(const std::string& key, const std::string& fallback) const;
  // (Without this, a literal fallback would convert to the bool above.)
  std::string getString(const std::string& key, const char* fallback) const {
    return getString(key, std::string(fallback));
  }

  // Sets the scalar `key` of this mapping, in the document itself, to `value`:
  // a command-line option that overrides the file (vslam-replay --map).
  void set(const std::string& key, const std::string& value) const;

  // Marks a key as read without reading it (e.g. handled by another layer).
  void markUsed(const std::string& key) const;
  // Throws for the first key of this mapping that nothing read, suggesting
  // the closest known key.
  void requireAllKeysUsed() const;

  // Every value read so far from this document whose key path starts with
  // `prefix`, with defaults marked: what a process prints at start-up.
  std::vector<ResolvedValue> resolvedValues(const std::string& prefix = "") const;

  // Builds an error about `key` of this node.
  ConfigError error(const std::string& key, const std::string& problem) const;

 private:
  struct Document {
    std::string file;
    std::filesystem::path base_dir;
    // Every value read, in order, for printing the effective parameters.
    mutable std::vector<ResolvedValue> resolved;
  };
  template <class T>
  T record(const std::string& key, T value, bool is_default) const;
  ConfigNode(std::shared_ptr<const Document> doc, YAML::Node node, std::string path);
  YAML::Node scalar(const std::string& key, const char* what) const;
  ConfigError missing(const std::string& key, const std::string& what) const;
  int lineOf(const std::string& key) const;
  std::string childPath(const std::string& key) const;

  std::shared_ptr<const Document> doc_;
  YAML::Node node_;
  std::string path_;
  // Shared between copies so that reading through any copy counts.
  std::shared_ptr<std::set<std::string>> used_;
};

}  // namespace vslam::config
