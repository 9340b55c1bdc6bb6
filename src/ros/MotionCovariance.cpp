#include "stereo_ground_dem/ros/MotionCovariance.hpp"

#include <Eigen/Eigenvalues>

namespace stereo_ground_dem {

Matrix6d MotionCovariance::fromInformation(const Matrix6d& information, const Matrix6d& fallback, bool* used_fallback,
                                           double min_eigenvalue) {
  const Matrix6d sym = 0.5 * (information + information.transpose());
  bool ok = sym.allFinite();
  Matrix6d cov = fallback;
  if (ok) {
    const Eigen::SelfAdjointEigenSolver<Matrix6d> es(sym);
    ok = es.info() == Eigen::Success && es.eigenvalues().minCoeff() > min_eigenvalue;
    if (ok) {
      const Vector6d inv = es.eigenvalues().cwiseInverse();
      cov = es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose();
      cov = 0.5 * (cov + cov.transpose());
    }
  }
  if (used_fallback) *used_fallback = !ok;
  return ok ? cov : fallback;
}

Matrix6d MotionCovariance::diagonal(double std_m, double std_rad) {
  Vector6d d;
  d << std_m * std_m, std_m * std_m, std_m * std_m, std_rad * std_rad, std_rad * std_rad, std_rad * std_rad;
  return d.asDiagonal();
}

Matrix6d MotionCovariance::adjoint(const Eigen::Isometry3d& t) {
  const Eigen::Matrix3d r = t.linear();
  Matrix6d ad = Matrix6d::Zero();
  ad.topLeftCorner<3, 3>() = r;
  ad.topRightCorner<3, 3>() = Se3::skew(t.translation()) * r;
  ad.bottomRightCorner<3, 3>() = r;
  return ad;
}

Matrix6d MotionCovariance::changeFrame(const Matrix6d& cov_c, const Eigen::Isometry3d& b_T_c) {
  const Matrix6d ad = adjoint(b_T_c);
  return ad * cov_c * ad.transpose();
}

Matrix6d MotionCovariance::rotate(const Matrix6d& cov, const Eigen::Matrix3d& r) {
  Matrix6d b = Matrix6d::Zero();
  b.topLeftCorner<3, 3>() = r;
  b.bottomRightCorner<3, 3>() = r;
  return b * cov * b.transpose();
}

boost::array<double, 36> MotionCovariance::toArray(const Matrix6d& cov) {
  boost::array<double, 36> a{};
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) a[static_cast<size_t>(r * 6 + c)] = cov(r, c);
  return a;
}

void MotionCovariance::accumulate(const Eigen::Isometry3d& delta, const Matrix6d& increment_cov) {
  const Matrix6d ad = adjoint(delta.inverse());
  pose_cov_ = ad * pose_cov_ * ad.transpose() + increment_cov;
  pose_cov_ = 0.5 * (pose_cov_ + pose_cov_.transpose());
}

}  // namespace stereo_ground_dem
