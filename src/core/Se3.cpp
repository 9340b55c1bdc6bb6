#include "stereo_ground_dem/Se3.hpp"

#include <cmath>

namespace stereo_ground_dem {

Eigen::Matrix3d Se3::skew(const Eigen::Vector3d& w) {
  Eigen::Matrix3d s;
  s << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return s;
}

Eigen::Matrix3d Se3::expSo3(const Eigen::Vector3d& w) {
  const double theta = w.norm();
  if (theta < 1e-12) return Eigen::Matrix3d::Identity() + skew(w);
  return Eigen::AngleAxisd(theta, w / theta).toRotationMatrix();
}

Eigen::Vector3d Se3::logSo3(const Eigen::Matrix3d& r) {
  const Eigen::AngleAxisd aa(r);
  return aa.angle() * aa.axis();
}

namespace {
// V(w) = I + (1 - cos t)/t^2 [w] + (t - sin t)/t^3 [w]^2, the left Jacobian of SO(3).
Eigen::Matrix3d leftJacobian(const Eigen::Vector3d& w) {
  const double t = w.norm();
  const Eigen::Matrix3d s = Se3::skew(w);
  if (t < 1e-6) return Eigen::Matrix3d::Identity() + 0.5 * s + s * s / 6.0;
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(t)) / (t * t) * s +
         (t - std::sin(t)) / (t * t * t) * s * s;
}
}  // namespace

Eigen::Isometry3d Se3::exp(const Vector6d& xi) {
  const Eigen::Vector3d v = xi.head<3>();
  const Eigen::Vector3d w = xi.tail<3>();
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = expSo3(w);
  t.translation() = leftJacobian(w) * v;
  return t;
}

Vector6d Se3::log(const Eigen::Isometry3d& t) {
  const Eigen::Vector3d w = logSo3(t.linear());
  Vector6d xi;
  xi.head<3>() = leftJacobian(w).inverse() * t.translation();
  xi.tail<3>() = w;
  return xi;
}

}  // namespace stereo_ground_dem
