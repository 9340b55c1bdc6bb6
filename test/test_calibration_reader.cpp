#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <unistd.h>

#include "stereo_ground_dem/CalibrationReader.hpp"

using stereo_ground_dem::CalibrationReader;
using stereo_ground_dem::StereoRig;

namespace {

class TempFile {
 public:
  explicit TempFile(const std::string& content) {
    std::string name = (std::filesystem::temp_directory_path() / "sgd_calib_XXXXXX").string();
    const int fd = mkstemp(name.data());
    path_ = name;
    ::close(fd);
    std::ofstream(path_) << content;
  }
  ~TempFile() { std::remove(path_.c_str()); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

const char* kKittiOdometry =
    "P0: 7.070912e+02 0.0 6.018873e+02 0.0 0.0 7.070912e+02 1.831104e+02 0.0 0.0 0.0 1.0 0.0\n"
    "P1: 7.070912e+02 0.0 6.018873e+02 -3.798145e+02 0.0 7.070912e+02 1.831104e+02 0.0 0.0 0.0 1.0 "
    "0.0\n"
    "P2: 7.070912e+02 0.0 6.018873e+02 4.688783e+01 0.0 7.070912e+02 1.831104e+02 1.178601e-01 0.0 "
    "0.0 1.0 6.203223e-03\n"
    "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n";

std::string last_path;
const std::string& lastPath() { return last_path; }

std::string expectError(const std::string& content) {
  TempFile f(content);
  last_path = f.path();
  try {
    CalibrationReader::read(f.path());
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error for:\n" << content;
  return {};
}

}  // namespace

TEST(CalibrationReader, KittiOdometryKeyed) {
  TempFile f(kKittiOdometry);
  const StereoRig rig = CalibrationReader::readKittiOdometry(f.path());
  EXPECT_DOUBLE_EQ(rig.fx, 707.0912);
  EXPECT_DOUBLE_EQ(rig.fy, 707.0912);
  EXPECT_DOUBLE_EQ(rig.cx, 601.8873);
  EXPECT_DOUBLE_EQ(rig.cy, 183.1104);
  EXPECT_NEAR(rig.baseline_m, 379.8145 / 707.0912, 1e-12);  // 0.537 m
}

TEST(CalibrationReader, KittiOdometryPlainLinesAsInSharedData) {
  TempFile f(
      "7.070912000000e+02 0.000000000000e+00 6.018873000000e+02 0.000000000000e+00 "
      "0.000000000000e+00 7.070912000000e+02 1.831104000000e+02 0.000000000000e+00 "
      "0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00\n"
      "7.070912000000e+02 0.000000000000e+00 6.018873000000e+02 -3.798145000000e+02 "
      "0.000000000000e+00 7.070912000000e+02 1.831104000000e+02 0.000000000000e+00 "
      "0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00");
  const StereoRig rig = CalibrationReader::read(f.path());
  EXPECT_NEAR(rig.baseline_m, 0.53716, 1e-5);
  EXPECT_DOUBLE_EQ(rig.cx, 601.8873);
}

const char* kRawCamToCam =  // KITTI raw 2011_09_26 calib_cam_to_cam.txt (the four rectified cameras)
    "calib_time: 09-Jan-2012 13:57:47\n"
    "corner_dist: 9.950000e-02\n"
    "S_rect_00: 1.242000e+03 3.750000e+02\n"
    "P_rect_00: 7.215377e+02 0.000000e+00 6.095593e+02 0.000000e+00 0.000000e+00 7.215377e+02 "
    "1.728540e+02 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00\n"
    "S_rect_01: 1.242000e+03 3.750000e+02\n"
    "P_rect_01: 7.215377e+02 0.000000e+00 6.095593e+02 -3.875744e+02 0.000000e+00 7.215377e+02 "
    "1.728540e+02 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00\n"
    "S_rect_02: 1.242000e+03 3.750000e+02\n"
    "P_rect_02: 7.215377e+02 0.000000e+00 6.095593e+02 4.485728e+01 0.000000e+00 7.215377e+02 "
    "1.728540e+02 2.163791e-01 0.000000e+00 0.000000e+00 1.000000e+00 2.745884e-03\n"
    "S_rect_03: 1.242000e+03 3.750000e+02\n"
    "P_rect_03: 7.215377e+02 0.000000e+00 6.095593e+02 -3.395242e+02 0.000000e+00 7.215377e+02 "
    "1.728540e+02 2.199936e+00 0.000000e+00 0.000000e+00 1.000000e+00 2.729905e-03\n";

TEST(CalibrationReader, KittiRawColourPairWithOwnOffsets) {
  // P_rect_02 and P_rect_03 both carry offsets relative to camera 0; the right camera's centre in
  // the left frame is K^-1 (p_left.col(3) - p_right.col(3)): 0.5327 m across, 2.75 mm vertically
  // (0.52 % of the baseline, under the 1 % tolerance: accepted with a warning) and 16 um along z.
  TempFile f(kRawCamToCam);
  const StereoRig rig = CalibrationReader::readKittiRaw(f.path(), CalibrationReader::CameraPair::kColor);
  EXPECT_NEAR(rig.baseline_m, 0.532711929, 1e-9);
  EXPECT_NEAR(rig.right_offset_y_m, -2.75289695e-3, 1e-11);
  EXPECT_NEAR(rig.right_offset_z_m, 1.5979e-5, 1e-12);
  EXPECT_NEAR(rig.rightCentreInLeft().x(), rig.baseline_m, 0.0);
  EXPECT_EQ(rig.width, 1242);
  EXPECT_EQ(rig.height, 375);
  EXPECT_EQ(rig.rectificationWarning(),
            "stereo calibration: the right camera is displaced by y -0.0027529 m and z 1.5979e-05 m (0.51677 % of the "
            "0.532712 m baseline, under the 1 % tolerance); ignored, the estimator uses the baseline only");
  // the same pair through read(): kColor explicitly, kAuto takes the grey pair when present
  EXPECT_DOUBLE_EQ(CalibrationReader::read(f.path(), CalibrationReader::CameraPair::kColor).baseline_m, rig.baseline_m);
  const StereoRig gray = CalibrationReader::read(f.path());
  EXPECT_NEAR(gray.baseline_m, 387.5744 / 721.5377, 1e-12);
  EXPECT_EQ(gray.rectificationWarning(), "");
  const CalibrationReader::Contents c = CalibrationReader::inspect(f.path());
  EXPECT_TRUE(c.gray);
  EXPECT_TRUE(c.color);
  EXPECT_FALSE(c.unkeyed);
}

TEST(CalibrationReader, KittiOdometryColourPairP2P3) {
  // KITTI-odometry-style P2/P3 (intrinsics of sequences 04-12): both offsets under 1 %.
  TempFile f(
      "P2: 7.070912e+02 0.0 6.018873e+02 4.688783e+01 0.0 7.070912e+02 1.831104e+02 1.178601e-01 0.0 0.0 1.0 "
      "6.203223e-03\n"
      "P3: 7.070912e+02 0.0 6.018873e+02 -3.334597e+02 0.0 7.070912e+02 1.831104e+02 1.930130e+00 0.0 0.0 1.0 "
      "3.318498e-03\n");
  const StereoRig rig = CalibrationReader::read(f.path());
  EXPECT_NEAR(rig.baseline_m, 0.53544896, 1e-8);
  EXPECT_NEAR(rig.right_offset_y_m, -0.00331003, 1e-8);
  EXPECT_NEAR(rig.right_offset_z_m, 0.00288472, 1e-8);
  EXPECT_EQ(rig.width, 0);  // calib.txt has no image size: set from the first image
  EXPECT_THROW(CalibrationReader::read(f.path(), CalibrationReader::CameraPair::kGray), std::runtime_error);
  // the odometry file with all four cameras: kAuto takes P0/P1, kColor P2/P3
  TempFile all(std::string(kKittiOdometry) +
               "P3: 7.070912e+02 0.0 6.018873e+02 -3.334597e+02 0.0 7.070912e+02 1.831104e+02 1.930130e+00 0.0 0.0 "
               "1.0 3.318498e-03\n");
  EXPECT_NEAR(CalibrationReader::read(all.path()).baseline_m, 379.8145 / 707.0912, 1e-12);
  EXPECT_NEAR(CalibrationReader::read(all.path(), CalibrationReader::CameraPair::kColor).baseline_m, 0.53544896, 1e-8);
}

TEST(CalibrationReader, OffsetBeyondTheToleranceIsAnErrorNamingTheNumbers) {
  // 1.5 % of a 0.5 m baseline vertically: refused, with the numbers
  const std::string vertical = expectError("P0: 700 0 600 0 0 700 180 0 0 0 1 0\n"
                                           "P1: 700 0 600 -350 0 700 180 -5.25 0 0 1 0\n");
  EXPECT_EQ(vertical,
            "calibration file '" + lastPath() +
                "': inconsistent stereo calibration: the right camera is displaced by y 0.0075 m and z 0 m (1.5 % of "
                "the 0.5 m baseline, more than the 1 % tolerance); not a rectified pair");
  // along the optical axis
  const std::string along_z = expectError("P0: 700 0 600 0 0 700 180 0 0 0 1 0\n"
                                          "P1: 700 0 600 -350 0 700 180 0 0 0 1 0.01\n");
  EXPECT_NE(along_z.find("and z -0.01 m (1.96629 % of the 0.508571 m baseline, more than the 1 % tolerance)"),
            std::string::npos)
      << along_z;
  // under the tolerance: accepted, offsets kept
  TempFile ok("P0: 700 0 600 0 0 700 180 0 0 0 1 0\nP1: 700 0 600 -350 0 700 180 -2.8 0 0 1 0\n");
  const StereoRig rig = CalibrationReader::read(ok.path());
  EXPECT_DOUBLE_EQ(rig.baseline_m, 0.5);
  EXPECT_DOUBLE_EQ(rig.right_offset_y_m, 0.004);
  // a tighter tolerance through StereoRig directly
  Eigen::Matrix<double, 3, 4> pl, pr;
  pl << 700, 0, 600, 0, 0, 700, 180, 0, 0, 0, 1, 0;
  pr << 700, 0, 600, -350, 0, 700, 180, -2.8, 0, 0, 1, 0;
  EXPECT_THROW(StereoRig::fromProjectionMatrices(pl, pr, 0, 0, 0.005), std::invalid_argument);
  EXPECT_NO_THROW(StereoRig::fromProjectionMatrices(pl, pr, 0, 0, 0.01));
}

TEST(StereoRig, ImageSizeAndPrincipalPoint) {
  StereoRig rig;
  rig.fx = rig.fy = 700;
  rig.cx = 600;
  rig.cy = 180;
  rig.baseline_m = 0.5;
  const StereoRig sized = rig.withImageSize(1226, 370);
  EXPECT_EQ(sized.width, 1226);
  EXPECT_EQ(sized.height, 370);
  EXPECT_NO_THROW(sized.withImageSize(1226, 370));
  const auto message = [](const StereoRig& r, int w, int h) -> std::string {
    try {
      r.withImageSize(w, h);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "<accepted>";
  };
  EXPECT_EQ(message(sized, 1242, 375), "image size 1242x375 differs from the calibration's 1226x370");
  EXPECT_EQ(message(rig, 500, 370),
            "principal point (cx 600, cy 180) lies outside the 500x370 image; calibration and images do not belong "
            "together");
  EXPECT_EQ(message(rig, 1226, 100),
            "principal point (cx 600, cy 180) lies outside the 1226x100 image; calibration and images do not belong "
            "together");
  EXPECT_EQ(message(rig, 0, 370), "image size 0x370 is not positive");
}

TEST(CalibrationReader, KittiRawGrayPairAndImageSize) {
  TempFile f(
      "S_rect_00: 1.242000e+03 3.750000e+02\n"
      "P_rect_00: 7.215377e+02 0.000000e+00 6.095593e+02 0.000000e+00 0.000000e+00 7.215377e+02 "
      "1.728540e+02 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00\n"
      "P_rect_01: 7.215377e+02 0.000000e+00 6.095593e+02 -3.875744e+02 0.000000e+00 7.215377e+02 "
      "1.728540e+02 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00\n");
  const StereoRig rig = CalibrationReader::readKittiRaw(f.path(), CalibrationReader::CameraPair::kGray);
  EXPECT_EQ(rig.width, 1242);
  EXPECT_EQ(rig.height, 375);
  EXPECT_NEAR(rig.baseline_m, 387.5744 / 721.5377, 1e-12);
}

TEST(CalibrationReader, RejectsMalformedFiles) {
  EXPECT_NE(expectError("P0: 1 2 3\nP1: 1 2 3\n").find("expected 12"), std::string::npos);
  EXPECT_NE(expectError("hello world\n").find("not a list of numbers"), std::string::npos);
  EXPECT_NE(expectError("").find("no P0"), std::string::npos);
  // a key we use must hold numbers, once; a pair needs both matrices
  EXPECT_NE(expectError("P0: 700 0 600 0 0 700 x 0 0 0 1 0\nP1: 700 0 600 -380 0 700 180 0 0 0 1 0\n")
                .find("P0 on line 1 holds 'x', not a number"),
            std::string::npos);
  EXPECT_NE(expectError("P0: 700 0 600 0 0 700 180 0 0 0 1 0\nP1: 700 0 600 -380 0 700 180 0 0 0 1 0\n"
                        "P0: 700 0 600 0 0 700 180 0 0 0 1 0\n")
                .find("P0 appears twice (lines 1 and 3)"),
            std::string::npos);
  EXPECT_NE(expectError("P0: 700 0 600 0 0 700 180 0 0 0 1 0\nP2: 700 0 600 -380 0 700 180 0 0 0 1 0\n")
                .find("has P0 but no P1"),
            std::string::npos);
  EXPECT_NE(expectError(std::string(kRawCamToCam).replace(std::string(kRawCamToCam).find("1.242000e+03 3.750000e+02"),
                                                            25, "1e300 3.750000e+02"))
                .find("S_rect_00 must hold two whole numbers 1..100000 (width height)"),
            std::string::npos);
  EXPECT_NE(expectError("P0: 700 0 600 0 0 700 180 0 0 0 1 0\nP1: 700 0 600 -380 0 700 180 0 0 0 1 inf\n")
                .find("P1 contains a non-finite number"),
            std::string::npos);
  // different focal lengths
  EXPECT_NE(expectError("P0: 700 0 600 0 0 700 180 0 0 0 1 0\n"
                        "P1: 710 0 600 -380 0 710 180 0 0 0 1 0\n")
                .find("fx differ"),
            std::string::npos);
  // different principal points
  EXPECT_NE(expectError("P0: 700 0 600 0 0 700 180 0 0 0 1 0\n"
                        "P1: 700 0 601 -380 0 700 180 0 0 0 1 0\n")
                .find("cx differ"),
            std::string::npos);
  // zero and negative baselines
  EXPECT_NE(expectError("P0: 700 0 600 0 0 700 180 0 0 0 1 0\n"
                        "P1: 700 0 600 0 0 700 180 0 0 0 1 0\n")
                .find("zero or negative"),
            std::string::npos);
  EXPECT_NE(expectError("P0: 700 0 600 0 0 700 180 0 0 0 1 0\n"
                        "P1: 700 0 600 380 0 700 180 0 0 0 1 0\n")
                .find("swapped"),
            std::string::npos);
  EXPECT_NE(expectError("P0: 700 0 600 0 0 700 180 0 0 0 1 0\n"
                        "P1: 700 0 600 nan 0 700 180 0 0 0 1 0\n")
                .find("non-finite"),
            std::string::npos);
  EXPECT_NE(expectError("P0: 700 0 600 0 0 700 180 0 0.1 0 1 0\n"
                        "P1: 700 0 600 -380 0 700 180 0 0 0 1 0\n")
                .find("rectified form"),
            std::string::npos);
}

TEST(CalibrationReader, MissingFile) {
  try {
    CalibrationReader::read("/nonexistent/calib.txt");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot be opened"), std::string::npos);
  }
}

TEST(StereoRig, LevelIntrinsics) {
  StereoRig rig;
  rig.fx = 700;
  rig.fy = 710;
  rig.cx = 600;
  rig.cy = 180;
  rig.baseline_m = 0.5;
  rig.width = 1226;
  rig.height = 370;
  const StereoRig l2 = rig.atLevel(2);
  EXPECT_DOUBLE_EQ(l2.fx, 175.0);
  EXPECT_DOUBLE_EQ(l2.cy, 45.0);
  EXPECT_EQ(l2.width, 307);  // 1226 -> 613 -> 307 as cv::pyrDown
  EXPECT_EQ(l2.height, 93);  // 370 -> 185 -> 93
  EXPECT_DOUBLE_EQ(l2.baseline_m, 0.5);
}
