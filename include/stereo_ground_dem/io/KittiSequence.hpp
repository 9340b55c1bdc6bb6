#pragma once
/// \file KittiSequence.hpp
/// A KITTI-odometry-style folder: `calib.txt`; left images in `image_0/`, `image_2/` or
/// `image_l/`; right images in `image_1/`, `image_3/` or `image_r/` (matching file names, sorted);
/// optional `times.txt` (seconds, one per frame) and `poses.txt` (ground truth, KITTI format).

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/StereoRig.hpp"

namespace stereo_ground_dem {

class KittiSequence {
 public:
  /// Opens `dir`; throws std::runtime_error naming what is missing. The rig's image size is
  /// taken from the first left image.
  static KittiSequence open(const std::string& dir);

  const std::string& directory() const { return dir_; }
  const StereoRig& rig() const { return rig_; }
  int size() const { return static_cast<int>(left_.size()); }
  /// times.txt when present, else index * 0.1 s.
  double stamp(int i) const;
  bool hasTimes() const { return !times_.empty(); }
  /// Reads frame i unchanged (8/16-bit, grey or colour); throws std::runtime_error if unreadable.
  void read(int i, cv::Mat* left, cv::Mat* right) const;
  const std::string& leftPath(int i) const { return left_.at(static_cast<size_t>(i)); }
  const std::string& rightPath(int i) const { return right_.at(static_cast<size_t>(i)); }
  /// poses.txt (camera0_T_cameraK), empty when absent.
  const std::vector<Eigen::Isometry3d>& groundTruth() const { return poses_; }

 private:
  std::string dir_;
  StereoRig rig_;
  std::vector<std::string> left_, right_;
  std::vector<double> times_;
  std::vector<Eigen::Isometry3d> poses_;
};

}  // namespace stereo_ground_dem
