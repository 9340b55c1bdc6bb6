// The development zoo end to end, as a user runs it: every scene rendered by sgd_render, mapped by
// dem_offline with the shipped defaults (config/kitti.yaml), scored by sgd_evaluate; the real KITTI
// clips of ../shared mapped and scored against their GPS/IMU poses and (raw drive 0013) the LiDAR
// ground reference. The same chain as scripts/evaluate_zoo.py; docs/results.md has the table.
//
// Each limit sits between the measured figure (the comment after it) and twice it, so a 2x
// regression of any figure fails. Where the measured figure misses the target of issue 10
// (rotation <= 0.5 deg, drift <= 1 %, heights within 20 m median <= 2 cm, 95th <= 6 cm) the
// limit guards what we have and the case is named in docs/results.md.
#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

const std::string kBin = SGD_BIN_DIR;
const std::string kSource = SGD_SOURCE_DIR;
// ../shared beside the repository (the source dir may be a symlink in the catkin workspace)
const std::string kShared = (fs::weakly_canonical(fs::path(kSource)).parent_path() / "shared").string();

struct Limits {
  const char* name;
  int frames;
  double drift_pct;      ///< end drift / path length
  double rotation_deg;   ///< end rotation error
  double median_cm;      ///< |height error| within 20 m, median
  double p95_cm;         ///< and 95th percentile
  double min_coverage;   ///< known / seen vertices within 20 m
  // The obstacle layer against the scene's footprints (sgd_evaluate, "obstacles"); negative: not checked.
  double max_free_flagged_pct = -1.0;   ///< free ground marked obstacle
  double max_ghost_pct = -1.0;          ///< cells a mover left, seen again, still marked
  double min_static_recall_pct = -1.0;  ///< static footprint cells in view marked
};

std::ostream& operator<<(std::ostream& os, const Limits& l) { return os << l.name; }

struct Figures {
  int failed = -1;
  double drift_pct = NAN, rotation_deg = NAN, median_cm = NAN, p95_cm = NAN, coverage = NAN;
  double free_flagged_pct = NAN, ghost_pct = NAN, static_recall_pct = NAN;
};

int sh(const std::string& cmd) {
  const int raw = std::system(cmd.c_str());
  return WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
}

std::string slurp(const std::string& path) {
  std::ifstream f(path);
  std::ostringstream os;
  os << f.rdbuf();
  return os.str();
}

int failedFrames(const std::string& out) {
  std::istringstream is(slurp(out + "/summary.txt"));
  std::string line;
  while (std::getline(is, line))
    if (line.rfind("failed: ", 0) == 0) return std::stoi(line.substr(8));
  return -1;
}

/// The number after "key: " in `text` from `from` on (NaN if absent).
double numberAfter(const std::string& text, const std::string& key, size_t from = 0) {
  const size_t at = text.find(key + ": ", from);
  if (at == std::string::npos) return NAN;
  return std::strtod(text.c_str() + at + key.size() + 2, nullptr);
}

/// sgd_evaluate's evaluation.yaml: trajectory and DEM figures (flow-style lines, read by key).
void readEvaluation(const std::string& out, Figures* f) {
  const std::string text = slurp(out + "/evaluation.yaml");
  ASSERT_FALSE(text.empty()) << out;
  f->drift_pct = numberAfter(text, "end_drift_pct");
  f->rotation_deg = numberAfter(text, "end_rotation_error_deg");
  const size_t w = text.find("within_20m:");
  if (w != std::string::npos) {
    f->median_cm = 100.0 * numberAfter(text, "median_m", w);
    f->p95_cm = 100.0 * numberAfter(text, "p95_m", w);
    f->coverage = numberAfter(text, "coverage", w);
  }
  const size_t o = text.find("obstacles: {");
  if (o != std::string::npos) {
    f->free_flagged_pct = numberAfter(text, "free_flagged_pct", o);
    f->ghost_pct = numberAfter(text, "ghost_pct", o);
    f->static_recall_pct = numberAfter(text, "static_recall_pct", o);
  }
}

class Zoo : public ::testing::TestWithParam<Limits> {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("sgd_zoo_" + std::to_string(::getpid()) + "_" + GetParam().name);
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  /// Maps `seq` with the defaults (or `config`) and scores it; the figures are printed for the record.
  Figures mapAndScore(const std::string& seq, const std::string& config = kSource + "/config/kitti.yaml") {
    const std::string out = (dir_ / "out").string();
    Figures f;
    EXPECT_EQ(sh(kBin + "/dem_offline --sequence " + seq + " --out " + out + " --config " + config + " --quiet > " +
                 out + ".log 2>&1"),
              0)
        << slurp(out + ".log");
    f.failed = failedFrames(out);
    EXPECT_EQ(sh(kBin + "/sgd_evaluate --sequence " + seq + " --result " + out + " > /dev/null"), 0);
    readEvaluation(out, &f);
    return f;
  }
  void expectWithin(const Limits& l, const Figures& f, int expected_failed = 0) {
    std::printf("[ zoo      ] %-14s failed %d  drift %.3f %%  rotation %.3f deg  height median %.2f cm  p95 %.2f cm  "
                "coverage %.1f %%\n",
                l.name, f.failed, f.drift_pct, f.rotation_deg, f.median_cm, f.p95_cm, 100.0 * f.coverage);
    EXPECT_EQ(f.failed, expected_failed);
    EXPECT_LT(f.drift_pct, l.drift_pct);
    EXPECT_LT(f.rotation_deg, l.rotation_deg);
    EXPECT_LT(f.median_cm, l.median_cm);
    EXPECT_LT(f.p95_cm, l.p95_cm);
    EXPECT_GT(f.coverage, l.min_coverage);
    if (l.max_free_flagged_pct >= 0.0) {
      std::printf("[ zoo      ] %-14s obstacle layer: free ground flagged %.2f %%, ghosts %.1f %%, static recall %.1f %%\n",
                  l.name, f.free_flagged_pct, f.ghost_pct, f.static_recall_pct);
      EXPECT_LT(f.free_flagged_pct, l.max_free_flagged_pct);
      EXPECT_LT(f.ghost_pct, l.max_ghost_pct);
      EXPECT_GT(f.static_recall_pct, l.min_static_recall_pct);
    }
  }
  /// The rows of the last mapAndScore's frames.csv (frame,stamp_s,status,...,message), header skipped.
  std::vector<std::string> frameRows() const {
    std::istringstream csv(slurp((dir_ / "out" / "frames.csv").string()));
    std::string line;
    std::vector<std::string> rows;
    std::getline(csv, line);  // header
    while (std::getline(csv, line)) rows.push_back(line);
    return rows;
  }
  /// config/kitti.yaml with the camera 0.8 m above the ground, in the test's directory.
  /// Renders scene l.name, l.frames frames, from the low camera (0.8 m) into `seq`: 0 on success.
  int renderLowCamera(const Limits& l, const std::string& seq) const {
    return sh(kBin + "/sgd_render --scene " + l.name + " --camera-height 0.8 --frames " + std::to_string(l.frames) +
              " --out " + seq + " --quiet");
  }
  std::string lowCameraConfig() const {
    const std::string config = (dir_ / "low_camera.yaml").string();
    std::ifstream in(kSource + "/config/kitti.yaml");
    std::ofstream out(config);
    std::string line;
    while (std::getline(in, line))
      if (line.rfind("nominal_height_m:", 0) != 0) out << line << "\n";
    out << "nominal_height_m: 0.8\n";
    return config;
  }
  fs::path dir_;
};

