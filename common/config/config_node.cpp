#include "config/config_node.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "util/strings.hpp"

namespace vslam::config {

std::string rangeText(const InRange& range) {
  std::ostringstream os;
  if (std::isinf(range.min) && std::isinf(range.max)) return "";
  if (std::isinf(range.max)) {
    if (range.min == std::numeric_limits<double>::min()) return "> 0";
    os << ">= " << range.min;
  } else if (std::isinf(range.min)) {
    os << "<= " << range.max;
  } else {
    os << "[" << range.min << ", " << range.max << "]";
  }
  return os.str();
}

namespace {

// "a number in [a, b]", "a number >= a", ... (the bounds as rangeText writes them).
std::string describeRange(const InRange& r) {
  const std::string bounds = rangeText(r);
  if (bounds.empty()) return "a number";
  return bounds[0] == '[' ? "a number in " + bounds : "a number " + bounds;
}

const char* typeName(const YAML::Node& n);

// YAML allows a list or a mapping as a key; a config has names only. Such a
// key is named by what it is, for the error that refuses it.
std::string keyText(const YAML::Node& key) {
  return key.IsScalar() ? key.Scalar() : std::string("(") + typeName(key) + " as a key)";
}

const char* typeName(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Null:
      return "nothing (null)";
    case YAML::NodeType::Scalar:
      return "a scalar";
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Map:
      return "a mapping";
    default:
      return "undefined";
  }
}

// YAML 1.2 core-schema words only: "yes"/"on" are strings, not booleans.
bool parseBool(const std::string& s, bool* out) {
  if (s == "true" || s == "True" || s == "TRUE") return *out = true, true;
  if (s == "false" || s == "False" || s == "FALSE") return *out = false, true;
  return false;
}

bool parseDouble(const std::string& s, double* out) {
  if (s.empty()) return false;
  const char* begin = s.c_str();
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(begin, &end);
  if (end != begin + s.size() || errno == ERANGE) return false;
  *out = v;
  return true;
}

}  // namespace

ConfigError::ConfigError(std::string file, std::string key, std::string problem, int line)
    : std::runtime_error(file + (line > 0 ? ":" + std::to_string(line) : std::string()) + ": " +
                         (key.empty() ? std::string() : key + ": ") + problem),
      file_(std::move(file)),
      key_(std::move(key)),
      problem_(std::move(problem)),
      line_(line) {}

ConfigNode::ConfigNode(std::shared_ptr<const Document> doc, YAML::Node node, std::string path)
    : doc_(std::move(doc)),
      node_(std::move(node)),
      path_(std::move(path)),
      used_(std::make_shared<std::set<std::string>>()) {}

ConfigNode ConfigNode::loadFile(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw ConfigError(file.string(), "", "cannot open the configuration file");
  std::stringstream text;
  text << in.rdbuf();
  return loadString(text.str(), file.string(),
                    file.parent_path().empty() ? "." : file.parent_path());
}

ConfigNode ConfigNode::loadString(const std::string& yaml, const std::string& origin,
                                  const std::filesystem::path& base_dir) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml);
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin, "",
                      "YAML syntax error at line " + std::to_string(e.mark.line + 1) + ", column " +
                          std::to_string(e.mark.column + 1) + ": " + e.msg);
  }
  if (!root.IsMap()) {
    throw ConfigError(origin, "",
                      std::string("expected a mapping at the top level, found ") + typeName(root));
  }
  auto doc = std::make_shared<Document>(Document{origin, base_dir, {}});
  return ConfigNode(doc, root, "");
}

std::string ConfigNode::childPath(const std::string& key) const {
  return path_.empty() ? key : path_ + "." + key;
}

ConfigError ConfigNode::error(const std::string& key, const std::string& problem) const {
  return ConfigError(doc_->file, childPath(key), problem, lineOf(key));
}

int ConfigNode::lineOf(const std::string& key) const {
  // "name[3]" refers to the 4th element of the list under "name".
  std::string base = key;
  int index = -1;
  if (const auto open = key.find('['); open != std::string::npos && key.back() == ']') {
    base = key.substr(0, open);
    index = std::atoi(key.c_str() + open + 1);
  }
  if (node_.IsMap()) {
    for (const auto& kv : node_) {
      if (kv.first.Scalar() != base) continue;
      if (index >= 0 && kv.second.IsSequence() && index < static_cast<int>(kv.second.size())) {
        return kv.second[static_cast<size_t>(index)].Mark().line + 1;
      }
      return kv.first.Mark().line + 1;
    }
  }
  // Not present: the line of the mapping it belongs in.
  return node_.Mark().line >= 0 ? node_.Mark().line + 1 : 0;
}

