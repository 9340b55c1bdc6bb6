#include "stereo_ground_dem/PlaneGeometry.hpp"

#include <Eigen/LU>
#include <cmath>

#include "stereo_ground_dem/Se3.hpp"

namespace stereo_ground_dem {

Eigen::Matrix3d PlaneGeometry::heightsToPlane(const std::array<Eigen::Vector2d, 3>& xy) {
  Eigen::Matrix3d mm;
  for (int i = 0; i < 3; ++i) mm.row(i) << xy[static_cast<size_t>(i)].x(), xy[static_cast<size_t>(i)].y(), 1.0;
  return mm.inverse();
}

bool PlaneGeometry::cameraPlane(const Eigen::Isometry3d& camera_T_ground, const Eigen::Vector3d& pqc,
                                Eigen::Vector3d* m) {
  const Eigen::Matrix3d& r = camera_T_ground.linear();
  const Eigen::Vector3d n = -pqc.x() * r.col(0) - pqc.y() * r.col(1) + r.col(2);
  const double d = pqc.z() + n.dot(camera_T_ground.translation());
  if (std::abs(d) < 1e-12) return false;
  *m = n / d;
  return true;
}

Eigen::Matrix3d PlaneGeometry::cameraPlaneJacobian(const Eigen::Isometry3d& camera_T_ground,
                                                   const Eigen::Vector3d& pqc) {
  const Eigen::Matrix3d& r = camera_T_ground.linear();
  const Eigen::Vector3d& t = camera_T_ground.translation();
  const Eigen::Vector3d n = -pqc.x() * r.col(0) - pqc.y() * r.col(1) + r.col(2);
  const double d = pqc.z() + n.dot(t);
  const Eigen::Vector3d m = n / d;
  Eigen::Matrix3d j;
  j.col(0) = (-r.col(0) + m * r.col(0).dot(t)) / d;
  j.col(1) = (-r.col(1) + m * r.col(1).dot(t)) / d;
  j.col(2) = -m / d;
  return j;
}

PlaneGeometry::Matrix36d PlaneGeometry::cameraPlaneMotionJacobian(const Eigen::Vector3d& m) {
  Matrix36d j;
  j.leftCols<3>() = -m * m.transpose();
  j.rightCols<3>() = -Se3::skew(m);
  return j;
}

Eigen::Matrix3d PlaneGeometry::homography(const Eigen::Matrix3d& k,
                                          const Eigen::Isometry3d& target_T_reference,
                                          const Eigen::Vector3d& m) {
  const Eigen::Matrix3d& rj = target_T_reference.linear();
  const Eigen::Vector3d& tj = target_T_reference.translation();
  return k * (rj + tj * m.transpose()) * k.inverse();
}

namespace {
Eigen::Matrix<double, 2, 3> projectionJacobianAtRay(const Eigen::Matrix3d& k, const Eigen::Vector3d& xhat) {
  Eigen::Matrix<double, 2, 3> d;
  d << k(0, 0), 0.0, -k(0, 0) * xhat.x(), 0.0, k(1, 1), -k(1, 1) * xhat.y();
  return d;
}
}  // namespace

Eigen::Matrix<double, 2, 3> PlaneGeometry::planeIncrementDisplacement(const Eigen::Matrix3d& k,
                                                                      const Eigen::Vector3d& xhat,
                                                                      const Eigen::Vector3d& t_prime) {
  return projectionJacobianAtRay(k, xhat) * t_prime * xhat.transpose();
}

Eigen::Matrix<double, 2, 6> PlaneGeometry::worldMotionDisplacement(const Eigen::Matrix3d& k,
                                                                   const Eigen::Vector3d& xhat,
                                                                   double rho) {
  const Eigen::Matrix<double, 2, 3> d = projectionJacobianAtRay(k, xhat);
  Eigen::Matrix<double, 2, 6> j;
  j.leftCols<3>() = rho * d;
  j.rightCols<3>() = -d * Se3::skew(xhat);
  return j;
}

}  // namespace stereo_ground_dem
