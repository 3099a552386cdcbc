#pragma once
// A parameter struct's keys, declared once: the key, where its value lives in
// the struct, the range it must lie in, its unit and what it means. One loader
// walks the declaration (a key the file leaves out keeps the struct's value,
// so a default is written in the struct and nowhere else), and the same
// declaration prints the documentation tables (scripts/config-docs) and
// annotates --print-config.
//
//   ParamTable<DeadReckonParams> t;
//   t.add("sigma_translation", &DeadReckonParams::sigma_translation, nonNegative(), "m/√m",
//         "σ_T: translation noise, variance σ_T²·distance")
//       .required()
//       .degrees("max_step_deg", &DeadReckonParams::max_step_rad, InRange{1, 180},
//                "larger turns between two readings are faults");
//   t.load(node, params);

#include <filesystem>
#include <functional>
#include <optional>
#include <sstream>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "config/config_node.hpp"
#include "util/angles.hpp"

namespace vslam::config {

// One declared key, as the documentation and --print-config show it.
struct ParamDoc {
  std::string key;            // relative to its role's block, e.g. "kidnap.detect_count"
  std::string unit;           // "" if none
  std::string default_value;  // "required" for a key the file must give
  std::string range;          // "[0, 1]", "> 0", "" if any value of the type
  std::string meaning;
  std::string configured;  // the value a given block sets where it differs from the default
};

// A value as --print-config and the tables write it (the stream's default
// format, as ConfigNode records it).
template <class T>
std::string valueText(const T& value) {
  std::ostringstream os;
  if constexpr (std::is_same_v<T, bool>) {
    os << (value ? "true" : "false");
  } else if constexpr (std::is_same_v<T, std::filesystem::path>) {
    os << (value.empty() ? "\"\"" : value.string());
  } else if constexpr (std::is_same_v<T, std::string>) {
    os << (value.empty() ? "\"\"" : value);
  } else if constexpr (std::is_same_v<T, std::vector<std::string>>) {
    os << "[";
    for (size_t i = 0; i < value.size(); ++i) os << (i ? ", " : "") << value[i];
    os << "]";
  } else {
    os << value;
  }
  return os.str();
}

template <class T>
struct IsOptional : std::false_type {};
template <class T>
struct IsOptional<std::optional<T>> : std::true_type {};

// An optional value: "unset" when it has none.
template <class T>
std::string valueText(const std::optional<T>& value) {
  return value ? valueText(*value) : "unset";
}

// Markdown table: key, unit, default, range, meaning, and a column of the
// configured values if any row has one (`configured_header` names it).
std::string markdownTable(const std::vector<ParamDoc>& rows,
                          const std::string& configured_header = "");

template <class S>
class ParamTable {
 public:
  // A number (double or integral) of S reached through `field`: a member
  // pointer, or for a nested member a generic lambda returning a reference
  // (`[](auto& p) -> auto& { return p.graph.max_iterations; }`: it is called
  // on const structs too, to describe them).
  template <class Field>
  ParamTable& add(std::string key, Field field, InRange range, std::string unit,
                  std::string meaning) {
    using Stored = std::decay_t<decltype(std::invoke(field, std::declval<S&>()))>;
    Entry e = entry(std::move(key), std::move(unit), std::move(meaning));
    e.range = rangeText(range);
    e.read = [field, range](const ConfigNode& node, const std::string& k, S& s, bool required) {
      Stored& v = std::invoke(field, s);
      if constexpr (IsOptional<Stored>::value) {
        // Left out: no value (the device's own, say); given: checked as any number.
        if (node.has(k)) v = readNumber<typename Stored::value_type>(node, k, range, nullptr);
      } else {
        v = readNumber<Stored>(node, k, range, required ? nullptr : &v);
      }
    };
    e.show = [field](const S& s) { return valueText(std::invoke(field, s)); };
    entries_.push_back(std::move(e));
    return *this;
  }

