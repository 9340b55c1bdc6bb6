#pragma once
/// \file MotionCovariance.hpp
/// nav_msgs/Odometry covariances from FrameResult::motion_information.
///
/// What the core gives: the 6x6 information [1/m^2, 1/rad^2] of the current camera pose given the
/// previous frames (heights marginalized), for a twist xi = (v, w) in the camera frame (Se3.hpp
/// order: translation first), the aligner updating camera_T_ground <- exp(xi) camera_T_ground.
/// Equivalently ground_T_camera = estimate * exp(-xi): a right perturbation of the pose, so its
/// inverse is the covariance of this frame's motion increment, expressed in the camera frame.
///
/// What the node publishes (documented in docs/ros.md):
///  1. increment covariance in the camera frame: inverse of the information (symmetrized); when the
///     information is not positive definite (a frame without motion estimate: the first frame, a
///     failed or re-initialized one) a fallback diagonal covariance is used instead;
///  2. moved to the child frame B (base_link) rigidly attached with B_T_C: Ad(B_T_C) S Ad(B_T_C)^T
///     with Ad = [R, [t]x R; 0, R] for (v, w) twists;
///  3. twist.covariance = increment covariance / dt^2 (the twist is the mean velocity over the
///     frame interval, in the child frame, as REP 105 / nav_msgs ask);
///  4. pose.covariance accumulates the increments along the trajectory (first order, the covariance
///     of a right perturbation of odom_T_base): S_k = Ad(D^-1) S_(k-1) Ad(D^-1)^T + S_inc, with
///     D = odom_T_base(k-1)^-1 odom_T_base(k); it is published rotated into the odom frame's axes
///     (blockdiag(R, R) S blockdiag(R, R)^T), i.e. x, y, z, rotation about x, y, z of odom at the
///     child's origin. It starts at zero: the first frame defines odom.
/// Row-major 6x6 arrays, order (x, y, z, rot x, rot y, rot z) as in geometry_msgs.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <boost/array.hpp>

#include "stereo_ground_dem/Se3.hpp"

namespace stereo_ground_dem {

class MotionCovariance {
 public:
  /// Inverse of `information` if it is positive definite (smallest eigenvalue above
  /// min_eigenvalue), else `fallback`. `used_fallback` (optional) tells which.
  static Matrix6d fromInformation(const Matrix6d& information, const Matrix6d& fallback,
                                  bool* used_fallback = nullptr, double min_eigenvalue = 1e-9);
  /// diag(std_m^2 x3, std_rad^2 x3).
  static Matrix6d diagonal(double std_m, double std_rad);
  /// The adjoint of T for (v, w) twists: Ad(T) xi is xi seen from the frame T maps into.
  static Matrix6d adjoint(const Eigen::Isometry3d& t);
  /// A twist covariance in frame C expressed in a frame B rigidly attached: b_T_c = pose of C in B.
  static Matrix6d changeFrame(const Matrix6d& cov_c, const Eigen::Isometry3d& b_T_c);
  /// blockdiag(R, R) S blockdiag(R, R)^T.
  static Matrix6d rotate(const Matrix6d& cov, const Eigen::Matrix3d& r);
  static boost::array<double, 36> toArray(const Matrix6d& cov);

  /// Accumulation along the trajectory (step 4 above).
  void reset() { pose_cov_.setZero(); }
  void accumulate(const Eigen::Isometry3d& delta, const Matrix6d& increment_cov);
  /// Accumulated covariance of the right perturbation of the child pose [child frame].
  const Matrix6d& poseCovarianceInChild() const { return pose_cov_; }

 private:
  Matrix6d pose_cov_ = Matrix6d::Zero();
};

}  // namespace stereo_ground_dem