bool ConfigNode::has(const std::string& key) const {
  return node_.IsMap() && node_[key].IsDefined() && !node_[key].IsNull();
}

std::vector<std::string> ConfigNode::keys() const {
  std::vector<std::string> out;
  for (const auto& kv : node_) {
    if (!kv.first.IsScalar()) throw error(keyText(kv.first), "a key must be a name");
    out.push_back(kv.first.Scalar());
  }
  return out;
}

void ConfigNode::markUsed(const std::string& key) const { used_->insert(key); }

void ConfigNode::set(const std::string& key, const std::string& value) const {
  YAML::Node handle = node_;  // shares the document's node
  handle[key] = value;
}

ConfigNode ConfigNode::child(const std::string& key) const {
  markUsed(key);
  if (!has(key)) throw missing(key, "a mapping");
  YAML::Node n = node_[key];
  if (!n.IsMap()) throw error(key, std::string("expected a mapping, found ") + typeName(n));
  return ConfigNode(doc_, n, childPath(key));
}

std::vector<ConfigNode> ConfigNode::sequence(const std::string& key) const {
  markUsed(key);
  if (!has(key)) throw missing(key, "a list");
  YAML::Node n = node_[key];
  if (!n.IsSequence()) throw error(key, std::string("expected a list, found ") + typeName(n));
  std::vector<ConfigNode> out;
  for (size_t i = 0; i < n.size(); ++i) {
    if (!n[i].IsMap()) {
      throw error(key + "[" + std::to_string(i) + "]",
                  std::string("expected a mapping, found ") + typeName(n[i]));
    }
    out.push_back(ConfigNode(doc_, n[i], childPath(key) + "[" + std::to_string(i) + "]"));
  }
  return out;
}

ConfigError ConfigNode::missing(const std::string& key, const std::string& what) const {
  std::string problem = "missing (expected " + what + ")";
  // A required key is most often "missing" because it is misspelt: name the culprit.
  if (node_.IsMap()) {
    for (const auto& kv : node_) {
      const std::string other = keyText(kv.first);
      if (other != key && !used_->count(other) && editDistance(other, key) <= 2) {
        problem += "; the unknown key '" + other + "' looks like a misspelling of it";
        break;
      }
    }
  }
  return error(key, problem);
}

YAML::Node ConfigNode::scalar(const std::string& key, const char* what) const {
  markUsed(key);
  if (!has(key)) throw missing(key, what);
  YAML::Node n = node_[key];
  if (!n.IsScalar()) {
    throw error(key, std::string("expected ") + what + ", found " + typeName(n));
  }
  return n;
}

double ConfigNode::getDouble(const std::string& key, InRange range) const {
  const YAML::Node n = scalar(key, describeRange(range).c_str());
  double v = 0;
  if (!parseDouble(n.Scalar(), &v) || !std::isfinite(v)) {
    throw error(key, "expected " + describeRange(range) + ", found '" + n.Scalar() + "'");
  }
  if (v < range.min || v > range.max) {
    std::ostringstream os;
    os << "expected " << describeRange(range) << ", found " << v;
    throw error(key, os.str());
  }
  return record(key, v, false);
}

int64_t ConfigNode::getInt(const std::string& key, InRange range) const {
  const std::string what = "an integer" + describeRange(range).substr(8);
  const YAML::Node n = scalar(key, what.c_str());
  double v = 0;
  if (!parseDouble(n.Scalar(), &v) || v != std::floor(v) || std::abs(v) > 9.0e15) {
    throw error(key, "expected " + what + ", found '" + n.Scalar() + "'");
  }
  if (v < range.min || v > range.max) {
    throw error(key, "expected " + what + ", found " + n.Scalar());
  }
  return record(key, static_cast<int64_t>(v), false);
}

bool ConfigNode::getBool(const std::string& key) const {
  const YAML::Node n = scalar(key, "true or false");
  bool v = false;
  if (n.Tag() == "!" || !parseBool(n.Scalar(), &v)) {
    throw error(key, "expected true or false, found '" + n.Scalar() + "'");
  }
  return record(key, v, false);
}

std::string ConfigNode::getString(const std::string& key, bool allow_empty) const {
  const YAML::Node n = scalar(key, "a string");
  if (!allow_empty && n.Scalar().empty()) throw error(key, "expected a non-empty string");
  return record(key, n.Scalar(), false);
}