class Scene : public Zoo {};

TEST_P(Scene, MappedWithinItsMeasuredFigures) {
  const Limits& l = GetParam();
  const std::string seq = (dir_ / "seq").string();
  ASSERT_EQ(sh(kBin + "/sgd_render --scene " + l.name + " --frames " + std::to_string(l.frames) + " --out " + seq +
               " --quiet"),
            0);
  expectWithin(l, mapAndScore(seq));
}

// name, frames, drift %, rotation deg, median cm, p95 cm, min coverage   (measured 2026-12-03)
// Since 2026-12-07 heights the photometric residual keeps contradicting are published as unknown
// (residual_max_published_outlier_rate; docs/results.md, "Heights the images contradict"): the
// coverage floors of ramp, shadows, rolling, off-road, traffic and the raw clip dropped with the
// heights they counted (ramp: 1,052 cells unpublished, median error 38 cm), the 95th limits tightened.
INSTANTIATE_TEST_SUITE_P(
    Zoo, Scene,
    ::testing::Values(Limits{"flat", 40, 0.05, 0.035, 0.18, 0.9, 0.98},            // 0.03 0.020 0.11 0.56 1.00
                      Limits{"bump", 40, 0.13, 0.09, 1.0, 3.5, 0.97},               // 0.07 0.053 0.67 2.28 0.997
                      Limits{"offroad", 40, 0.13, 0.09, 0.7, 5.5, 0.86},            // 0.06 0.030 0.29 2.86 0.905 (0.30 4.14 0.923 while heights the residual contradicts were published; 0.06 0.034 0.34 4.77 0.922 before the step solved with its own evaluation's planes; 0.35 5.93 0.938 while heights without information were published; 0.07 0.047 0.36 5.64 before far_depth_ratio; coverage 0.848 before it counted only ground in sight)
                      Limits{"crest", 40, 0.09, 0.24, 1.9, 9.5, 0.97},              // 0.05 0.127 1.00 5.14 0.997 (0.10 0.182 2.82 9.04 without skyline_mask)
                      Limits{"sag", 40, 0.04, 0.055, 0.65, 2.6, 0.97},              // 0.02 0.035 0.44 1.70 0.997
                      Limits{"banked_curve", 40, 0.05, 0.09, 0.5, 2.0, 0.98},       // 0.03 0.055 0.35 1.41 1.00
                      Limits{"bounce", 40, 0.05, 0.03, 0.45, 2.2, 0.97},            // 0.01 0.004 0.24 1.13 0.998 (0.39 0.068 0.75 1.93 before search_pitch_rad; 1.81 0.460 2.37 6.39 without prealign_refine_iterations)
                      Limits{"tight_curve", 40, 0.07, 0.16, 1.3, 3.8, 0.96},        // 0.05 0.097 0.83 2.41 0.983
                      Limits{"ramp", 40, 0.15, 0.30, 0.7, 8.0, 0.83},               // 0.09 0.196 0.36 4.04 0.861 (0.40 57.2 0.934 while heights the residual contradicts were published: the mesh draped behind the far guardrail, docs/results.md; 0.10 0.213 0.43 59.5 0.937 on 2026-12-03)
                      Limits{"rolling", 40, 0.3, 0.5, 0.8, 7.5, 0.83},              // 0.12 0.270 0.41 3.95 0.856 (0.41 4.30 0.863 while heights the residual contradicts were published; 0.15 0.261 0.41 4.91 0.861 before the step solved with its own evaluation's planes; 0.49 69.9 0.888 while heights a far ray refuted were published: 390 vertices within 20 m, median error 0.99 m, docs/results.md; 0.50 70.2 0.901 while heights without information were published; 0.18 0.451 0.46 91.2 0.868 before the far rays' ceilings; 0.56 1.78 0.47 92.3 0.855 before far_ground_seeds; 1.08 3.66 0.72 89.1 0.934 before far_depth_ratio and temporal_visibility: ground past the crest is no longer fused; 1.64 3.48 0.73 88.0 0.917 before carry_moving_texture; 3.34 3.15 0.73 87.1 before max_acceleration_mps2; 2.62 3.05 0.72 87.1 before hypothesis_win_ratio 0.9; 5.41 3.10 0.64 113 before the obstacle layer's two-frame rule, 7.82 4.90 2.80 64.3 without skyline_mask)
                      // + obstacle layer: free ground flagged %, ghosts %, static recall % (measured 3.72 8.7 -, 8.54 10.5 99.3
                      // with hypothesis_win_ratio 0.9; 3.97 9.4 -, 8.57 10.5 99.3 with the obstacle's foot and two frames' evidence; 5.72 23.0 -, 15.3 11.5 99.3 before; the targets of
                      // issue 10 are 2 % and no ghosts: docs/results.md, "The obstacle layer")
                      Limits{"shadows", 40, 0.45, 0.25, 1.0, 7.5, 0.90, 5.0, 15.0, -2.0},    // 0.23 0.119 0.35 3.85 0.931, flagged 2.7 %, ghosts 13.9 % (0.38 7.22 0.984 while heights the residual contradicts were published; ghosts seen again only in a free line of sight since 2026-12-06: 17.6 % -> 13.7 % by the earlier count of the same run; 0.25 0.147 0.42 7.1 before the step solved with its own evaluation's planes; 0.36 0.250 0.37 7.1, 2.7 %, 17.4 % before repeat_from_prediction; 0.38 7.8 0.995 while heights without information were published; 0.40 0.292 0.42 8.5, 2.7 %, 16.7 % before temporal_visibility; 0.56 0.498 0.51 8.4, 2.3 %, 15.2 % before obstacle_continue_at_left_border; 0.73 0.676 1.00 14.5 before carry_moving_texture; 1.28 1.010 0.98 14.2 before max_acceleration_mps2; 1.27 0.996 0.93 14.3 before hypothesis_win_ratio)
                      Limits{"traffic", 40, 0.10, 0.18, 0.36, 2.5, 0.87, 16.0, 8.0, 95.0}),  // 0.05 0.131 0.30 2.02 0.896, flagged 9.1 %, ghosts 5.4 % (2.05 0.911 while heights the residual contradicts were published; in a free line of sight; 10.9 % -> 5.4 % by the earlier count; 0.03 0.115 0.30 1.97, 9.4 % before the step solved with its own evaluation's planes; 0.05 0.096 0.29 2.02, 9.3 %, 11.0 % before repeat_from_prediction; 0.06 0.119 0.30 2.07, 9.2 %, 10.4 % before obstacle_continue_at_left_border; 0.063 0.113 0.26 1.76 before carry_moving_texture; 0.055 0.102 0.26 1.72 before hypothesis_win_ratio)
    [](const ::testing::TestParamInfo<Limits>& i) { return std::string(i.param.name); });

