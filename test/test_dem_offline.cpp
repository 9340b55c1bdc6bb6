// The offline runner as a user meets it: outputs on the bundled KITTI sample, one-line errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>
#include <sys/stat.h>
#include <sys/wait.h>

#include "offline_runner.hpp"
#include "same_layer.hpp"
#include "stereo_ground_dem/io/DemMetadata.hpp"
#include "stereo_ground_dem/io/DisparityPng.hpp"
#include "stereo_ground_dem/io/GeoTiff.hpp"

using namespace stereo_ground_dem;
using namespace sgd_test;

namespace {

class DemOffline : public TempDirTest {};

bool exists(const std::string& p) { return fs::exists(p); }

}  // namespace

TEST_F(DemOffline, OnePairWritesTheDemOnRealKitti) {
  const std::string out = path("pair");
  const Outcome r = run("--left " + kSample + "/image_l/000000.png --right " + kSample + "/image_r/000000.png --calib " +
                    kSample + "/calib.txt --out " + out);
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* f : {"dem.tif", "dem.yaml", "dem_disparity_000000.png", "dem_height.png", "traversability.tif"}) {
    EXPECT_TRUE(exists(out + "/" + f)) << f;
  }
  GroundGrid grid;
  const cv::Mat dem = GeoTiff::read(out + "/dem.tif", &grid);
  const DemMetadata meta = DemMetadata::read(out + "/dem.yaml");
  EXPECT_TRUE(meta.grid().sameLayout(grid));
  EXPECT_DOUBLE_EQ(meta.resolution_m, 0.5);
  // The camera is ~1.65 m above the fitted ground, looking forward (optical z ~ ground x).
  EXPECT_NEAR(meta.ground_T_camera0.translation().z(), 1.65, 0.1);
  EXPECT_GT(meta.ground_T_camera0.linear()(0, 2), 0.99);
  // The road ahead (x 6..12 m, |y| < 1 m) is known, smooth and near zero height.
  int known = 0;
  double max_abs = 0.0;
  for (int r2 = 0; r2 < grid.rows; ++r2)
    for (int c = 0; c < grid.cols; ++c) {
      const double x = grid.xOfCol(c), y = grid.yOfRow(r2);
      if (x < 6 || x > 12 || std::abs(y) > 1.0) continue;
      const float h = dem.at<float>(r2, c);
      if (!std::isfinite(h)) continue;
      ++known;
      max_abs = std::max(max_abs, std::abs(static_cast<double>(h)));
    }
  EXPECT_GT(known, 40);
  EXPECT_LT(max_abs, 0.25);
  // Disparity PNG: the road at the bottom centre of the image has 30..100 px of disparity.
  const cv::Mat d = DisparityPng::read(out + "/dem_disparity_000000.png", 0.0f);
  EXPECT_EQ(d.cols, 1226);
  EXPECT_GT(d.at<float>(350, 650), 30.0f);
  EXPECT_LT(d.at<float>(350, 650), 100.0f);
  EXPECT_EQ(d.at<float>(50, 650), 0.0f);  // sky: none
}

