#pragma once
// A small JSON reader for tests: parses the whole text (throws on any syntax
// error, so it also checks that vslam-eval writes valid JSON) into a tree
// that tests index by key and position.

#include <cctype>
#include <cstdlib>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace vslam::test {

struct JsonValue {
  enum class Type { kNull, kBool, kNumber, kString, kArray, kObject } type = Type::kNull;
  bool boolean = false;
  double number = 0;
  std::string string;
  std::vector<JsonValue> array;
  std::map<std::string, JsonValue> object;

  const JsonValue& operator[](const std::string& key) const {
    if (type != Type::kObject) throw std::runtime_error("not an object looking up " + key);
    const auto it = object.find(key);
    if (it == object.end()) throw std::runtime_error("no key " + key);
    return it->second;
  }
  const JsonValue& operator[](std::size_t i) const {
    if (type != Type::kArray || i >= array.size()) throw std::runtime_error("bad array index");
    return array[i];
  }
  double num() const {
    if (type != Type::kNumber) throw std::runtime_error("not a number");
    return number;
  }
  const std::string& str() const {
    if (type != Type::kString) throw std::runtime_error("not a string");
    return string;
  }
};

class JsonParser {
 public:
  static JsonValue parse(const std::string& text) {
    JsonParser p(text);
    JsonValue v = p.value();
    p.skipSpace();
    if (p.i_ != text.size()) p.fail("trailing characters");
    return v;
  }

 private:
  explicit JsonParser(const std::string& t) : t_(t) {}
  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error("JSON: " + what + " at offset " + std::to_string(i_));
  }
  void skipSpace() {
    while (i_ < t_.size() && std::isspace(static_cast<unsigned char>(t_[i_]))) ++i_;
  }
  bool take(char c) {
    skipSpace();
    if (i_ < t_.size() && t_[i_] == c) {
      ++i_;
      return true;
    }
    return false;
  }
  void expect(char c) {
    if (!take(c)) fail(std::string("expected '") + c + "'");
  }
  std::string stringBody() {
    expect('"');
    std::string s;
    while (i_ < t_.size() && t_[i_] != '"') {
      if (t_[i_] == '\\') {
        ++i_;
        if (i_ >= t_.size()) fail("bad escape");
        const char e = t_[i_];
        if (e == 'n')
          s += '\n';
        else if (e == 't')
          s += '\t';
        else if (e == 'u') {
          s += '?';
          i_ += 4;
        } else {
          s += e;
        }
        ++i_;
      } else {
        s += t_[i_++];
      }
    }
    if (i_ >= t_.size()) fail("unterminated string");
    ++i_;
    return s;
  }
  JsonValue value() {
    skipSpace();
    if (i_ >= t_.size()) fail("unexpected end");
    JsonValue v;
    const char c = t_[i_];
    if (c == '{') {
      ++i_;
      v.type = JsonValue::Type::kObject;
      if (take('}')) return v;
      do {
        skipSpace();
        const std::string key = stringBody();
        expect(':');
        v.object[key] = value();
      } while (take(','));
      expect('}');
    } else if (c == '[') {
      ++i_;
      v.type = JsonValue::Type::kArray;
      if (take(']')) return v;
      do {
        v.array.push_back(value());
      } while (take(','));
      expect(']');
    } else if (c == '"') {
      v.type = JsonValue::Type::kString;
      v.string = stringBody();
    } else if (t_.compare(i_, 4, "null") == 0) {
      i_ += 4;
    } else if (t_.compare(i_, 4, "true") == 0) {
      i_ += 4;
      v.type = JsonValue::Type::kBool;
      v.boolean = true;
    } else if (t_.compare(i_, 5, "false") == 0) {
      i_ += 5;
      v.type = JsonValue::Type::kBool;
    } else {
      char* end = nullptr;
      v.number = std::strtod(t_.c_str() + i_, &end);
      if (end == t_.c_str() + i_) fail("bad value");
      i_ = static_cast<std::size_t>(end - t_.c_str());
      v.type = JsonValue::Type::kNumber;
    }
    return v;
  }

  const std::string& t_;
  std::size_t i_ = 0;
};

}  // namespace vslam::test
