// ParameterTable::loadYaml: every key sets its own field and nothing else, every kind of bad value
// gives one line naming the file, the key and the value, and ranges are PipelineOptions::isValid's.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "stereo_ground_dem/ParameterTable.hpp"

using namespace stereo_ground_dem;
namespace fs = std::filesystem;

namespace {

class ParameterYaml : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("sgd_test_params_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    path_ = (dir_ / "p.yaml").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// Loads `text` into fresh options; "" on success, else the error (the file name shown as <file>).
  std::string load(const std::string& text, PipelineOptions* out = nullptr) {
    // a new file each time: rewriting one in place makes ext4 flush it on every close
    path_ = (dir_ / ("p" + std::to_string(count_++) + ".yaml")).string();
    std::ofstream(path_) << text;
    PipelineOptions o;
    try {
      ParameterTable(&o).loadYaml(path_);
    } catch (const std::runtime_error& e) {
      std::string m = e.what();  // the file name varies: shown as <file>
      const size_t at = m.find(path_);
      if (at != std::string::npos) m.replace(at, path_.size(), "<file>");
      return m;
    }
    if (out) *out = o;
    return "";
  }
  static std::string prefix() { return "parameter file '<file>': "; }

  fs::path dir_;
  std::string path_;
  int count_ = 0;
};

std::string text(double v) {
  std::ostringstream os;
  os.precision(17);
  os << v;
  return os.str();
}

}  // namespace

TEST_F(ParameterYaml, EveryKeySetsItsOwnFieldOnly) {
  PipelineOptions defaults;
  const ParameterTable dt(&defaults);
  ASSERT_GE(dt.entries().size(), 60u);
  for (const auto& e : dt.entries()) {
    const double d = dt.get(e);
    double v = 0.0;
    std::string written;
    switch (e.type) {
      case ParameterTable::Type::kBool: v = d != 0.0 ? 0.0 : 1.0; written = v != 0.0 ? "true" : "false"; break;
      case ParameterTable::Type::kInt: v = d + 3.0; written = text(v); break;
      case ParameterTable::Type::kDouble: v = d * 1.5 + 0.125; written = text(v); break;
    }
    PipelineOptions loaded;
    ASSERT_EQ(load(e.name + ": " + written + "\n", &loaded), "") << e.name;
    const ParameterTable lt(&loaded);
    for (const auto& f : lt.entries()) {
      const double expected = f.name == e.name ? v : dt.get(*dt.find(f.name));
      EXPECT_EQ(lt.get(f), expected) << "writing " << e.name << " changed " << f.name;
    }
  }
}

TEST_F(ParameterYaml, WrappersCommentsAndEmptyFiles) {
  PipelineOptions o;
  EXPECT_EQ(load("stereo_ground_dem:\n  smoothness_weight: 3.5\n  use_hierarchy: false\n", &o), "");
  EXPECT_EQ(o.estimator.stereo.aligner.smoothness_weight, 3.5);
  EXPECT_FALSE(o.estimator.stereo.use_hierarchy);
  EXPECT_EQ(load("dem_nodelet:\n  image_bit_depth: 12\n  left_topic: /a\n", &o), "");
  EXPECT_EQ(o.input.image_bit_depth, 12);
  EXPECT_EQ(load(""), "");
  EXPECT_EQ(load("# only a comment\n"), "");
  EXPECT_EQ(load("%YAML:1.0\nmesh_levels: 3\n", &o), "");
  EXPECT_EQ(o.estimator.stereo.mesh_levels, 3);
  EXPECT_EQ(load("use_hierarchy: 0\nobstacles_enabled: 1\n", &o), "");
  EXPECT_FALSE(o.estimator.stereo.use_hierarchy);
}

TEST_F(ParameterYaml, NonFiniteValuesForEveryKey) {
  PipelineOptions o;
  const ParameterTable t(&o);
  for (const auto& e : t.entries()) {
    for (const auto& [spelling, shown] : {std::pair<const char*, const char*>{".nan", "nan"}, {".inf", "inf"},
                                          {"-.inf", "-inf"}, {"nan", "nan"}, {"'-inf'", "-inf"}, {"1e999", "inf"}}) {
      EXPECT_EQ(load(e.name + ": " + spelling + "\n"), prefix() + "'" + e.name + "' must be a finite number, got " + shown)
          << e.name << ": " << spelling;
    }
  }
}

TEST_F(ParameterYaml, WrongTypesForEveryKey) {
  PipelineOptions o;
  const ParameterTable t(&o);
  for (const auto& e : t.entries()) {
    const std::string p = prefix() + "'" + e.name + "' ";
    EXPECT_EQ(load(e.name + ": abc\n"), p + "is not a number: 'abc'") << e.name;
    EXPECT_EQ(load(e.name + ": [1, 2]\n"), p + "must be a single number, not a list") << e.name;
    EXPECT_EQ(load(e.name + ": {a: 1}\n"), p + "must be a single number, not a map") << e.name;
    switch (e.type) {
      case ParameterTable::Type::kInt:
        EXPECT_EQ(load(e.name + ": 2.5\n"), p + "must be an integer, got 2.5") << e.name;
        EXPECT_EQ(load(e.name + ": 1e12\n"), p + "= 1e+12 is outside the integer range") << e.name;
        EXPECT_EQ(load(e.name + ": true\n"), p + "must be a number, got 'true'") << e.name;
        break;
      case ParameterTable::Type::kDouble:
        EXPECT_EQ(load(e.name + ": false\n"), p + "must be a number, got 'false'") << e.name;
        break;
      case ParameterTable::Type::kBool:
        EXPECT_EQ(load(e.name + ": 2\n"), p + "must be true or false (or 1 or 0), got 2") << e.name;
        EXPECT_EQ(load(e.name + ": yes please\n"), p + "is not a number: 'yes please'") << e.name;
        break;
    }
  }
}