TEST_F(DemOffline, SequenceModeOnTheBundledSample) {
  const std::string out = path("seq");
  const Outcome r = run("--sequence " + kSample + " --out " + out + " --frames 4 --quiet");
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* f : {"dem.tif", "dem.yaml", "trajectory_kitti.txt", "trajectory_tum.txt", "timing.csv",
                        "alignments.csv", "variance.tif", "traversability.tif", "mesh.ply", "summary.txt", "dem_disparity_000000.png",
                        "intensity.tif", "ortho.tif", "ortho.png", "residual.tif", "residual_outlier_rate.tif"}) {
    EXPECT_TRUE(exists(out + "/" + f)) << f;
  }
  // alignments.csv: every Gauss-Newton pass of the tracked frames, coarse to fine; a tracked frame
  // ends with the joint passes at pyramid level 1 (two pairs, motion and heights) and level 0
  // (the stereo pair, heights only).
  {
    std::ifstream csv(out + "/alignments.csv");
    std::string header, row;
    ASSERT_TRUE(std::getline(csv, header));
    EXPECT_EQ(header.rfind("frame,pass,level,pairs,motion,heights,iterations,", 0), 0u) << header;
    std::vector<std::vector<std::string>> rows;
    while (std::getline(csv, row)) {
      std::vector<std::string> f;
      std::istringstream rs(row);
      for (std::string c; std::getline(rs, c, ',');) f.push_back(c);
      ASSERT_EQ(f.size(), 21u) << row;
      rows.push_back(f);
    }
    ASSERT_GE(rows.size(), 6u);  // frames 1-3, at least two joint passes each
    const std::vector<std::string>& last = rows.back();
    EXPECT_EQ(last[0], "3");
    EXPECT_EQ(last[2], "0");  // level 0
    EXPECT_EQ(last[3], "1");  // the stereo pair
    EXPECT_EQ(last[4], "0");  // no motion
    EXPECT_EQ(last[5], "1");  // heights
    EXPECT_GT(std::stoi(last[9]), 1);    // evaluations
    EXPECT_GT(std::stoi(last[16]), 1000);  // samples
    // a stalled pass spends nothing on the final undamped step
    for (const auto& f : rows) {
      if (f[19] == "1") EXPECT_EQ(f[20], "0") << "frame " << f[0] << " pass " << f[1];
    }
    bool joint_level1 = false;
    for (const auto& f : rows) joint_level1 = joint_level1 || (f[0] == "3" && f[2] == "1" && f[3] == "2" && f[4] == "1" && f[5] == "1");
    EXPECT_TRUE(joint_level1);
  }
  // Heights the images kept contradicting (outlier rate >= residual_max_published_outlier_rate,
  // 0.5) are published as unknown.
  {
    GroundGrid dg, rg;
    const cv::Mat dem = GeoTiff::read(out + "/dem.tif", &dg);
    const cv::Mat rate = GeoTiff::read(out + "/residual_outlier_rate.tif", &rg);
    ASSERT_TRUE(dg.sameLayout(rg));
    const cv::Mat contradicted = rate >= 0.5f, known = dem == dem;
    const int n_contradicted = cv::countNonZero(contradicted), n_known = cv::countNonZero(known);
    std::printf("[ residual ] %d cells contradicted, %d heights published\n", n_contradicted, n_known);
    EXPECT_GT(n_contradicted, 0);  // measured 69 (of 2,391 heights published)
    EXPECT_EQ(cv::countNonZero(contradicted & known), 0);
  }
  // The ortho-texture: 4 frames of the KITTI road, 0.1 m texels, grey levels of a real road.
  GroundGrid og;
  const cv::Mat ortho = GeoTiff::read(out + "/ortho.tif", &og);
  EXPECT_DOUBLE_EQ(og.resolution_m, 0.1);
  const cv::Mat known_texels = ortho == ortho;
  // Measured: 34,976 texels known (350 m^2 of road and verge), grey 75.5 +- 25.5 (9..202).
  EXPECT_GT(cv::countNonZero(known_texels), 17500);
  double lo = 0.0, hi = 0.0;
  cv::minMaxLoc(ortho, &lo, &hi, nullptr, nullptr, known_texels);
  EXPECT_GE(lo, 0.0);
  EXPECT_LE(hi, 255.0);
  cv::Scalar mean, stddev;
  cv::meanStdDev(ortho, mean, stddev, known_texels);
  std::printf("[ ortho ] %d texels known, grey %.1f +- %.1f (%.0f..%.0f)\n", cv::countNonZero(known_texels), mean[0],
              stddev[0], lo, hi);
  EXPECT_NEAR(mean[0], 75.5, 15.0);
  EXPECT_GT(stddev[0], 12.0);
  std::ifstream traj(out + "/trajectory_kitti.txt");
  std::string line;
  int n = 0;
  double z_last = 0.0;
  while (std::getline(traj, line)) {
    std::istringstream ss(line);
    double v[12];
    for (double& x : v) ss >> x;
    z_last = v[11];
    ++n;
  }
  EXPECT_EQ(n, 4);
  EXPECT_NEAR(z_last, 3.576, 0.1);  // KITTI ground truth of frame 3: 3.576 m forward
  // The camera above the local ground: NaN while only the ground ahead is mapped (4 frames, 4 m).
  std::ifstream frames(out + "/frames.csv");
  std::string header;
  std::getline(frames, header);
  EXPECT_NE(header.find(",moving_pixels,ground_height_m,ground_pitch_deg,ground_roll_deg,prealign_shift_m,prealign_rejected,prealign_discarded,carried_moving_pixels,hidden_pixels,far_pixels,far_seeded_vertices,far_carved_vertices,rising_seeded_vertices,far_refuted_vertices,repeat_from_prediction,message"), std::string::npos)
      << header;
  const std::vector<std::string> heights = column(out, 13);
  ASSERT_EQ(heights.size(), 4u);
  for (const std::string& h : heights) EXPECT_EQ(h, "nan");
}