std::string ConfigNode::getEnum(const std::string& key,
                                const std::vector<std::string>& allowed) const {
  std::string joined;
  for (const auto& a : allowed) joined += (joined.empty() ? "" : ", ") + a;
  const YAML::Node n = scalar(key, ("one of: " + joined).c_str());
  if (std::find(allowed.begin(), allowed.end(), n.Scalar()) == allowed.end()) {
    throw error(key, "expected one of: " + joined + "; found '" + n.Scalar() + "'");
  }
  return n.Scalar();
}

std::filesystem::path expandUserPath(const std::string& path) {
  const auto home = [](const std::string& what) {
    const char* h = std::getenv("HOME");
    if (h == nullptr || *h != '/') {
      throw std::runtime_error(what + " needs $HOME, which is not set to an absolute path");
    }
    return std::filesystem::path(h);
  };
  if (path == "~" || path.rfind("~/", 0) == 0)
    return home("'~'") / path.substr(std::min<size_t>(2, path.size()));
  static const std::string kData = "$XDG_DATA_HOME";
  if (path == kData || path.rfind(kData + "/", 0) == 0) {
    // XDG base directories: a relative value is invalid and ignored.
    const char* x = std::getenv("XDG_DATA_HOME");
    const std::filesystem::path data =
        x != nullptr && *x == '/' ? std::filesystem::path(x) : home(kData) / ".local/share";
    return path.size() > kData.size() + 1 ? data / path.substr(kData.size() + 1) : data;
  }
  return path;
}

std::filesystem::path ConfigNode::getPath(const std::string& key, bool must_exist) const {
  const std::string raw = getString(key);
  std::filesystem::path p;
  try {
    p = expandUserPath(raw);
  } catch (const std::runtime_error& e) {
    throw error(key, e.what());
  }
  if (p.is_relative()) p = doc_->base_dir / p;
  p = p.lexically_normal();
  // The error_code form: a name the system refuses (too long, a bad
  // component) is a config error like a missing file, not an exception of
  // the filesystem library (found by fuzzing: tests/fuzz/fuzz_config).
  std::error_code ec;
  if (must_exist && !std::filesystem::exists(p, ec)) {
    throw error(key, "file '" + raw + "' not found (looked for " + p.string() + ")" +
                         (ec ? ": " + ec.message() : std::string()));
  }
  record(key, p.string(), false);
  return p;
}

std::string ConfigNode::getChannel(const std::string& key) const {
  const std::string c = getString(key);
  const bool upper_snake = std::isupper(static_cast<unsigned char>(c[0])) &&
                           std::all_of(c.begin(), c.end(), [](char ch) {
                             return std::isupper(static_cast<unsigned char>(ch)) ||
                                    std::isdigit(static_cast<unsigned char>(ch)) || ch == '_';
                           });
  if (!upper_snake) {
    throw error(key, "expected an LCM channel name in UPPER_SNAKE_CASE, found '" + c + "'");
  }
  return c;
}

std::vector<double> ConfigNode::getDoubles(const std::string& key, size_t expected_size,
                                           InRange range) const {
  markUsed(key);
  const std::string what =
      "a list of " + std::to_string(expected_size) + " numbers" +
      (std::isinf(range.min) && std::isinf(range.max) ? ""
                                                      : " each " + describeRange(range).substr(2));
  if (!has(key)) throw missing(key, what);
  const YAML::Node n = node_[key];
  if (!n.IsSequence() || n.size() != expected_size) {
    throw error(key, "expected " + what + ", found " +
                         (n.IsSequence() ? "a list of " + std::to_string(n.size()) : typeName(n)));
  }
  std::vector<double> out;
  for (size_t i = 0; i < n.size(); ++i) {
    double v = 0;
    if (!n[i].IsScalar() || !parseDouble(n[i].Scalar(), &v) || !std::isfinite(v) || v < range.min ||
        v > range.max) {
      throw error(key + "[" + std::to_string(i) + "]",
                  "expected " + describeRange(range) + ", found '" +
                      (n[i].IsScalar() ? n[i].Scalar() : typeName(n[i])) + "'");
    }
    out.push_back(v);
  }
  std::ostringstream text;
  for (size_t i = 0; i < out.size(); ++i) text << (i ? ", " : "[") << out[i];
  record(key, text.str() + "]", false);
  return out;
}