TEST_F(ParameterYaml, MalformedFilesAndUnknownKeys) {
  EXPECT_EQ(load("smoothnes_weight: 3\n"), prefix() + "unknown parameter 'smoothnes_weight'");
  EXPECT_EQ(load("- 1\n- 2\n"), prefix() + "the top level is not a map of name: value");
  EXPECT_EQ(load("mesh_levels 3\n").rfind(prefix(), 0), 0u);
  const std::string unbalanced = load("mesh_levels: [3\n");
  EXPECT_EQ(unbalanced.rfind(prefix() + "not readable YAML", 0), 0u) << unbalanced;
  EXPECT_EQ(unbalanced.find('\n'), std::string::npos);
  EXPECT_EQ(load("mesh_levels: \"3\"\n"), "");  // a quoted number is a number
  PipelineOptions o;
  EXPECT_THROW(ParameterTable(&o).loadYaml((dir_ / "missing.yaml").string()), std::runtime_error);
  try {
    ParameterTable(&o).loadYaml((dir_ / "missing.yaml").string());
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "parameter file '" + (dir_ / "missing.yaml").string() + "': cannot be opened");
  }
}

TEST_F(ParameterYaml, RangesAreRefusedByIsValidWithTheReason) {
  const std::pair<const char*, const char*> cases[] = {
      {"mesh_levels: 9", "stereo: mesh_levels must be in 1..6"},
      {"grid_resolution_m: 0", "stereo: grid_resolution_m must be > 0"},
      {"grid_resolution_m: -0.5", "stereo: grid_resolution_m must be > 0"},
      {"max_range_m: 3", "stereo: need 0 < min_range_m < max_range_m"},
      {"tracking_levels: 7", "tracking_levels must be in 1..mesh_levels"},
      {"map_tile_size: 4", "map: tile_size must be in 8..1024"},
      {"image_bit_depth: 7", "input: image_bit_depth must be 0 (detect) or 8..16, got 7"},
      {"image_bit_depth: 17", "input: image_bit_depth must be 0 (detect) or 8..16, got 17"},
      {"nominal_frame_period_s: 0", "nominal_frame_period_s must be > 0"},
      {"reinit_after_failures: 0", "reinit_after_failures must be >= 1"},
  };
  for (const auto& [yaml, why] : cases) {
    PipelineOptions o;
    ASSERT_EQ(load(std::string(yaml) + "\n", &o), "") << yaml;
    std::string w;
    EXPECT_FALSE(o.isValid(&w)) << yaml;
    EXPECT_EQ(w, why) << yaml;
  }
  // Extreme values of every key: loading succeeds or refuses, isValid answers; never a crash.
  PipelineOptions d;
  const ParameterTable t(&d);
  for (const auto& e : t.entries()) {
    for (const char* v : {"-1000000", "0", "1000000", "2147483647", "-2147483648"}) {
      PipelineOptions o;
      const std::string err = load(e.name + ": " + v + "\n", &o);
      if (!err.empty()) {
        EXPECT_EQ(err.find('\n'), std::string::npos);
        continue;
      }
      std::string w;
      if (!o.isValid(&w)) EXPECT_FALSE(w.empty()) << e.name << ": " << v;
    }
  }
}

// ParameterTable::load: what dem_offline, sgd_long_run and sgd_benchmark run with.
TEST_F(ParameterYaml, LoadGivesDefaultsOrTheFileValidated) {
  const PipelineOptions defaults = ParameterTable::load("");
  std::string why;
  EXPECT_TRUE(defaults.isValid(&why)) << why;
  EXPECT_EQ(defaults.estimator.tracking_levels, PipelineOptions().estimator.tracking_levels);

  const std::string good = (dir_ / "good.yaml").string();
  std::ofstream(good) << "tracking_levels: 3\n";
  EXPECT_EQ(ParameterTable::load(good).estimator.tracking_levels, 3);

  const std::string invalid = (dir_ / "invalid.yaml").string();
  std::ofstream(invalid) << "max_range_m: 3\n";
  try {
    ParameterTable::load(invalid);
    ADD_FAILURE() << "an invalid range was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "invalid parameters: stereo: need 0 < min_range_m < max_range_m");
  }
  // loadYaml's own refusal passes through with the file's name
  const std::string unknown = (dir_ / "unknown.yaml").string();
  std::ofstream(unknown) << "no_such_parameter: 1\n";
  try {
    ParameterTable::load(unknown);
    ADD_FAILURE() << "an unknown name was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(unknown), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no_such_parameter"), std::string::npos) << e.what();
  }
}