// Other terrain seeds where a mechanism decides the result. Rolling seed 2: the hill ahead rises
// more than ground_band_m out of the surface and the obstacle test takes it for upright; without
// rising_ground_seeds it stays excluded, flagged and unmapped (1.25 % / 0.665 deg / 5.08 / 53.1 cm,
// coverage 0.829, free ground flagged 10.2 %).
class SceneSeed2 : public Zoo {};

TEST_P(SceneSeed2, MappedWithinItsMeasuredFigures) {
  const Limits& l = GetParam();
  const std::string seq = (dir_ / "seq").string();
  ASSERT_EQ(sh(kBin + "/sgd_render --scene " + l.name + " --seed 2 --frames " + std::to_string(l.frames) + " --out " +
               seq + " --quiet"),
            0);
  expectWithin(l, mapAndScore(seq));
}

INSTANTIATE_TEST_SUITE_P(Zoo, SceneSeed2,
                         ::testing::Values(Limits{"rolling", 40, 0.3, 0.2, 1.3, 13.0, 0.80, 9.0, 1.0, -1.0}),  // 0.15 0.110 0.65 7.20 0.824, flagged 6.1 % (0.68 7.79 0.844 while heights the residual contradicts were published; 0.15 0.099 0.67 6.56 0.826, 6.3 % before the step solved with its own evaluation's planes; 0.78 22.7 0.853 while heights a far ray refuted were published; 0.84 28.0 0.882 while heights without information were published)
                         [](const ::testing::TestParamInfo<Limits>& i) { return std::string(i.param.name); });

// A low camera (a small robot's, 0.8 m above the ground instead of 1.65 m), the defaults with its
// height set (nominal_height_m: 0.8). Off-road: beside the track an embankment fills the right of
// the image; the near ground's disparities slant too fast for the sparse matches, and the start-up
// took the embankment's plane (tilted 32 deg, 4.2 m "below" the camera) for the ground until the
// start-up plane had to lie within nominal_max_tilt_rad (0.35) of the mounted attitude.
class LowCamera : public Zoo {};

TEST_P(LowCamera, MappedWithinItsMeasuredFigures) {
  const Limits& l = GetParam();
  const std::string seq = (dir_ / "seq").string();
  ASSERT_EQ(renderLowCamera(l, seq), 0);
  expectWithin(l, mapAndScore(seq, lowCameraConfig()));
}

// name, frames, drift %, rotation deg, median cm, p95 cm, min coverage   (measured 2026-12-07)
INSTANTIATE_TEST_SUITE_P(Zoo, LowCamera,
                         ::testing::Values(Limits{"offroad", 40, 0.09, 0.30, 0.8, 7.0, 0.85},   // 0.05 0.156 0.41 4.02 0.893 (1.15 3.461 5.98 403 0.26 with nominal_max_tilt_rad 0: the start-up on the slope)
                                           Limits{"crest", 10, 0.08, 0.075, 0.6, 5.2, 0.90}),  // 0.04 0.037 0.29 2.57 0.96 (2 failed, 22.3 0.018 2.41 5.88 0.92 without the matches along the expected ground: no plane in frames 0-1)
                         [](const ::testing::TestParamInfo<Limits>& i) { return std::string(i.param.name); });

