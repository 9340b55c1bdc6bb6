#include "stereo_ground_dem/TemporalVisibility.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace stereo_ground_dem {

bool TemporalVisibilityOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(inverse_depth_tolerance > 0.0 && inverse_depth_tolerance < 1.0)) return bad("inverse_depth_tolerance must be in (0, 1)");
  if (dilation_px < 0) return bad("dilation_px must be >= 0");
  if (!(min_repeat_share >= 0.0 && min_repeat_share <= 1.0)) return bad("min_repeat_share must be in [0, 1]");
  return true;
}

TemporalVisibility::TemporalVisibility(const TemporalVisibilityOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("TemporalVisibilityOptions: " + why);
}

cv::Mat TemporalVisibility::hidden(const cv::Mat& reference_rho, const cv::Mat& target_rho, const StereoRig& rig,
                                   const Eigen::Isometry3d& target_T_reference) const {
  if (reference_rho.type() != CV_32F || target_rho.type() != CV_32F || reference_rho.size() != target_rho.size()) {
    throw std::invalid_argument("TemporalVisibility: inverse depths must be CV_32F of one size");
  }
  const int w = reference_rho.cols, h = reference_rho.rows;
  cv::Mat mask = cv::Mat::zeros(h, w, CV_8U);
  const Eigen::Matrix3d R = target_T_reference.linear();
  const Eigen::Vector3d t = target_T_reference.translation();
  const double keep = 1.0 + options_.inverse_depth_tolerance;
  for (int v = 0; v < h; ++v) {
    const float* rho = reference_rho.ptr<float>(v);
    uint8_t* m = mask.ptr<uint8_t>(v);
    const double ray_y = (v - rig.cy) / rig.fy;
    for (int u = 0; u < w; ++u) {
      if (!(rho[u] > 0.0f)) continue;
      // the point X = ray / rho; in the target, Y = R X + t, so rho * Y = R ray + rho t
      const Eigen::Vector3d ray((u - rig.cx) / rig.fx, ray_y, 1.0);
      const Eigen::Vector3d y = R * ray + static_cast<double>(rho[u]) * t;  // Y scaled by rho
      if (!(y.z() > 0.0)) continue;
      const double ut = rig.fx * y.x() / y.z() + rig.cx, vt = rig.fy * y.y() / y.z() + rig.cy;
      const int ui = static_cast<int>(std::lround(ut)), vi = static_cast<int>(std::lround(vt));
      if (ui < 0 || vi < 0 || ui >= w || vi >= h) continue;
      const float seen = target_rho.at<float>(vi, ui);  // the target's nearest surface there
      if (!(seen > 0.0f)) continue;
      const double point_rho = rho[u] / y.z();  // 1 / Y.z
      if (seen > keep * point_rho) m[u] = 255;
    }
  }
  if (options_.dilation_px > 0 && cv::countNonZero(mask) > 0) {
    const int k = 2 * options_.dilation_px + 1;
    cv::dilate(mask, mask, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k)));
    // only where there is a surface
    mask.setTo(0, reference_rho <= 0.0f);
  }
  return mask;
}

}  // namespace stereo_ground_dem
