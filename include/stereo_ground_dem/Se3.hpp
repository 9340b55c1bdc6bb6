#pragma once
/// \file Se3.hpp
/// The few SE(3) operations the estimators need (Sophus is not packaged in Debian).
/// A twist is xi = (v, omega): translation part first, then rotation, and
/// exp(xi) * X ~= X + v + omega x X for small xi.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace stereo_ground_dem {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

class Se3 {
 public:
  /// [w]_x, the cross-product matrix: skew(w) * x = w.cross(x).
  static Eigen::Matrix3d skew(const Eigen::Vector3d& w);
  /// Rodrigues: the rotation by angle |w| about w / |w|.
  static Eigen::Matrix3d expSo3(const Eigen::Vector3d& w);
  static Eigen::Vector3d logSo3(const Eigen::Matrix3d& r);
  /// The group exponential of a twist (v, omega).
  static Eigen::Isometry3d exp(const Vector6d& xi);
  /// Inverse of exp for rotation angles below pi.
  static Vector6d log(const Eigen::Isometry3d& t);
};

}  // namespace stereo_ground_dem
