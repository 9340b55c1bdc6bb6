#include "stereo_ground_dem/StereoRig.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace stereo_ground_dem {

namespace {
bool nearlyEqual(double a, double b, double rel_tol) {
  return std::abs(a - b) <= rel_tol * std::max({1.0, std::abs(a), std::abs(b)});
}
}  // namespace

StereoRig StereoRig::fromProjectionMatrices(const Eigen::Matrix<double, 3, 4>& p_left,
                                            const Eigen::Matrix<double, 3, 4>& p_right, int width,
                                            int height) {
  constexpr double kTol = 1e-6;
  auto fail = [](const std::string& what) {
    throw std::invalid_argument("inconsistent stereo calibration: " + what);
  };
  for (const auto* p : {&p_left, &p_right}) {
    if (!p->allFinite()) fail("projection matrix contains NaN or Inf");
    if (std::abs(p->coeff(1, 0)) > kTol || std::abs(p->coeff(2, 0)) > kTol ||
        std::abs(p->coeff(2, 1)) > kTol || !nearlyEqual(p->coeff(2, 2), 1.0, kTol)) {
      fail("projection matrix is not of the rectified form [fx s cx tx; 0 fy cy ty; 0 0 1 tz]");
    }
  }
  const Eigen::Matrix3d kl = p_left.leftCols<3>();
  const Eigen::Matrix3d kr = p_right.leftCols<3>();
  const char* names[] = {"fx", "fy", "cx", "cy"};
  const double lv[] = {kl(0, 0), kl(1, 1), kl(0, 2), kl(1, 2)};
  const double rv[] = {kr(0, 0), kr(1, 1), kr(0, 2), kr(1, 2)};
  for (int i = 0; i < 4; ++i) {
    if (!nearlyEqual(lv[i], rv[i], kTol)) {
      std::ostringstream os;
      os << "left and right " << names[i] << " differ (" << lv[i] << " vs " << rv[i]
         << "); the images must be rectified with one intrinsic matrix";
      fail(os.str());
    }
  }
  if (!(kl(0, 0) > 0.0) || !(kl(1, 1) > 0.0)) fail("focal lengths must be positive");
  if (std::abs(kl(0, 1)) > kTol || std::abs(kr(0, 1)) > kTol) fail("skew must be zero");
  // p_left may carry its own offset (KITTI P2/P3 do): the baseline is the difference.
  const double tx_l = p_left(0, 3) / kl(0, 0);
  const double tx_r = p_right(0, 3) / kr(0, 0);
  const double baseline = tx_l - tx_r;
  if (std::abs(p_right(1, 3) - p_left(1, 3)) > 1e-6 * kl(1, 1) ||
      std::abs(p_right(2, 3) - p_left(2, 3)) > 1e-9) {
    fail("the right camera is displaced vertically or along the optical axis; not a rectified pair");
  }
  if (!(baseline > 0.0)) {
    std::ostringstream os;
    os << "baseline " << baseline
       << " m is zero or negative (is the right camera's P(0,3) = -fx * baseline? are left and "
          "right swapped?)";
    fail(os.str());
  }
  StereoRig rig;
  rig.fx = kl(0, 0);
  rig.fy = kl(1, 1);
  rig.cx = kl(0, 2);
  rig.cy = kl(1, 2);
  rig.baseline_m = baseline;
  rig.width = width;
  rig.height = height;
  return rig;
}

StereoRig StereoRig::atLevel(int level) const {
  StereoRig r = *this;
  const double s = std::ldexp(1.0, -level);
  r.fx *= s;
  r.fy *= s;
  r.cx *= s;
  r.cy *= s;
  for (int i = 0; i < level; ++i) {
    r.width = (r.width + 1) / 2;
    r.height = (r.height + 1) / 2;
  }
  return r;
}

Eigen::Matrix3d StereoRig::K() const {
  Eigen::Matrix3d k;
  k << fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0;
  return k;
}

bool StereoRig::isValid(std::string* why) const {
  auto bad = [why](const char* msg) {
    if (why) *why = msg;
    return false;
  };
  if (!(fx > 0.0 && fy > 0.0)) return bad("focal lengths must be positive");
  if (!std::isfinite(cx) || !std::isfinite(cy)) return bad("principal point is not finite");
  if (!(baseline_m > 0.0)) return bad("baseline_m must be positive");
  if (width < 0 || height < 0) return bad("image size must not be negative");
  return true;
}

}  // namespace stereo_ground_dem