std::vector<std::vector<double>> ConfigNode::getDoubleRows(const std::string& key, size_t row_size,
                                                           InRange range) const {
  markUsed(key);
  const std::string what = "a list of [" + std::to_string(row_size) + " numbers] rows";
  if (!has(key)) throw missing(key, what);
  const YAML::Node n = node_[key];
  if (!n.IsSequence()) throw error(key, "expected " + what + ", found " + typeName(n));
  std::vector<std::vector<double>> rows;
  for (size_t i = 0; i < n.size(); ++i) {
    const std::string item = key + "[" + std::to_string(i) + "]";
    if (!n[i].IsSequence() || n[i].size() != row_size) {
      throw error(item, "expected a list of " + std::to_string(row_size) + " numbers");
    }
    std::vector<double> row;
    for (size_t j = 0; j < row_size; ++j) {
      double v = 0;
      if (!n[i][j].IsScalar() || !parseDouble(n[i][j].Scalar(), &v) || !std::isfinite(v) ||
          v < range.min || v > range.max) {
        throw error(item, "expected " + describeRange(range) + " at position " + std::to_string(j) +
                              ", found '" +
                              (n[i][j].IsScalar() ? n[i][j].Scalar() : typeName(n[i][j])) + "'");
      }
      row.push_back(v);
    }
    rows.push_back(row);
  }
  record(key, std::to_string(rows.size()) + " rows", false);
  return rows;
}

std::vector<std::string> ConfigNode::getStrings(const std::string& key) const {
  markUsed(key);
  if (!has(key)) throw missing(key, "a list of strings");
  const YAML::Node n = node_[key];
  if (!n.IsSequence())
    throw error(key, std::string("expected a list of strings, found ") + typeName(n));
  std::vector<std::string> out;
  for (size_t i = 0; i < n.size(); ++i) {
    if (!n[i].IsScalar() || n[i].Scalar().empty()) {
      throw error(key + "[" + std::to_string(i) + "]", "expected a non-empty string");
    }
    out.push_back(n[i].Scalar());
  }
  return out;
}

double ConfigNode::getDouble(const std::string& key, double fallback, InRange range) const {
  if (!has(key)) {
    markUsed(key);
    return record(key, fallback, true);
  }
  return getDouble(key, range);
}

int64_t ConfigNode::getInt(const std::string& key, int64_t fallback, InRange range) const {
  if (!has(key)) {
    markUsed(key);
    return record(key, fallback, true);
  }
  return getInt(key, range);
}

bool ConfigNode::getBool(const std::string& key, bool fallback) const {
  if (!has(key)) {
    markUsed(key);
    return record(key, fallback, true);
  }
  return getBool(key);
}

std::string ConfigNode::getString(const std::string& key, const std::string& fallback) const {
  if (!has(key)) {
    markUsed(key);
    return record(key, fallback, true);
  }
  return getString(key);
}

template <class T>
T ConfigNode::record(const std::string& key, T value, bool is_default) const {
  std::ostringstream text;
  if constexpr (std::is_same_v<T, bool>) {
    text << (value ? "true" : "false");
  } else {
    text << value;
  }
  doc_->resolved.push_back({childPath(key), text.str(), is_default});
  return value;
}

std::vector<ResolvedValue> ConfigNode::resolvedValues(const std::string& prefix) const {
  // A key read more than once (e.g. `role`) is listed once, at its first read.
  std::vector<ResolvedValue> out;
  std::set<std::string> seen;
  for (const auto& r : doc_->resolved) {
    if (r.key.rfind(prefix, 0) == 0 && seen.insert(r.key).second) out.push_back(r);
  }
  return out;
}

void ConfigNode::requireAllKeysUsed() const {
  if (!node_.IsMap()) return;
  std::vector<std::string> known(used_->begin(), used_->end());
  for (const auto& kv : node_) {
    const std::string key = keyText(kv.first);
    if (!kv.first.IsScalar()) throw error(key, "a key must be a name");
    if (used_->count(key)) continue;
    std::string best;
    size_t best_d = 1000;
    for (const auto& k : known) {
      const size_t d = editDistance(key, k);
      if (d < best_d) best_d = d, best = k;
    }
    std::string problem = "unknown key";
    if (!best.empty() && best_d <= std::max<size_t>(2, key.size() / 3)) {
      problem += " (did you mean '" + best + "'?)";
    }
    if (!known.empty()) {
      std::string list;
      for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
      problem += "; known keys here: " + list;
    }
    throw error(key, problem);
  }
}

}  // namespace vslam::config