// The rolling scene from 0.8 m, frames 0-19: at frames 16-18 the vehicle crosses a ditch, pitching
// 3.6, 9.3 and 3.6 deg up in three frames, and from that low the camera then sees little but sky.
// Frame 16's alignment converged on the stereo pair (its final level) with a motion that leaves the
// previous image 28.6 grey off (usual 1.4): it was fused as tracked, and the map and the motion ran
// away (40 frames: drift 22 %, end rotation 25.9 deg). Now the tracking check tests the temporal
// pair against its own level: frames 16-18 fail, their poses coast at the last velocity, and frame
// 19 is re-localized against the map from the stereo pair's attitude (standing still at the last
// good pose lost the 4 m driven meanwhile: 20.3 % drift; the stereo pair's own re-initialization
// kept the coasted heading, 1.24 deg of yaw). The coverage is lower than with the stereo pair's
// surface fused at frame 19 (the last frame here): the tracked frame fuses what it observed.
class LowCameraDitch : public Zoo {};

TEST_P(LowCameraDitch, AWrongMotionFailsAndThePoseCoasts) {
  const Limits& l = GetParam();
  const std::string seq = (dir_ / "seq").string();
  ASSERT_EQ(renderLowCamera(l, seq), 0);
  const Figures f = mapAndScore(seq, lowCameraConfig());
  const std::vector<std::string> row_text = frameRows();
  std::vector<std::string> status;
  for (const std::string& line : row_text) {
    const size_t a = line.find(',');
    const size_t b = line.find(',', a + 1);
    status.push_back(line.substr(b + 1, line.find(',', b + 1) - b - 1));
  }
  ASSERT_EQ(status.size(), static_cast<size_t>(l.frames));
  for (int k = 0; k < l.frames; ++k) {
    const char* expected = k == 0 ? "initialized" : k >= 16 && k <= 18 ? "failed" : k == 19 ? "recovered" : "tracked";
    EXPECT_EQ(status[static_cast<size_t>(k)], expected) << row_text[static_cast<size_t>(k)];
  }
  EXPECT_NE(row_text[16].find("the motion does not explain the previous image"), std::string::npos) << row_text[16];
  EXPECT_NE(row_text[19].find("re-localized against the map after 3 failures"), std::string::npos) << row_text[19];
  expectWithin(l, f, 3);
}

// name, frames, drift %, rotation deg, median cm, p95 cm, min coverage   (measured 2026-12-08)
INSTANTIATE_TEST_SUITE_P(Zoo, LowCameraDitch,
                         ::testing::Values(Limits{"rolling", 20, 0.6, 0.28, 0.42, 4.2, 0.55}),  // 0.33 0.145 0.22 2.16 0.605 (1.74 1.330 0.52 11.94 0.80 re-initialized from the stereo pair; 4.20 13.39 0.35 71.2 0.61 with frame 16 fused; 20.27 1.391 0.58 34.5 0.69 standing still at the last good pose)
                         [](const ::testing::TestParamInfo<Limits>& i) { return std::string(i.param.name); });

// Tracking lost for three frames (scripts/make_lost_stretch.py: frames 12-14 replaced by their own
// pair upside down, a consistent stereo pair of a world the map does not hold). Those frames must
// fail and fuse nothing: before the ground-support check (min_observed_fraction) the second of
// them was tracked with 0 of ~2,000 vertices observed and every scene ended 4-51 m off (the rolling
// scene still does: its upside-down hills look like ground, docs/results.md). Frame 15
// is then re-localized: tracked against the map and frame 11's images from the stereo pair's
// attitude (relocalize_against_map); the stereo pair's own re-initialization took the coasted
// heading and ended 2.04 deg off on off-road, 0.52 deg on the sag.
class LostStretch : public Zoo {};

TEST_P(LostStretch, ForeignFramesFailAndTheMapRelocalizes) {
  const Limits& l = GetParam();
  const std::string rendered = (dir_ / "rendered").string(), seq = (dir_ / "seq").string();
  ASSERT_EQ(sh(kBin + "/sgd_render --scene " + l.name + " --frames " + std::to_string(l.frames) + " --out " + rendered +
               " --quiet"),
            0);
  ASSERT_EQ(sh("/usr/bin/python3 " + kSource + "/scripts/make_lost_stretch.py --sequence " + rendered + " --out " + seq +
               " --first 12 --count 3 > /dev/null"),
            0);
  const Figures f = mapAndScore(seq);
  const std::vector<std::string> rows = frameRows();
  ASSERT_EQ(rows.size(), static_cast<size_t>(l.frames));
  for (int k = 12; k <= 14; ++k) EXPECT_NE(rows[static_cast<size_t>(k)].find(",failed,"), std::string::npos) << rows[static_cast<size_t>(k)];
  // The first foreign frame (the velocity still known) fails the tracking check (sag: the ground
  // support, 49 of ~3,700 vertices observed; off-road: the temporal pair); the next ones are placed
  // without a velocity and must first show ground near the mounted attitude.
  for (int k = 13; k <= 14; ++k)
    EXPECT_NE(rows[static_cast<size_t>(k)].find("no ground in view near the mounted attitude"), std::string::npos)
        << rows[static_cast<size_t>(k)];
  EXPECT_NE(rows[15].find(",recovered,"), std::string::npos) << rows[15];
  EXPECT_NE(rows[15].find("re-localized against the map after 3 failures"), std::string::npos) << rows[15];
  expectWithin(l, f, 3);
}

// name, frames, drift %, rotation deg, median cm, p95 cm, min coverage   (measured 2026-12-08)
INSTANTIATE_TEST_SUITE_P(Zoo, LostStretch,
                         ::testing::Values(Limits{"offroad", 40, 0.13, 0.08, 0.65, 6.0, 0.85},  // 0.07 0.042 0.35 3.15 0.897 (0.24 2.038 with the stereo pair's re-initialization)
                                           Limits{"sag", 40, 0.025, 0.05, 0.7, 2.8, 0.97}),      // 0.01 0.028 0.37 1.46 0.992 (0.29 0.520 with the stereo pair's re-initialization)
                         [](const ::testing::TestParamInfo<Limits>& i) { return std::string(i.param.name); });