TEST_F(DemOffline, ResumeContinuesTheMapAsOneRun) {
  // The 6-frame sample in one run against frames 0-2 and then --resume for the rest: the DEM and
  // its layers must be identical bit for bit, and the trajectories must join (the state holds the
  // estimator's last frame, velocity and images; MapStateFile).
  const std::string whole = path("whole"), a = path("first_half"), b = path("second_half");
  ASSERT_EQ(run("--sequence " + kSample + " --out " + whole + " --quiet").status, 0);
  ASSERT_EQ(run("--sequence " + kSample + " --out " + a + " --frames 3 --quiet").status, 0);
  for (const char* f : {"state/state.yaml", "state/previous_left.tif", "state/previous_right.tif", "state/ortho.bin",
                        "state/residual.bin"})
    EXPECT_TRUE(exists(a + "/" + f)) << f;
  const Outcome r = run("--sequence " + kSample + " --out " + b + " --resume " + a + " --quiet");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> names = column(b, 0);
  ASSERT_EQ(names.size(), 3u);
  EXPECT_EQ(names.front(), "3");  // frames.csv counts the sequence's frames
  for (const char* f : {"dem.tif", "variance.tif", "obstacles.tif", "intensity.tif", "residual.tif",
                        "traversability_confidence.tif"}) {
    GroundGrid g1, g2;
    const cv::Mat m1 = GeoTiff::read(whole + "/" + f, &g1), m2 = GeoTiff::read(b + "/" + f, &g2);
    EXPECT_TRUE(g1.sameLayout(g2)) << f;
    EXPECT_TRUE(test::sameLayer(m1, m2)) << f;
  }
  auto lines = [](const std::string& file) {
    std::ifstream in(file);
    std::vector<std::string> v;
    for (std::string l; std::getline(in, l);) v.push_back(l);
    return v;
  };
  std::vector<std::string> joined = lines(a + "/trajectory_kitti.txt");
  for (const std::string& l : lines(b + "/trajectory_kitti.txt")) joined.push_back(l);
  EXPECT_EQ(joined, lines(whole + "/trajectory_kitti.txt"));
  // Resumed at an earlier frame (stamps going back, as with a state the node saved on the ROS
  // clock): the saved velocity and stamp are dropped and the motion searched from the saved pose.
  const Outcome earlier = run("--sequence " + kSample + " --out " + path("g") + " --resume " + a +
                              " --first-frame 1 --frames 2 --quiet");
  EXPECT_EQ(earlier.status, 0) << earlier.err;
  EXPECT_NE(earlier.err.find("on another clock than the saved state's"), std::string::npos) << earlier.err;
  // Frame 1 is found 1.2 m behind the saved frame 2. That step back took no time one can know: it
  // measures no velocity (MotionPredictor::distrustLastStamp). When it did (-12 m/s), frame 2 was
  // fused 2.4 m from the truth, then failed by the temporal pair's check.
  EXPECT_EQ(summary(path("g"))["mapped"], "2");
  const std::vector<std::string> resumed = lines(path("g") + "/trajectory_kitti.txt");
  const std::vector<std::string> truth = lines(kSample + "/poses.txt");
  ASSERT_EQ(resumed.size(), 2u);
  const auto z = [](const std::string& l) {  // the 12th number: the forward position
    std::istringstream in(l);
    double v = 0.0;
    for (int i = 0; i < 12; ++i) in >> v;
    return v;
  };
  EXPECT_NEAR(z(resumed[0]), z(truth[1]), 0.05);
  EXPECT_NEAR(z(resumed[1]), z(truth[2]), 0.05);
  // Nothing left to continue, a directory without a saved map, another layout: one line, exit 1.
  const Outcome done = run("--sequence " + kSample + " --out " + path("c") + " --resume " + b + " --quiet");
  EXPECT_EQ(done.status, 1);
  EXPECT_NE(done.err.find("the first frame 6 is past the sequence's 6 frames (the resumed run stopped there)"),
            std::string::npos) << done.err;
  const Outcome missing = run("--sequence " + kSample + " --out " + path("d") + " --resume " + path("nowhere"));
  EXPECT_EQ(missing.status, 1);
  EXPECT_NE(missing.err.find("is not a directory"), std::string::npos) << missing.err;
  const Outcome no_state = run("--sequence " + kSample + " --out " + path("f") + " --resume " + kSample);
  EXPECT_EQ(no_state.status, 1);
  EXPECT_NE(no_state.err.find("holds no saved map (no state.yaml)"), std::string::npos) << no_state.err;
  std::ofstream(path("coarse.yaml")) << "grid_resolution_m: 1.0\n";
  const Outcome layout = run("--sequence " + kSample + " --out " + path("e") + " --config " + path("coarse.yaml") +
                             " --resume " + a + " --quiet");
  EXPECT_EQ(layout.status, 1);
  EXPECT_NE(layout.err.find("saved with grid_resolution_m 0.5"), std::string::npos) << layout.err;
  for (const Outcome* o : {&done, &missing, &no_state, &layout}) EXPECT_EQ(std::count(o->err.begin(), o->err.end(), '\n'), 1) << o->err;
}

