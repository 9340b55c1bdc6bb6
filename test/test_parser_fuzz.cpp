// Randomized robustness of the offline input parsers: calibration files (KITTI odometry and raw),
// parameter YAML and sequence folders (calib, times.txt, poses.txt, image files). Valid inputs are
// mutated with a fixed seed (byte flips, truncations, inserted NaN/huge/negative numbers and YAML
// or key syntax, duplicated, deleted and swapped lines, deleted or emptied files); every input
// must either be accepted or refused with a std::runtime_error whose message is one non-empty
// line. A crash, another exception type or a multi-line message fails the test.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "stereo_ground_dem/CalibrationReader.hpp"
#include "stereo_ground_dem/ParameterTable.hpp"
#include "stereo_ground_dem/io/KittiSequence.hpp"

using namespace stereo_ground_dem;
namespace fs = std::filesystem;

namespace {

const char* kOdometry =
    "P0: 7.070912e+02 0.0 6.018873e+02 0.0 0.0 7.070912e+02 1.831104e+02 0.0 0.0 0.0 1.0 0.0\n"
    "P1: 7.070912e+02 0.0 6.018873e+02 -3.798145e+02 0.0 7.070912e+02 1.831104e+02 0.0 0.0 0.0 1.0 0.0\n"
    "P2: 7.070912e+02 0.0 6.018873e+02 4.688783e+01 0.0 7.070912e+02 1.831104e+02 1.178601e-01 0.0 0.0 1.0 6.203223e-03\n"
    "P3: 7.070912e+02 0.0 6.018873e+02 -3.334597e+02 0.0 7.070912e+02 1.831104e+02 1.930130e+00 0.0 0.0 1.0 3.318498e-03\n"
    "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n";
const char* kUnkeyed =
    "7.070912e+02 0 6.018873e+02 0 0 7.070912e+02 1.831104e+02 0 0 0 1 0\n"
    "7.070912e+02 0 6.018873e+02 -3.798145e+02 0 7.070912e+02 1.831104e+02 0 0 0 1 0\n";
const char* kRaw =
    "calib_time: 09-Jan-2012 13:57:47\n"
    "S_rect_00: 1.242000e+03 3.750000e+02\n"
    "P_rect_00: 7.215377e+02 0 6.095593e+02 0 0 7.215377e+02 1.728540e+02 0 0 0 1 0\n"
    "P_rect_01: 7.215377e+02 0 6.095593e+02 -3.875744e+02 0 7.215377e+02 1.728540e+02 0 0 0 1 0\n"
    "S_rect_02: 1.242000e+03 3.750000e+02\n"
    "P_rect_02: 7.215377e+02 0 6.095593e+02 4.485728e+01 0 7.215377e+02 1.728540e+02 2.163791e-01 0 0 1 2.745884e-03\n"
    "S_rect_03: 1.242000e+03 3.750000e+02\n"
    "P_rect_03: 7.215377e+02 0 6.095593e+02 -3.395242e+02 0 7.215377e+02 1.728540e+02 2.199936e+00 0 0 1 2.729905e-03\n";
const char* kYaml =
    "# parameters\n"
    "grid_resolution_m: 0.5\n"
    "mesh_levels: 4\n"
    "max_range_m: 40.0\n"
    "use_hierarchy: true\n"
    "smoothness_weight: 200.0\n"
    "image_bit_depth: 0\n"
    "stereo_ground_dem:\n"
    "  tracking_levels: 2\n"
    "  obstacles_enabled: false\n"
    "left_topic: /stereo/left\n";
/// A tiny sequence's calibration: principal point inside its 40x40 images.
const char* kTinyCalib = "P0: 50 0 20 0 0 50 20 0 0 0 1 0\nP1: 50 0 20 -27 0 50 20 0 0 0 1 0\n";
const char* kTimes = "0.0\n0.1\n0.2\n0.3\n";
const char* kPoses =
    "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 1.2\n1 0 0 0 0 1 0 0 0 0 1 2.4\n1 0 0 0 0 1 0 0 0 0 1 3.6\n";

const char* kTokens[] = {"nan", "NaN", "-nan", "inf", "-inf", "1e999", "-1e999", "1e308", "-1e308", "-1", "0", "-0",
                         "99999999999999999999", "0x1p3", "1e-320", ".nan", ".inf", "-.inf", "- ", "\n", "\r\n", "\r",
                         ":", "::", " ", "\t", "" /* a NUL byte */, "P0:", "P1:", "P2:", "P_rect_02:",
                         "S_rect_00:", "S_rect_02: 1e300 -5", "[", "{", "}", "]", "'", "\"", "#", "%YAML:1.0", "&a",
                         "*a", "!!str", "|", ">", "stereo_ground_dem:", "  ", "mesh_levels:", "true", "false",
                         "2147483648", "-2147483649", "1e12", "0.5", "\xff\xfe", "\x01"};

class Mutator {
 public:
  explicit Mutator(unsigned seed) : rng_(seed) {}

