// ParamTable: one declaration of a struct's keys reads a block (defaults
// from the struct, ranges, degrees, words, sub-blocks, required keys) and
// describes it for the documentation.
#include <gtest/gtest.h>

#include <cmath>

#include "config/param_table.hpp"

using vslam::config::ConfigError;
using vslam::config::ConfigNode;
using vslam::config::InRange;
using vslam::config::ParamDoc;
using vslam::config::ParamTable;

namespace {

enum class Mode { kFast, kCareful };

struct Inner {
  double gain = 2.0;
};

struct Params {
  double sigma = 0.5;
  int count = 3;
  double angle_rad = 0.1;
  bool enabled = false;
  std::string name = "robot";
  Mode mode = Mode::kFast;
  Inner inner;
  double required_value = 0;
};

ParamTable<Params> table() {
  ParamTable<Inner> inner;
  inner.add("gain", &Inner::gain, InRange{1, 10}, "", "the inner gain");
  ParamTable<Params> t;
  t.add("sigma", &Params::sigma, InRange{0, 1}, "m", "a spread")
      .add("count", &Params::count, InRange{1, 100}, "", "how many")
      .degrees("angle_deg", &Params::angle_rad, InRange{0, 180}, "an angle")
      .add("enabled", &Params::enabled, "on or off")
      .add("name", &Params::name, "a word")
      .choice("mode", &Params::mode,
              std::vector<std::pair<std::string, Mode>>{{"fast", Mode::kFast},
                                                        {"careful", Mode::kCareful}},
              "how")
      .block("inner", &Params::inner, inner)
      .add("required_value", &Params::required_value, InRange{}, "", "must be given")
      .required()
      .check([](const ConfigNode& node, const Params& p) {
        if (p.enabled && p.count < 2) throw node.error("count", "must be at least 2 when enabled");
      });
  return t;
}

ConfigNode yaml(const std::string& text) { return ConfigNode::loadString(text, "test.yaml"); }

template <class Fn>
void expectConfigError(Fn fn, const std::string& key, const std::string& part) {
  try {
    fn();
    FAIL() << "no ConfigError for " << key;
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.key(), key) << e.what();
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

const ParamDoc& row(const std::vector<ParamDoc>& rows, const std::string& key) {
  for (const auto& r : rows) {
    if (r.key == key) return r;
  }
  throw std::out_of_range("no row " + key);
}

}  // namespace

TEST(ParamTable, KeysLeftOutKeepTheStructsValues) {
  Params p;
  table().load(yaml("required_value: 7"), p);
  const Params defaults;
  EXPECT_EQ(p.sigma, defaults.sigma);
  EXPECT_EQ(p.count, defaults.count);
  // Read back through degrees, as the loaders always did: within an ulp.
  EXPECT_NEAR(p.angle_rad, defaults.angle_rad, 1e-15);
  EXPECT_EQ(p.name, "robot");
  EXPECT_EQ(p.mode, Mode::kFast);
  EXPECT_EQ(p.inner.gain, 2.0);
  EXPECT_EQ(p.required_value, 7.0);
}

TEST(ParamTable, ReadsEveryKindOfKey) {
  Params p;
  table().load(yaml("sigma: 0.25\ncount: 9\nangle_deg: 90\nenabled: true\nname: rover\n"
                    "mode: careful\ninner: {gain: 4}\nrequired_value: -1"),
               p);
  EXPECT_EQ(p.sigma, 0.25);
  EXPECT_EQ(p.count, 9);
  EXPECT_NEAR(p.angle_rad, M_PI / 2, 1e-12);
  EXPECT_TRUE(p.enabled);
  EXPECT_EQ(p.name, "rover");
  EXPECT_EQ(p.mode, Mode::kCareful);
  EXPECT_EQ(p.inner.gain, 4.0);
  EXPECT_EQ(p.required_value, -1.0);
}

TEST(ParamTable, BadValuesAreErrorsNamingTheKey) {
  Params p;
  expectConfigError([&] { table().load(yaml("sigma: 2\nrequired_value: 0"), p); }, "sigma",
                    "[0, 1]");
  expectConfigError([&] { table().load(yaml("angle_deg: 200\nrequired_value: 0"), p); },
                    "angle_deg", "[0, 180]");
  expectConfigError([&] { table().load(yaml("mode: slow\nrequired_value: 0"), p); }, "mode",
                    "fast, careful");
  expectConfigError([&] { table().load(yaml("sigma: 0.1"), p); }, "required_value", "missing");
  expectConfigError([&] { table().load(yaml("inner: {gain: 0.5}\nrequired_value: 0"), p); },
                    "inner.gain", "[1, 10]");
  expectConfigError([&] { table().load(yaml("inner: {gian: 3}\nrequired_value: 0"), p); },
                    "inner.gian", "did you mean 'gain'");
  expectConfigError([&] { table().load(yaml("enabled: true\ncount: 1\nrequired_value: 0"), p); },
                    "count", "at least 2 when enabled");
}

TEST(ParamTable, DescribesDefaultsAndWhatABlockChanges) {
  const Params defaults;
  Params configured;
  table().load(yaml("sigma: 0.25\nangle_deg: 5.729577951308232\ninner: {gain: 3}\n"
                    "required_value: 4"),
               configured);
  const auto rows = table().describe(defaults, &configured);
  ASSERT_EQ(rows.size(), 8u);
  EXPECT_EQ(row(rows, "sigma").default_value, "0.5");
  EXPECT_EQ(row(rows, "sigma").configured, "0.25");
  EXPECT_EQ(row(rows, "sigma").range, "[0, 1]");
  EXPECT_EQ(row(rows, "sigma").unit, "m");
  EXPECT_EQ(row(rows, "count").configured, "");  // as the default
  EXPECT_EQ(row(rows, "angle_deg").default_value, "5.72958");
  EXPECT_EQ(row(rows, "angle_deg").configured, "");  // the same angle, written in degrees
  EXPECT_EQ(row(rows, "mode").default_value, "fast");
  EXPECT_EQ(row(rows, "mode").range, "fast, careful");
  EXPECT_EQ(row(rows, "name").default_value, "robot");
  EXPECT_EQ(row(rows, "inner.gain").configured, "3");
  EXPECT_EQ(row(rows, "required_value").default_value, "required");
  EXPECT_EQ(row(rows, "required_value").configured, "4");

  const std::string md = vslam::config::markdownTable(rows, "in test.yaml");
  EXPECT_NE(md.find("| key | unit | default | range | in test.yaml | meaning |"), std::string::npos)
      << md;
  EXPECT_NE(md.find("| `inner.gain` |  | 2 | [1, 10] | 3 | the inner gain |"), std::string::npos)
      << md;
}

TEST(ParamTable, OptionalValuesStayUnsetUnlessGivenAndCustomKeysReadTheirOwnWay) {
  struct Device {
    std::optional<double> exposure;
    std::optional<bool> auto_exposure;
    std::string size_text = "none";
  };
  ParamTable<Device> t;
  t.add("exposure", &Device::exposure, InRange{0, 100}, "", "device units")
      .add("auto_exposure", &Device::auto_exposure, "control")
      .custom(
          "size", "px", "WxH",
          [](const ConfigNode& node, const std::string& key, Device& d) {
            if (!node.has(key)) return;
            const std::string text = node.getString(key);
            if (text.find('x') == std::string::npos) throw node.error(key, "expected WxH");
            d.size_text = text;
          },
          [](const Device& d) { return d.size_text; });
  Device left_out;
  t.load(yaml("{}"), left_out);
  EXPECT_FALSE(left_out.exposure.has_value());
  EXPECT_FALSE(left_out.auto_exposure.has_value());
  Device given;
  t.load(yaml("exposure: 30\nauto_exposure: false\nsize: 640x480"), given);
  EXPECT_EQ(given.exposure, 30.0);
  EXPECT_EQ(given.auto_exposure, false);
  EXPECT_EQ(given.size_text, "640x480");
  expectConfigError([&] { t.load(yaml("exposure: 300"), given); }, "exposure", "[0, 100]");
  expectConfigError([&] { t.load(yaml("size: big"), given); }, "size", "expected WxH");
  const auto rows = t.describe(Device{}, &given);
  EXPECT_EQ(row(rows, "exposure").default_value, "unset");
  EXPECT_EQ(row(rows, "exposure").configured, "30");
  EXPECT_EQ(row(rows, "size").default_value, "none");
  EXPECT_EQ(row(rows, "size").configured, "640x480");
}