TEST_F(DemOffline, BadInputGivesOneLineAndNonZeroExit) {
  const std::string l = kSample + "/image_l/000000.png", rgt = kSample + "/image_r/000000.png",
                    c = kSample + "/calib.txt";
  // missing file
  Outcome r = run("--left " + path("nonexistent.png") + " --right " + rgt + " --calib " + c + " --out " + path("bad"));
  EXPECT_NE(r.status, 0);
  EXPECT_EQ(lineCount(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("cannot read image"), std::string::npos) << r.err;
  // unreadable image (a text file)
  r = run("--left " + c + " --right " + rgt + " --calib " + c + " --out " + path("bad"));
  EXPECT_NE(r.status, 0);
  EXPECT_EQ(lineCount(r.err), 1) << r.err;
  // size mismatch
  const std::string small = path("small.png");
  cv::imwrite(small, cv::Mat(100, 200, CV_8U, cv::Scalar(90)));
  r = run("--left " + l + " --right " + small + " --calib " + c + " --out " + path("bad"));
  EXPECT_NE(r.status, 0);
  EXPECT_EQ(lineCount(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("differ in size"), std::string::npos) << r.err;
  // bad calibration
  const std::string bad_calib = path("bad_calib.txt");
  std::ofstream(bad_calib) << "P0: 700 0 600 0 0 700 180 0 0 0 1 0\nP1: 700 0 600 380 0 700 180 0 0 0 1 0\n";
  r = run("--left " + l + " --right " + rgt + " --calib " + bad_calib + " --out " + path("bad"));
  EXPECT_NE(r.status, 0);
  EXPECT_EQ(lineCount(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("baseline"), std::string::npos) << r.err;
  // bad arguments and a bad parameter file
  r = run("--sequence " + path("nonexistent") + " --out " + path("bad"));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("is not a directory"), std::string::npos) << r.err;
  const std::string bad_cfg = path("bad_cfg.yaml");
  std::ofstream(bad_cfg) << "smoothnes_weight: 3\n";
  r = run("--sequence " + kSample + " --out " + path("bad") + " --config " + bad_cfg);
  EXPECT_NE(r.status, 0);
  EXPECT_EQ(lineCount(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("unknown parameter 'smoothnes_weight'"), std::string::npos) << r.err;
  r = run("--frames 3");
  EXPECT_EQ(r.status, 2);
}

// docs/parameters.md says its table is generated from the code: it is `--list-parameters`,
// line for line (regenerate it with the command below when a parameter or its meaning changes).
TEST_F(DemOffline, ParameterDocIsTheListing) {
  const Outcome r = run("--list-parameters");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto tableLines = [](std::istream& in) {
    std::vector<std::string> rows;
    for (std::string line; std::getline(in, line);)
      if (line.rfind("| ", 0) == 0 || line.rfind("|---", 0) == 0) rows.push_back(line);
    return rows;
  };
  std::istringstream listed(r.out);
  std::ifstream doc(std::string(SGD_SOURCE_DIR) + "/docs/parameters.md");
  ASSERT_TRUE(doc.good());
  const std::vector<std::string> want = tableLines(listed), have = tableLines(doc);
  ASSERT_GT(want.size(), 100u);  // the header, its rule and every parameter
  for (size_t i = 0; i < std::max(want.size(), have.size()); ++i) {
    ASSERT_EQ(i < have.size() ? have[i] : "(missing)", i < want.size() ? want[i] : "(extra)")
        << "docs/parameters.md line " << i + 1 << " of its table differs from `dem_offline --list-parameters`; "
        << "regenerate the table: dem_offline --list-parameters";
  }
}