  std::string mutate(std::string s) {
    const int n = 1 + pick(4);
    for (int i = 0; i < n; ++i) s = once(s);
    return s;
  }
  int pick(int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng_); }

 private:
  std::vector<std::string> split(const std::string& s) {
    std::vector<std::string> lines;
    std::istringstream is(s);
    std::string l;
    while (std::getline(is, l)) lines.push_back(l + "\n");
    return lines;
  }
  static std::string join(const std::vector<std::string>& v) {
    std::string s;
    for (const auto& l : v) s += l;
    return s;
  }
  std::string token() {
    const size_t n = sizeof(kTokens) / sizeof(kTokens[0]);
    const std::string t = kTokens[static_cast<size_t>(pick(static_cast<int>(n)))];
    return t.empty() ? std::string(1, '\0') : t;
  }
  std::string once(std::string s) {
    const int kind = pick(8);
    const size_t pos = s.empty() ? 0 : static_cast<size_t>(pick(static_cast<int>(s.size()) + 1));
    switch (kind) {
      case 0:  // byte flip
        if (!s.empty()) s[std::min(pos, s.size() - 1)] = static_cast<char>(pick(256));
        return s;
      case 1:  // truncation
        return s.substr(0, pos);
      case 2:  // inserted token
        return s.insert(pos, token());
      case 3: {  // a number replaced by a token
        const size_t start = s.find_first_of("0123456789", pos);
        if (start == std::string::npos) return s;
        const size_t end = s.find_first_not_of("0123456789.e+-", start);
        return s.replace(start, (end == std::string::npos ? s.size() : end) - start, token());
      }
      case 4: case 5: case 6: {  // duplicated, deleted, swapped lines
        std::vector<std::string> lines = split(s);
        if (lines.empty()) return s;
        const size_t i = static_cast<size_t>(pick(static_cast<int>(lines.size())));
        const size_t j = static_cast<size_t>(pick(static_cast<int>(lines.size())));
        if (kind == 4) lines.insert(lines.begin() + static_cast<long>(j), lines[i]);
        else if (kind == 5) lines.erase(lines.begin() + static_cast<long>(i));
        else std::swap(lines[i], lines[j]);
        return join(lines);
      }
      default:  // a whole line of garbage bytes
        {
          std::string g;
          const int len = pick(40);
          for (int k = 0; k < len; ++k) g += static_cast<char>(pick(256));
          return s.insert(pos, g + "\n");
        }
    }
  }
  std::mt19937 rng_;
};

class ParserFuzz : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("sgd_fuzz_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  static void write(const fs::path& p, const std::string& text) { std::ofstream(p, std::ios::binary) << text; }
  /// A new file per input: rewriting one file in place makes ext4 flush it on every close
  /// (auto_da_alloc), which costs seconds over thousands of inputs.
  fs::path fresh(const std::string& stem, int i) const { return dir_ / (stem + std::to_string(i)); }

  /// Runs f; counts an acceptance or a proper refusal, fails the test on anything else.
  template <typename F>
  void expectAcceptedOrOneLine(F f, const std::string& input) {
    try {
      f();
      ++accepted_;
    } catch (const std::runtime_error& e) {
      const std::string m = e.what();
      ++refused_;
      if (m.empty() || m.find('\n') != std::string::npos || m.find('\r') != std::string::npos) {
        ADD_FAILURE() << "refusal is not one non-empty line: '" << m << "' for input:\n" << input;
      }
    } catch (const std::exception& e) {
      ADD_FAILURE() << "unexpected exception type: " << e.what() << " for input:\n" << input;
    }
  }

  fs::path dir_;
  int accepted_ = 0, refused_ = 0;
};

}  // namespace