class RealClip : public Zoo {};

TEST_P(RealClip, MappedWithinItsMeasuredFigures) {
  const Limits& l = GetParam();
  const std::string seq = kShared + "/data/" + l.name;
  if (!fs::exists(seq + "/times.txt")) GTEST_SKIP() << seq << " is not there (../shared beside the repository)";
  Figures f = mapAndScore(seq);
  // Heights of the raw clip: against the LiDAR ground reference (gt/lidar_ground.npz) with the
  // LiDAR's poses, as ../shared/tools/lidar_dem_eval.py scores them.
  if (fs::exists(seq + "/gt/lidar_ground.npz")) {
    const std::string json = (dir_ / "lidar.json").string();
    ASSERT_EQ(sh("/usr/bin/python3 " + kShared + "/tools/lidar_dem_eval.py --ref " + seq + " --est " +
                 (dir_ / "out").string() + " --pose lidar --json > " + json),
              0);
    const std::string text = slurp(json);  // {"dem": {"all": {..., "median_abs": x, ..., "p95": x}, ..., "coverage_pct": x}}
    const size_t all = text.find("\"all\": {");
    ASSERT_NE(all, std::string::npos) << text;
    f.median_cm = 100.0 * numberAfter(text, "\"median_abs\"", all);
    f.p95_cm = 100.0 * numberAfter(text, "\"p95\"", all);
    f.coverage = numberAfter(text, "\"coverage_pct\"", all) / 100.0;
    // The obstacle layer against the LiDAR's obstacle cells (cars, poles, fences, hedges): the
    // share of the vertices over them that are marked, and of those over LiDAR ground. Measured
    // with the obstacle's foot and two frames' evidence (docs/results.md, "The obstacle layer"):
    // recall 0.723, false alarm 0.091 (0.771 / 0.139 before). Limits: a 2x regression of either.
    const size_t ob = text.find("\"obstacles\": {");
    ASSERT_NE(ob, std::string::npos) << text;
    EXPECT_GT(numberAfter(text, "\"recall\"", ob), 0.60) << text;
    EXPECT_LT(numberAfter(text, "\"false_alarm\"", ob), 0.18) << text;
    // The camera above the local ground (frames.csv) against the same plane fit on the LiDAR
    // reference, LiDAR poses (scripts/ground_attitude_eval.py). Measured: 71 of 80 frames scored,
    // |error| median / max: height 2.1 / 5.2 cm, pitch 0.11 / 0.53 deg, roll 0.59 / 1.25 deg (the
    // map's cross tilt: the roll is biased by -0.59 deg). Limits 2x.
    const std::string att_json = (dir_ / "attitude.json").string();
    ASSERT_EQ(sh("/usr/bin/python3 " + kSource + "/scripts/ground_attitude_eval.py --ref " + seq + " --est " +
                 (dir_ / "out").string() + " --json > " + att_json),
              0);
    const std::string att = slurp(att_json);  // {"frames": n, "scored": n, ..., "height_m": {"median": x, "median_abs": x, "max_abs": x}, ...}
    EXPECT_GE(numberAfter(att, "\"scored\""), 65) << att;
    const size_t h = att.find("\"height_m\""), pt = att.find("\"pitch_deg\""), rl = att.find("\"roll_deg\"");
    ASSERT_TRUE(h != std::string::npos && pt != std::string::npos && rl != std::string::npos) << att;
    EXPECT_LT(100.0 * numberAfter(att, "\"median_abs\"", h), 4.2) << att;
    EXPECT_LT(100.0 * numberAfter(att, "\"max_abs\"", h), 10.4) << att;
    EXPECT_LT(numberAfter(att, "\"median_abs\"", pt), 0.22) << att;
    EXPECT_LT(numberAfter(att, "\"max_abs\"", pt), 1.05) << att;
    EXPECT_LT(numberAfter(att, "\"median_abs\"", rl), 1.2) << att;
    EXPECT_LT(numberAfter(att, "\"max_abs\"", rl), 2.5) << att;
    // Against the images themselves (scripts/trajectory_consistency.py): the trajectory moves
    // tracked SGBM corners over 3 frames to within 2.00 px (median; the GPS/INS poses: 4.41 px)
    // and sees the same road from 14-20 m and from 5-8 m at the same height within 1.7 cm along
    // the clip (max - min of the stretch medians; the GPS/INS poses: 15.7 cm, their vertical
    // motion wanders by ~25 cm in frames 20-60, which the LiDAR reference inherits: results.md).
    const std::string tc_json = (dir_ / "consistency.json").string();
    ASSERT_EQ(sh("/usr/bin/python3 " + kSource + "/scripts/trajectory_consistency.py --sequence " + seq + " --json " +
                 tc_json + " gps_ins=" + seq + "/poses.txt ours=" + (dir_ / "out").string() +
                 "/trajectory_kitti.txt > /dev/null"),
              0);
    const std::string tc = slurp(tc_json);
    const size_t rp = tc.find("\"reprojection_px\""), rg = tc.find("\"near_minus_far_range_cm\"");
    ASSERT_TRUE(rp != std::string::npos && rg != std::string::npos) << tc;
    EXPECT_LT(numberAfter(tc, "\"ours\"", rp), 3.0) << tc;
    EXPECT_LT(numberAfter(tc, "\"ours\"", rg), 3.4) << tc;
    EXPECT_GT(numberAfter(tc, "\"gps_ins\"", rg), 10.0) << tc;  // a fact of the data, guards the tool
  } else {
    f.median_cm = f.p95_cm = 0.0;  // no height reference
    f.coverage = 1.0;
  }
  expectWithin(l, f);
}

