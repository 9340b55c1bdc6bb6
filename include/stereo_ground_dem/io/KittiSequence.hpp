#pragma once
/// \file KittiSequence.hpp
/// A KITTI-style sequence folder:
///  - calibration: `calib.txt` (KITTI odometry: `P0:`..`P3:`, or two unkeyed lines of 12 numbers),
///    else `calib_cam_to_cam.txt` (KITTI raw / KITTI 2015: `P_rect_00`..`P_rect_03`);
///  - images, by camera pair: grey 0/1 in `image_0/`+`image_1/` (or KITTI raw's
///    `image_00/data/`+`image_01/data/`), colour 2/3 in `image_2/`+`image_3/` (or
///    `image_02/data/`+`image_03/data/`), or an unnamed pair in `image_l/`+`image_r/`; frames are
///    the left folder's images sorted by name, matched by name in the right folder;
///  - optional `times.txt` (seconds, one per line and frame) and `poses.txt` (ground truth).
///
/// Camera pair: CameraPair::kAuto takes the grey pair when its folders and calibration exist, the
/// colour pair otherwise, then image_l/image_r; kGray / kColor insist on that pair. An unkeyed
/// calib.txt goes with any folder pair.
///
/// Problems that do not stop a run are collected as one-line warnings(): right images missing for
/// some frames (those frames cannot be read), times.txt stamps that are not finite, do not
/// increase or jump, the calibration's rectification offset. Problems that do throw
/// std::runtime_error naming the folder and the reason.

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/CalibrationReader.hpp"
#include "stereo_ground_dem/StereoRig.hpp"

namespace stereo_ground_dem {

struct KittiSequenceOptions {
  CalibrationReader::CameraPair cameras = CalibrationReader::CameraPair::kAuto;
  bool read_ground_truth = true;  ///< read poses.txt (a malformed one throws)
  /// A step of times.txt larger than this times the median step is reported as a jump [-].
  double time_jump_factor = 5.0;
};

class KittiSequence {
 public:
  /// Opens `dir`; throws std::runtime_error naming what is missing. The rig's image size is
  /// taken from the first readable left image, whose size must hold the principal point.
  static KittiSequence open(const std::string& dir, const KittiSequenceOptions& options = KittiSequenceOptions());

  const std::string& directory() const { return dir_; }
  const StereoRig& rig() const { return rig_; }
  int size() const { return static_cast<int>(left_.size()); }
  /// times.txt when present (may be non-finite: see warnings()), else index * 0.1 s.
  double stamp(int i) const;
  bool hasTimes() const { return !times_.empty(); }
  /// Reads frame i unchanged (8/16-bit, grey or colour); throws std::runtime_error if unreadable.
  void read(int i, cv::Mat* left, cv::Mat* right) const;
  /// Reads frame i unchanged; false and a one-line reason when a file is missing or unreadable.
  bool tryRead(int i, cv::Mat* left, cv::Mat* right, std::string* why) const;
  const std::string& leftPath(int i) const { return left_.at(static_cast<size_t>(i)); }
  const std::string& rightPath(int i) const { return right_.at(static_cast<size_t>(i)); }
  /// poses.txt (camera0_T_cameraK), empty when absent or not read.
  const std::vector<Eigen::Isometry3d>& groundTruth() const { return poses_; }
  /// The calibration file read and the camera pair chosen (kAuto for image_l/image_r).
  const std::string& calibrationPath() const { return calib_path_; }
  CalibrationReader::CameraPair cameras() const { return cameras_; }
  const std::string& leftFolder() const { return left_dir_; }
  /// Problems that do not stop a run, one line each.
  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  std::string dir_, calib_path_, left_dir_, right_dir_;
  CalibrationReader::CameraPair cameras_ = CalibrationReader::CameraPair::kAuto;
  StereoRig rig_;
  std::vector<std::string> left_, right_;
  std::vector<double> times_;
  std::vector<Eigen::Isometry3d> poses_;
  std::vector<std::string> warnings_;
};

}  // namespace stereo_ground_dem
