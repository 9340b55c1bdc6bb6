#pragma once
/// \file StereoRig.hpp
/// A rectified stereo pair: one pinhole intrinsic matrix shared by both cameras and a baseline.
///
/// Conventions (used everywhere in this library):
///  - camera (optical) frame: x right, y down, z forward [m];
///  - pixel coordinates (u, v): u to the right, v down, pixel centres at integer coordinates;
///  - the right camera sits at +baseline_m along the left camera's x axis, so a point X in the
///    left camera frame is X - (baseline_m, 0, 0) in the right camera frame and its disparity is
///    d = fx * baseline_m / Z [px].

#include <Eigen/Core>
#include <string>

namespace stereo_ground_dem {

struct StereoRig {
  double fx = 0.0;          ///< focal length along u [px]
  double fy = 0.0;          ///< focal length along v [px]
  double cx = 0.0;          ///< principal point u [px]
  double cy = 0.0;          ///< principal point v [px]
  double baseline_m = 0.0;  ///< distance between the optical centres [m], > 0
  int width = 0;            ///< image width [px]; 0 while unknown (set from the images)
  int height = 0;           ///< image height [px]; 0 while unknown

  /// Builds a rig from the 3x4 rectified projection matrices of the left and right cameras
  /// (KITTI `P0`/`P1`, ROS `CameraInfo.P`). The right matrix must be `[K | K * (-baseline, 0, 0)^T]`
  /// up to the usual `P(0,3) = -fx * baseline`. Throws std::invalid_argument naming the problem
  /// (different intrinsics, zero or negative baseline, a non-rectified matrix).
  static StereoRig fromProjectionMatrices(const Eigen::Matrix<double, 3, 4>& p_left,
                                          const Eigen::Matrix<double, 3, 4>& p_right,
                                          int width = 0, int height = 0);

  /// The intrinsics at pyramid level `level` (image downsampled by 2^level with cv::pyrDown,
  /// whose output pixel i is centred on input pixel 2i).
  StereoRig atLevel(int level) const;

  Eigen::Matrix3d K() const;

  /// fx * baseline [px m]: disparity = this / depth.
  double disparityTimesDepth() const { return fx * baseline_m; }

  bool isValid(std::string* why = nullptr) const;
};

}  // namespace stereo_ground_dem