  // A flag, a word (a non-empty string) or a list of words.
  template <class Field>
  ParamTable& add(std::string key, Field field, std::string meaning) {
    using T = std::decay_t<decltype(std::invoke(field, std::declval<S&>()))>;
    static_assert(std::is_same_v<T, bool> || std::is_same_v<T, std::optional<bool>> ||
                      std::is_same_v<T, std::string> || std::is_same_v<T, std::vector<std::string>>,
                  "numbers take a range");
    Entry e = entry(std::move(key), "", std::move(meaning));
    e.read = [field](const ConfigNode& node, const std::string& k, S& s, bool required) {
      T& v = std::invoke(field, s);
      if constexpr (std::is_same_v<T, std::optional<bool>>) {
        if (node.has(k)) v = node.getBool(k);
      } else if constexpr (std::is_same_v<T, bool>) {
        v = required ? node.getBool(k) : node.getBool(k, v);
      } else if constexpr (std::is_same_v<T, std::string>) {
        v = required ? node.getString(k) : node.getString(k, v);
      } else if (required || node.has(k)) {
        v = node.getStrings(k);
      } else {
        node.markUsed(k);
      }
    };
    e.show = [field](const S& s) { return valueText(std::invoke(field, s)); };
    entries_.push_back(std::move(e));
    return *this;
  }

  // An angle kept in radians and written in degrees (the key ends in _deg).
  template <class Field>
  ParamTable& degrees(std::string key, Field radians, InRange range_deg, std::string meaning,
                      std::string unit = "deg") {
    Entry e = entry(std::move(key), std::move(unit), std::move(meaning));
    e.range = rangeText(range_deg);
    e.read = [radians, range_deg](const ConfigNode& node, const std::string& k, S& s,
                                  bool required) {
      double& v = std::invoke(radians, s);
      v = degToRad(required ? node.getDouble(k, range_deg)
                            : node.getDouble(k, radToDeg(v), range_deg));
    };
    e.show = [radians](const S& s) { return valueText(radToDeg(std::invoke(radians, s))); };
    entries_.push_back(std::move(e));
    return *this;
  }

  // One of a fixed set of words, each standing for a value of the field.
  template <class Field, class V>
  ParamTable& choice(std::string key, Field field, std::vector<std::pair<std::string, V>> words,
                     std::string meaning) {
    Entry e = entry(std::move(key), "", std::move(meaning));
    std::vector<std::string> allowed;
    for (const auto& w : words) allowed.push_back(w.first);
    for (const auto& w : allowed) e.range += (e.range.empty() ? "" : ", ") + w;
    e.read = [field, words, allowed](const ConfigNode& node, const std::string& k, S& s,
                                     bool required) {
      if (!required && !node.has(k)) {
        node.markUsed(k);
        return;
      }
      const std::string word = node.getEnum(k, allowed);
      for (const auto& w : words) {
        if (w.first == word) std::invoke(field, s) = w.second;
      }
    };
    e.show = [field, words](const S& s) {
      for (const auto& w : words) {
        if (w.second == std::invoke(field, s)) return w.first;
      }
      return std::string("?");
    };
    entries_.push_back(std::move(e));
    return *this;
  }

  // A file, relative to the config file; "" (or left out) keeps the field's
  // value (empty: no file).
  template <class Field>
  ParamTable& path(std::string key, Field field, bool must_exist, std::string meaning) {
    Entry e = entry(std::move(key), "path", std::move(meaning));
    e.read = [field, must_exist](const ConfigNode& node, const std::string& k, S& s,
                                 bool required) {
      if (!required && !node.has(k)) {
        node.markUsed(k);
        return;
      }
      std::filesystem::path& v = std::invoke(field, s);
      v = node.getString(k, true).empty() ? std::filesystem::path() : node.getPath(k, must_exist);
    };
    e.show = [field](const S& s) { return valueText(std::invoke(field, s)); };
    e.as_written = true;  // resolved, it would name this machine's directories
    entries_.push_back(std::move(e));
    return *this;
  }

  // A key read and written by the caller's own functions, for a value no
  // kind above fits (a parsed specification, a value checked against others).
  // `read(node, key, s)` is called whether or not the key is present.
  ParamTable& custom(std::string key, std::string unit, std::string meaning,
                     std::function<void(const ConfigNode&, const std::string&, S&)> read,
                     std::function<std::string(const S&)> show) {
    Entry e = entry(std::move(key), std::move(unit), std::move(meaning));
    e.read = [read](const ConfigNode& node, const std::string& k, S& s, bool required) {
      if (required && !node.has(k)) throw node.error(k, "missing");
      read(node, k, s);
    };
    e.show = std::move(show);
    entries_.push_back(std::move(e));
    return *this;
  }

  // The key (or block) declared last has no default: the file must give it.
  ParamTable& required() {
    entries_.back().required = true;
    return *this;
  }

