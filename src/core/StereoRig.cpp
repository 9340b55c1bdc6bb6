#include "stereo_ground_dem/StereoRig.hpp"

#include <Eigen/Dense>
#include <algorithm>
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
                                            int height, double max_relative_offset) {
  constexpr double kTol = 1e-6;
  auto fail = [](const std::string& what) {
    throw std::invalid_argument("inconsistent stereo calibration: " + what);
  };
  if (!(max_relative_offset >= 0.0)) fail("max_relative_offset must be >= 0");
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
  // P = K [I | t] for both cameras; the right optical centre in the left frame is t_l - t_r.
  const Eigen::Vector3d centre = kl.inverse() * (p_left.col(3) - p_right.col(3));
  if (!centre.allFinite()) fail("the camera offsets are not finite");
  const double baseline = centre.x();
  if (!(baseline > 0.0)) {
    std::ostringstream os;
    os << "baseline " << baseline
       << " m is zero or negative (is the right camera's P(0,3) = -fx * baseline? are left and "
          "right swapped?)";
    fail(os.str());
  }
  const double limit = max_relative_offset * baseline;
  if (std::abs(centre.y()) > limit || std::abs(centre.z()) > limit) {
    std::ostringstream os;
    os << "the right camera is displaced by y " << centre.y() << " m and z " << centre.z() << " m ("
       << 100.0 * std::max(std::abs(centre.y()), std::abs(centre.z())) / baseline << " % of the " << baseline
       << " m baseline, more than the " << 100.0 * max_relative_offset
       << " % tolerance); not a rectified pair";
    fail(os.str());
  }
  StereoRig rig;
  rig.fx = kl(0, 0);
  rig.fy = kl(1, 1);
  rig.cx = kl(0, 2);
  rig.cy = kl(1, 2);
  rig.baseline_m = baseline;
  rig.right_offset_y_m = centre.y();
  rig.right_offset_z_m = centre.z();
  rig.width = width;
  rig.height = height;
  return rig;
}

std::string StereoRig::rectificationWarning() const {
  const double tiny = 1e-6 * std::abs(baseline_m);
  if (std::abs(right_offset_y_m) <= tiny && std::abs(right_offset_z_m) <= tiny) return {};
  std::ostringstream os;
  os << "stereo calibration: the right camera is displaced by y " << right_offset_y_m << " m and z "
     << right_offset_z_m << " m (" << 100.0 * std::max(std::abs(right_offset_y_m), std::abs(right_offset_z_m)) / baseline_m
     << " % of the " << baseline_m << " m baseline, under the " << 100.0 * kMaxRelativeOffset
     << " % tolerance); ignored, the estimator uses the baseline only";
  return os.str();
}

StereoRig StereoRig::withImageSize(int image_width, int image_height) const {
  std::ostringstream os;
  if (image_width <= 0 || image_height <= 0) {
    os << "image size " << image_width << "x" << image_height << " is not positive";
    throw std::invalid_argument(os.str());
  }
  if ((width > 0 || height > 0) && (width != image_width || height != image_height)) {
    os << "image size " << image_width << "x" << image_height << " differs from the calibration's " << width << "x"
       << height;
    throw std::invalid_argument(os.str());
  }
  if (!(cx >= -0.5 && cx <= image_width - 0.5 && cy >= -0.5 && cy <= image_height - 0.5)) {
    os << "principal point (cx " << cx << ", cy " << cy << ") lies outside the " << image_width << "x"
       << image_height << " image; calibration and images do not belong together";
    throw std::invalid_argument(os.str());
  }
  StereoRig r = *this;
  r.width = image_width;
  r.height = image_height;
  return r;
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
  if (!(fx > 0.0 && fy > 0.0) || !std::isfinite(fx) || !std::isfinite(fy)) return bad("focal lengths must be positive");
  if (!std::isfinite(cx) || !std::isfinite(cy)) return bad("principal point is not finite");
  if (!(baseline_m > 0.0) || !std::isfinite(baseline_m)) return bad("baseline_m must be positive and finite");
  if (!std::isfinite(right_offset_y_m) || !std::isfinite(right_offset_z_m)) return bad("right camera offsets must be finite");
  if (width < 0 || height < 0) return bad("image size must not be negative");
  return true;
}

}  // namespace stereo_ground_dem