// Stereo mode (one pair, as at start-up and relocalization) on the real clip's pairs, frames 0, 10,
// ..., 70, against its LiDAR ground reference within 6 m of the path (the road and its edges),
// 5-40 m deep, beside OpenCV SGBM's three modes (scripts/stereo_vs_lidar.py; docs/results.md,
// "Stereo mode against the LiDAR and SGBM's own modes"). Measured: ours coverage 81.0 %, median
// 0.511 px, D1 0.60 % (SGBM 3-way 94.9 %, 0.631 px, 4.99 %: moving cars in front of the reference
// ground); ours against SGBM 3-way D1 0.53 %, within SGBM's modes against each other (0.56-1.37 %),
// issue 10's yardstick for the stereo mode. (With the sequences' 0.8 px blur, before
// stereo_presmooth_sigma_px: 78.7 %, 0.572 px, D1 1.85 %; against SGBM 1.17 %.) Limits: a 2x
// regression of ours fails.
TEST(StereoMode, GroundAgreesWithTheLidarAndWithSgbmAsSgbmWithItself) {
  const std::string seq = kShared + "/data/kitti_raw_0926_d0013_f000-079";
  if (!fs::exists(seq + "/gt/lidar_ground.npz")) GTEST_SKIP() << seq << " is not there (../shared beside the repository)";
  const fs::path dir = fs::temp_directory_path() / ("sgd_stereo_lidar_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string json = (dir / "s.json").string();
  fs::create_directories(dir);
  ASSERT_EQ(sh("/usr/bin/python3 " + kSource + "/scripts/stereo_vs_lidar.py --ref " + seq + " --bin " + kBin +
               " --config " + kSource + "/config/kitti.yaml --out " + (dir / "out").string() + " --json " + json +
               " > /dev/null"),
            0);
  const std::string t = slurp(json);
  const size_t all = t.find("\"all\": {");
  ASSERT_NE(all, std::string::npos) << t;
  const size_t ours = t.find("\"ours\": {", all);
  ASSERT_NE(ours, std::string::npos) << t;
  EXPECT_GT(numberAfter(t, "\"coverage_pct\"", ours), 72.0) << t;
  EXPECT_LT(numberAfter(t, "\"median_px\"", ours), 0.70) << t;
  EXPECT_LT(numberAfter(t, "\"d1_pct\"", ours), 1.0) << t;
  double sgbm_self = 0.0;
  for (const char* pair : {"\"sgbm_3way~sgbm_5dir\"", "\"sgbm_3way~sgbm_hh\"", "\"sgbm_5dir~sgbm_hh\""}) {
    const size_t at = t.find(pair, all);
    ASSERT_NE(at, std::string::npos) << pair << t;
    EXPECT_GT(numberAfter(t, "\"pixels\"", at), 40000) << t;  // the reference is there (measured 57-61k)
    sgbm_self = std::max(sgbm_self, numberAfter(t, "\"d1_pct\"", at));
  }
  const size_t vs = t.find("\"ours~sgbm_3way\"", all);
  ASSERT_NE(vs, std::string::npos) << t;
  EXPECT_LE(numberAfter(t, "\"d1_pct\"", vs), sgbm_self) << t;
  EXPECT_LT(numberAfter(t, "\"median_px\"", vs), 0.40) << t;  // measured 0.262 (SGBM's modes 0.19-0.44)
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

// scripts/trajectory_consistency.py (docs/results.md, "The real clips' ground truth") on three
// trajectories of a rendered flat drive: a camera mounted 0.8 deg to the right and 0.3 deg up
// against the true one (the poses of a GPS/INS whose camera calibration is off: every pose T_k
// becomes M T_k M^T, M rotating directions by those angles), the exact poses, and the exact poses
// climbing 25 cm between frames 10 and 25 with the attitude unchanged (a GPS-like vertical wander,
// as the GPS/INS of KITTI raw 0013 in frames 20-60). Measured: road height far - near ranges over
// 0.5 cm with the truth, 16.9 cm with the wander; 3-frame reprojection 2.32 / 2.46 px overall,
// 4.0-4.2 px in the stretch of the wander.
TEST(TrajectoryConsistency, SeesAVerticalWanderAndAMountingRotationOfExactPoses) {
  const fs::path dir = fs::temp_directory_path() / ("sgd_consistency_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string seq = (dir / "flat").string();
  ASSERT_EQ(sh(kBin + "/sgd_render --scene flat --frames 40 --out " + seq + " --quiet"), 0);
  std::istringstream poses(slurp(seq + "/poses.txt"));
  std::ofstream wander(dir / "wander.txt"), mounted(dir / "mounted.txt");
  // yaw (right +) about y, then elevation (up +) about x: y points down, z forward
  const Eigen::Matrix3d m = (Eigen::AngleAxisd(0.3 * M_PI / 180.0, Eigen::Vector3d::UnitX()) *
                             Eigen::AngleAxisd(0.8 * M_PI / 180.0, Eigen::Vector3d::UnitY()))
                                .toRotationMatrix();
  std::string line;
  for (int k = 0; std::getline(poses, line); ++k) {
    std::istringstream is(line);
    double v[12];
    for (double& x : v) is >> x;
    Eigen::Matrix<double, 3, 4, Eigen::RowMajor> t(v), mt;
    mt << m * t.leftCols<3>() * m.transpose(), m * t.col(3);  // M [R t] M^T = [M R M^T, M t]
    for (int i = 0; i < 12; ++i) mounted << std::setprecision(12) << mt.data()[i] << (i == 11 ? "\n" : " ");
    v[7] -= 0.25 * std::min(std::max((k - 10) / 15.0, 0.0), 1.0);  // y points down: up 25 cm
    for (int i = 0; i < 12; ++i) wander << v[i] << (i == 11 ? "\n" : " ");
  }
  wander.close();
  mounted.close();
  const std::string json = (dir / "c.json").string();
  ASSERT_EQ(sh("/usr/bin/python3 " + kSource + "/scripts/trajectory_consistency.py --sequence " + seq + " --json " +
               json + " mounted=" + (dir / "mounted.txt").string() + " truth=" + seq +
               "/poses.txt wander=" + (dir / "wander.txt").string() + " > /dev/null"),
            0);
  const std::string tc = slurp(json);
  const size_t rg = tc.find("\"near_minus_far_range_cm\"");
  ASSERT_NE(rg, std::string::npos) << tc;
  EXPECT_LT(numberAfter(tc, "\"truth\"", rg), 1.0) << tc;
  EXPECT_GT(numberAfter(tc, "\"wander\"", rg), 12.0) << tc;
  // Direction of travel against the images' (essential matrix over 4 frames): the exact poses
  // within the tool's own bias (measured yaw +0.058, elevation -0.040 deg), the mounted camera
  // offset by its rotation on top of it (measured 0.858 / 0.260), and with that offset rotated
  // out the exact poses end 4.8 cm from the mounted ones (58.2 cm as given).
  const size_t dof = tc.find("\"direction_offset_deg\"");
  ASSERT_NE(dof, std::string::npos) << tc;
  const size_t mo = tc.find("\"mounted\"", dof), tr = tc.find("\"truth\"", dof);
  const double truth_yaw = numberAfter(tc, "\"yaw\"", tr), truth_el = numberAfter(tc, "\"elevation\"", tr);
  EXPECT_LT(std::abs(truth_yaw), 0.12) << tc;
  EXPECT_LT(std::abs(truth_el), 0.08) << tc;
  EXPECT_NEAR(numberAfter(tc, "\"yaw\"", mo) - truth_yaw, 0.8, 0.03) << tc;
  EXPECT_NEAR(numberAfter(tc, "\"elevation\"", mo) - truth_el, 0.3, 0.03) << tc;
  EXPECT_GT(numberAfter(tc, "\"direction_frames\""), 30) << tc;  // measured 36 of 36
  const size_t ee = tc.find("\"truth\"", tc.find("\"end_error_m\""));
  EXPECT_GT(numberAfter(tc, "\"as_given\"", ee), 0.5) << tc;
  EXPECT_LT(numberAfter(tc, "\"offset_rotated_out\"", ee), 0.10) << tc;
  // Step length against a stereo PnP of the images: the exact poses 0.9939 (the PnP's SGBM points
  // lie a little far), the mounted ones the same (a rotation keeps lengths).
  const size_t sl = tc.find("\"step_length_over_pnp\"");
  ASSERT_NE(sl, std::string::npos) << tc;
  EXPECT_NEAR(numberAfter(tc, "\"truth\"", sl), 0.9939, 0.004) << tc;
  EXPECT_NEAR(numberAfter(tc, "\"mounted\"", sl), numberAfter(tc, "\"truth\"", sl), 1e-4) << tc;
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(
    Kitti, RealClip,
    ::testing::Values(Limits{"kitti_raw_0926_d0013_f000-079", 80, 1.8, 0.75, 30.0, 60.0, 0.80},  // 1.26 0.430 20.6 40.9 0.849 (20.5 41.0 0.912 while heights the residual contradicts were published; 1.25 0.419 20.5 40.9 0.909 before the step solved with its own evaluation's planes; 1.25 0.395 20.7 41.7 on 2026-12-04; 1.22 0.420 20.9 41.2 0.931 before carry_moving_texture)
                      Limits{"kitti_odom_seq06_f000-050", 51, 1.6, 0.9, 1.0, 1.0, 0.5}),         // 1.04 0.590 (no heights; 0.97 0.609 before the step solved with its own evaluation's planes; 1.00 0.615 before repeat_from_prediction; 1.03 0.588 on 2026-12-04; 1.01 0.608 before obstacle_continue_at_left_border; 1.03 0.555 before carry_moving_texture; 1.05 0.593 before hypothesis_win_ratio)
    [](const ::testing::TestParamInfo<Limits>& i) {
      return std::string(i.param.name).rfind("kitti_raw", 0) == 0 ? std::string("RawDrive0013") : std::string("Odometry06");
    });

}  // namespace

/// A real clip with only every `frames`-th frame (Limits::frames is the stride here): the first
/// tracked frame comes a long gap after the initializing one, with no velocity known yet.
class GappedClip : public Zoo {
 protected:
  /// A KITTI-style folder of every stride-th frame of `seq` (symbolic links), its times and poses.
  std::string subsample(const std::string& seq, int stride) {
    return pick(seq, [stride](int k) { return k % stride == 0; });
  }
  /// ... of the frames `keep` accepts (by their index in `seq`).
  std::string pick(const std::string& seq, const std::function<bool(int)>& keep) {
    const fs::path out = dir_ / "seq";
    fs::create_directories(out / "image_l");
    fs::create_directories(out / "image_r");
    fs::copy_file(seq + "/calib.txt", out / "calib.txt");
    std::istringstream times(slurp(seq + "/times.txt")), poses(slurp(seq + "/poses.txt"));
    std::ofstream t(out / "times.txt"), p(out / "poses.txt");
    std::string time_line, pose_line;
    char name[16];
    for (int k = 0, i = 0; std::getline(times, time_line) && std::getline(poses, pose_line); ++k) {
      if (!keep(k)) continue;
      for (const char* side : {"l", "r"}) {
        std::snprintf(name, sizeof(name), "%06d.png", k);
        const std::string src = seq + "/image_" + side + "/" + name;
        std::snprintf(name, sizeof(name), "%06d.png", i);
        fs::create_symlink(src, out / (std::string("image_") + side) / name);
      }
      t << time_line << "\n";
      p << pose_line << "\n";
      ++i;
    }
    return out.string();
  }
};

TEST_P(GappedClip, FirstLongGapFindsTheStep) {
  const Limits& l = GetParam();
  const std::string seq = kShared + "/data/" + l.name;
  if (!fs::exists(seq + "/times.txt")) GTEST_SKIP() << seq << " is not there (../shared beside the repository)";
  Figures f = mapAndScore(subsample(seq, l.frames));
  f.median_cm = f.p95_cm = 0.0;  // trajectory only
  f.coverage = 1.0;
  expectWithin(l, f);
}

// KITTI raw 0013 with only every n-th frame (a node that drops frames; full rate: 1.22 %, 0.42 deg).
// Every 3rd (0.3 s, ~3.6 m per step): the motion search without a velocity took the cheapest step
// (0.4 m: far ground and everything above it barely change there) and the constant velocity kept
// it: 124 % drift, 48.8 deg, every frame "tracked". With the local minima of the search as
// candidates: 1.97 %, 1.36 deg; with prealign_refine_iterations 8 (default): 1.71 %, 1.20 deg; with
// the prediction kept when no start moves (below): 1.67 %, 1.13 deg.
// Every 4th (4.7 m steps): 121 % -> 24-25 % with the search's local minima: under the overpass
// (frame 11) no pre-alignment start accepts a single Gauss-Newton step, the cheapest initial cost
// picked the half-step hypothesis and the constant velocity kept it. With the prediction kept when
// no start moved: 1.86 %, 0.91 deg. Every 2nd: 1.19 %, 0.65 deg (the bound, 1.5x the full
// rate, is 1.83 %).
// stride, drift %, rotation deg (measured 2026-12-03)
INSTANTIATE_TEST_SUITE_P(Kitti, GappedClip,
                         ::testing::Values(Limits{"kitti_raw_0926_d0013_f000-079", 2, 1.8, 1.1, 1.0, 1.0, 0.5},
                                           Limits{"kitti_raw_0926_d0013_f000-079", 3, 3.3, 2.2, 1.0, 1.0, 0.5},
                                           Limits{"kitti_raw_0926_d0013_f000-079", 4, 3.0, 1.6, 1.0, 1.0, 0.5}),
                         [](const ::testing::TestParamInfo<Limits>& info) {
                           return "RawDrive0013Every" + std::to_string(info.param.frames) +
                                  (info.param.frames == 2 ? "nd" : info.param.frames == 3 ? "rd" : "th");
                         });

/// The frames a nodelet kept of a real clip played at 10 Hz (the node processes one frame in two
/// or three; the first ones are slow): Limits::frames indexes kNodeFrames.
class NodeFrames : public GappedClip {};

// Frame indices logged by dem_nodelet.launch at 10 Hz on 2026-12-03 (scripts/ros_realtime_check.py,
// the worker's debug log), replayed offline (deterministic).
const std::vector<std::vector<int>> kNodeFrames = {
    // KITTI 06, holding two frames with a velocity (StartHoldPolicy): the 6-frame step 3 -> 9 came
    // out 10.84 m for 7.16 m (the 1.5x-step hypothesis beat the prediction by 3 % before
    // pre-alignment converged): 12.8 % drift, 1.77 deg; another start must beat the prediction's
    // cost clearly (hypothesis_win_ratio 0.9): 1.04 %, 0.76 deg
    {0, 1, 3, 9, 12, 19, 22, 24, 26, 30, 34, 37, 39, 41, 44, 46, 48, 50},
    // KITTI raw 0013 before StartHoldPolicy: the 11-frame step 3 -> 14 cost 1.2 deg of yaw: 2.92 %
    // (2.82 %, 0.75 deg with hypothesis_win_ratio; kept as a guard: a long step from one short one).
    // The temporal pair's check failed that step at first (4.7 grey against a level of 1.0 learnt
    // at 0.1-0.2 s gaps), and the search after it failed two more: 1.73 %, 2.03 deg; its limit now
    // grows with the gap (TrackingEvidence::temporal_gap_ratio): 2.83 %, 0.79 deg again
    {0, 1, 3, 14, 16, 18, 20, 22, 24, 26, 28, 30, 32, 34, 36, 38, 40, 42, 44, 46, 48, 50, 52, 54, 56, 58, 60, 62, 64, 66, 68, 70, 72, 74, 76, 78},
    // ... and the frames the policy keeps: 1.21 % (1.24 %, 0.56 deg with hypothesis_win_ratio)
    {0, 1, 3, 9, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31, 33, 35, 37, 39, 41, 43, 45, 47, 49, 51, 53, 55, 57, 59, 61, 63, 65, 67, 69, 71, 73, 75, 77, 79}};

TEST_P(NodeFrames, KeepTheTrajectory) {
  const Limits& l = GetParam();
  const std::string seq = kShared + "/data/" + l.name;
  if (!fs::exists(seq + "/times.txt")) GTEST_SKIP() << seq << " is not there (../shared beside the repository)";
  const std::vector<int>& kept = kNodeFrames.at(static_cast<size_t>(l.frames));
  Figures f = mapAndScore(pick(seq, [&kept](int k) { return std::find(kept.begin(), kept.end(), k) != kept.end(); }));
  f.median_cm = f.p95_cm = 0.0;  // trajectory only
  f.coverage = 1.0;
  expectWithin(l, f);
}

std::string nodeFramesName(const ::testing::TestParamInfo<Limits>& info) {
  static const char* const kNames[] = {"Odometry06HoldingTwo", "RawDrive0013NoHold", "RawDrive0013HoldingTwo"};
  return kNames[info.param.frames];
}

// clip, pattern, drift %, rotation deg (measured 2026-12-03: see kNodeFrames)
INSTANTIATE_TEST_SUITE_P(Kitti, NodeFrames,
                         ::testing::Values(Limits{"kitti_odom_seq06_f000-050", 0, 1.8, 1.3, 1.0, 1.0, 0.5},
                                           Limits{"kitti_raw_0926_d0013_f000-079", 1, 4.5, 1.3, 1.0, 1.0, 0.5},
                                           Limits{"kitti_raw_0926_d0013_f000-079", 2, 2.0, 1.0, 1.0, 1.0, 0.5}),
                         nodeFramesName);