TEST_F(ParserFuzz, CalibrationFiles) {
  Mutator m(20261130);
  const std::string seeds[] = {kOdometry, kUnkeyed, kRaw};
  const CalibrationReader::CameraPair pairs[] = {CalibrationReader::CameraPair::kAuto, CalibrationReader::CameraPair::kGray,
                                                 CalibrationReader::CameraPair::kColor};
  for (int i = 0; i < 4000; ++i) {
    const std::string input = m.mutate(seeds[i % 3]);
    const fs::path p = fresh("calib", i);
    write(p, input);
    expectAcceptedOrOneLine(
        [&] {
          CalibrationReader::inspect(p.string());
          const StereoRig rig = CalibrationReader::read(p.string(), pairs[i % 3]);
          std::string why;
          EXPECT_TRUE(rig.isValid(&why)) << why;  // whatever is accepted is a valid rig
          EXPECT_LE(std::abs(rig.right_offset_y_m), StereoRig::kMaxRelativeOffset * rig.baseline_m);
          rig.rectificationWarning();
        },
        input);
    fs::remove(p);
  }
  EXPECT_GT(accepted_, 100);  // the mutations are not all fatal: the accepting paths are exercised
  EXPECT_GT(refused_, 1000);
  std::cout << "[          ] calibration: " << accepted_ << " accepted, " << refused_ << " refused\n";
}

TEST_F(ParserFuzz, ParameterYaml) {
  Mutator m(7);
  for (int i = 0; i < 3000; ++i) {
    const std::string input = m.mutate(kYaml);
    const fs::path p = fresh("p.yaml", i);
    write(p, input);
    expectAcceptedOrOneLine(
        [&] {
          PipelineOptions o;
          ParameterTable(&o).loadYaml(p.string());
          std::string why;
          if (!o.isValid(&why)) EXPECT_FALSE(why.empty());
        },
        input);
    fs::remove(p);
  }
  EXPECT_GT(accepted_, 100);
  EXPECT_GT(refused_, 500);
  std::cout << "[          ] parameter YAML: " << accepted_ << " accepted, " << refused_ << " refused\n";
}

TEST_F(ParserFuzz, SequenceFolders) {
  Mutator m(99);
  const cv::Mat image(40, 40, CV_8UC1, cv::Scalar(100));
  std::vector<uchar> png;
  cv::imencode(".png", image, png);
  const std::string png_bytes(png.begin(), png.end());
  for (int i = 0; i < 3000; ++i) {
    const fs::path seq = fresh("seq", i);
    fs::create_directories(seq / "image_l");
    fs::create_directories(seq / "image_r");
    const int part = m.pick(4);  // which file is mutated
    write(seq / "calib.txt", part == 0 ? m.mutate(kTinyCalib) : kTinyCalib);
    write(seq / "times.txt", part == 1 ? m.mutate(kTimes) : kTimes);
    write(seq / "poses.txt", part == 2 ? m.mutate(kPoses) : kPoses);
    for (int f = 0; f < 4; ++f) {
      for (const char* side : {"image_l", "image_r"}) {
        std::string bytes = png_bytes;
        if (part == 3 && m.pick(4) == 0) bytes = m.mutate(bytes);  // a broken image file
        const fs::path file = seq / side / ("00000" + std::to_string(f) + ".png");
        if (part == 3 && m.pick(10) == 0) continue;  // a missing file
        write(file, bytes);
      }
    }
    const std::string input = "part " + std::to_string(part) + " of iteration " + std::to_string(i);
    expectAcceptedOrOneLine(
        [&] {
          const KittiSequence s = KittiSequence::open(seq.string());
          EXPECT_EQ(s.rig().width, 40);
          for (const std::string& w : s.warnings()) EXPECT_EQ(w.find('\n'), std::string::npos) << w;
          for (int f = 0; f < s.size(); ++f) {
            cv::Mat l, r;
            std::string why;
            if (!s.tryRead(f, &l, &r, &why)) EXPECT_FALSE(why.empty());
            s.stamp(f);
          }
        },
        input);
    fs::remove_all(seq);
  }
  EXPECT_GT(accepted_, 1000);
  EXPECT_GT(refused_, 100);
  std::cout << "[          ] sequence folders: " << accepted_ << " accepted, " << refused_ << " refused\n";
}