  // A sub-block with a table of its own; left out, its values stay (unless
  // marked required()).
  template <class Field, class T>
  ParamTable& block(std::string key, Field field, ParamTable<T> table) {
    Entry e = entry(std::move(key), "", "");
    e.read = [field, table](const ConfigNode& node, const std::string& k, S& s, bool required) {
      if (!required && !node.has(k)) return;
      const ConfigNode child = node.child(k);
      table.load(child, std::invoke(field, s));
      child.requireAllKeysUsed();
    };
    e.nested = [field, table](const S& s, const S* configured, const ConfigNode* node,
                              const std::string& k) {
      std::optional<ConfigNode> child;
      if (node && node->has(k)) child = node->child(k);
      return table.describe(std::invoke(field, s),
                            configured ? &std::invoke(field, *configured) : nullptr,
                            child ? &*child : nullptr);
    };
    entries_.push_back(std::move(e));
    return *this;
  }

  // The keys of another table, at this level, for a member of S (a library's
  // parameters inside a stage's).
  template <class Field, class T>
  ParamTable& merge(Field field, ParamTable<T> table) {
    Entry e = entry("", "", "");
    e.read = [field, table](const ConfigNode& node, const std::string&, S& s, bool) {
      table.load(node, std::invoke(field, s));
    };
    e.nested = [field, table](const S& s, const S* configured, const ConfigNode* node,
                              const std::string&) {
      return table.describe(std::invoke(field, s),
                            configured ? &std::invoke(field, *configured) : nullptr, node);
    };
    entries_.push_back(std::move(e));
    return *this;
  }

  // A rule across keys, checked after they are read; it throws
  // node.error(key, why).
  ParamTable& check(std::function<void(const ConfigNode&, const S&)> rule) {
    checks_.push_back(std::move(rule));
    return *this;
  }

  // Reads every declared key of `node` into `s`. Keys it does not declare
  // are left for the caller's requireAllKeysUsed() (a block may hold keys
  // read elsewhere, such as `role`).
  void load(const ConfigNode& node, S& s) const {
    for (const Entry& e : entries_) e.read(node, e.key, s, e.required);
    for (const auto& rule : checks_) rule(node, s);
  }

  // The declared keys with the values of `defaults`; with `configured`, each
  // row also gives that struct's value where it differs (a path as `block`,
  // the block it was read from, writes it).
  std::vector<ParamDoc> describe(const S& defaults, const S* configured = nullptr,
                                 const ConfigNode* block = nullptr) const {
    std::vector<ParamDoc> rows;
    for (const Entry& e : entries_) {
      if (e.nested) {
        for (ParamDoc d : e.nested(defaults, configured, block, e.key)) {
          if (!e.key.empty()) d.key = e.key + "." + d.key;
          rows.push_back(std::move(d));
        }
        continue;
      }
      ParamDoc d{e.key, e.unit, e.required ? "required" : e.show(defaults), e.range, e.meaning, ""};
      if (configured) {
        std::string value = e.show(*configured);
        if (e.as_written && block && block->has(e.key)) {
          value = valueText(block->getString(e.key, true));
        }
        if (e.required || value != e.show(defaults)) d.configured = value;
      }
      rows.push_back(std::move(d));
    }
    return rows;
  }

 private:
  struct Entry {
    std::string key, unit, meaning, range;
    bool required = false;
    bool as_written = false;  // described as the file writes it, not as read
    std::function<void(const ConfigNode&, const std::string&, S&, bool)> read;
    std::function<std::string(const S&)> show;
    // A sub-block or merged table: (defaults, configured, the block read, key).
    std::function<std::vector<ParamDoc>(const S&, const S*, const ConfigNode*, const std::string&)>
        nested;
  };
  // A number of type T; `fallback` null: required.
  template <class T>
  static T readNumber(const ConfigNode& node, const std::string& k, InRange range,
                      const T* fallback) {
    static_assert(std::is_arithmetic_v<T>, "a range only fits a number");
    if constexpr (std::is_floating_point_v<T>) {
      return fallback ? node.getDouble(k, *fallback, range) : node.getDouble(k, range);
    } else {
      return static_cast<T>(fallback ? node.getInt(k, static_cast<int64_t>(*fallback), range)
                                     : node.getInt(k, range));
    }
  }
  static Entry entry(std::string key, std::string unit, std::string meaning) {
    Entry e;
    e.key = std::move(key);
    e.unit = std::move(unit);
    e.meaning = std::move(meaning);
    return e;
  }

  std::vector<Entry> entries_;
  std::vector<std::function<void(const ConfigNode&, const S&)>> checks_;
};

}  // namespace vslam::config
