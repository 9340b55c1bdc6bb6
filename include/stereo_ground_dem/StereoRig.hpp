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
///  - real calibrations are rectified only up to a few millimetres: KITTI's colour cameras
///    (P_rect_02/03, odometry P2/P3) sit ~3 mm apart vertically. The full position of the right
///    optical centre in the left camera frame is kept (rightCentreInLeft()); offsets along y and z
///    up to kMaxRelativeOffset of the baseline are accepted (rectificationWarning() names them, to
///    be printed once) and the estimator uses baseline_m only.

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
  double right_offset_y_m = 0.0;  ///< right optical centre along the left camera's y [m] (0 if rectified)
  double right_offset_z_m = 0.0;  ///< ... along its z (optical axis) [m] (0 if rectified)

  /// Largest accepted |right_offset_y_m| and |right_offset_z_m| as a fraction of the baseline
  /// (1 %: KITTI's colour pair has 0.52 % in y).
  static constexpr double kMaxRelativeOffset = 0.01;

  /// Builds a rig from the 3x4 rectified projection matrices of the left and right cameras
  /// (KITTI `P0`/`P1`, `P2`/`P3`, `P_rect_0X`, ROS `CameraInfo.P`): both `K [I | t]` with one K.
  /// The left matrix may carry its own offset (KITTI's colour cameras are not the rectified
  /// reference camera): the right optical centre in the left frame is
  /// K^-1 (p_left.col(3) - p_right.col(3)) = (baseline_m, right_offset_y_m, right_offset_z_m).
  /// Throws std::invalid_argument naming the problem and the numbers (different intrinsics, zero or
  /// negative baseline, a non-rectified matrix, |y| or |z| above max_relative_offset * baseline).
  static StereoRig fromProjectionMatrices(const Eigen::Matrix<double, 3, 4>& p_left,
                                          const Eigen::Matrix<double, 3, 4>& p_right,
                                          int width = 0, int height = 0,
                                          double max_relative_offset = kMaxRelativeOffset);

  /// (baseline_m, right_offset_y_m, right_offset_z_m): the right optical centre in the left
  /// camera frame [m].
  Eigen::Vector3d rightCentreInLeft() const { return {baseline_m, right_offset_y_m, right_offset_z_m}; }

  /// "" when the right camera is exactly beside the left one (|y|, |z| <= 1e-6 baseline), else one
  /// line naming the offsets that were accepted and are ignored by the estimator.
  std::string rectificationWarning() const;

  /// This rig for images of width x height: sets the size when unknown (0), else it must match.
  /// Throws std::invalid_argument naming the numbers when the sizes differ, a size is not
  /// positive, or the principal point lies outside the image ([-0.5, size - 0.5]).
  StereoRig withImageSize(int image_width, int image_height) const;

  /// The intrinsics at pyramid level `level` (image downsampled by 2^level with cv::pyrDown,
  /// whose output pixel i is centred on input pixel 2i).
  StereoRig atLevel(int level) const;

  Eigen::Matrix3d K() const;

  /// fx * baseline [px m]: disparity = this / depth.
  double disparityTimesDepth() const { return fx * baseline_m; }

  bool isValid(std::string* why = nullptr) const;
};

}  // namespace stereo_ground_dem
