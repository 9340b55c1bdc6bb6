#include "stereo_ground_dem/TemporalConsistency.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace stereo_ground_dem {

bool TemporalConsistencyOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (level < 0 || level > 6) return bad("level must be in 0..6");
  if (window_px < 0 || dilation_px < 0) return bad("window_px and dilation_px must be >= 0");
  if (!(ratio >= 1.0) || !(margin_grey >= 0.0) || !(share_of_median >= 1.0)) {
    return bad("need ratio >= 1, margin_grey >= 0, share_of_median >= 1");
  }
  if (!(min_flagged_share >= 0.0 && min_flagged_share < 1.0)) return bad("min_flagged_share must be in [0, 1)");
  return true;
}

TemporalConsistency::TemporalConsistency(const TemporalConsistencyOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("TemporalConsistencyOptions: " + why);
}

namespace {

inline bool sample(const cv::Mat& img, double u, double v, float* out) {
  if (!(u >= 0.0 && v >= 0.0 && u < img.cols - 1 && v < img.rows - 1)) return false;
  const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
  const float fu = static_cast<float>(u - u0), fv = static_cast<float>(v - v0);
  const float* r0 = img.ptr<float>(v0) + u0;
  const float* r1 = img.ptr<float>(v0 + 1) + u0;
  *out = (1.0f - fv) * ((1.0f - fu) * r0[0] + fu * r0[1]) + fv * ((1.0f - fu) * r1[0] + fu * r1[1]);
  return true;
}

double medianOf(std::vector<float> v) {
  if (v.empty()) return 0.0;
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

TemporalInconsistency TemporalConsistency::detect(const ImagePyramid& left, const ImagePyramid& right,
                                                  const ImagePyramid& previous_left, const StereoRig& rig,
                                                  const cv::Mat& inverse_depth, const cv::Mat& excluded,
                                                  const Eigen::Isometry3d& prev_T_current,
                                                  const PhotometricParams& stereo, const PhotometricParams& temporal,
                                                  const VerticalMisalignment& rectification) const {
  TemporalInconsistency out;
  const int l = std::min(options_.level, left.levels() - 1);
  const cv::Mat& il = left.level(l).image;
  const cv::Mat& ir = right.level(l).image;
  const cv::Mat& ip = previous_left.level(l).image;
  if (inverse_depth.size() != il.size()) throw std::invalid_argument("TemporalConsistency: inverse depth size");
  const StereoRig r = rig.atLevel(l);
  const double s = std::ldexp(1.0, -l);
  const double fb = r.fx * r.baseline_m;
  const Eigen::Matrix3d rot = prev_T_current.linear();
  const Eigen::Vector3d tr = prev_T_current.translation();
  cv::Mat es(il.size(), CV_32F, cv::Scalar(0)), et(il.size(), CV_32F, cv::Scalar(0)), valid(il.size(), CV_32F, cv::Scalar(0));
  for (int v = 0; v < il.rows; ++v) {
    const float* rho = inverse_depth.ptr<float>(v);
    const float* i0 = il.ptr<float>(v);
    const uint8_t* ex = excluded.empty() ? nullptr : excluded.ptr<uint8_t>(v);
    float* ps = es.ptr<float>(v);
    float* pt = et.ptr<float>(v);
    float* pv = valid.ptr<float>(v);
    for (int u = 0; u < il.cols; ++u) {
      if (!(rho[u] > 0.0f) || (ex && ex[u])) continue;
      const double d = fb * rho[u];
      const double ur = u - d;
      const double vr = v + s * rectification.rowShift(rig, ur / s, v / s) + rectification.per_disparity * d;
      const Eigen::Vector3d x((u - r.cx) / r.fx / rho[u], (v - r.cy) / r.fy / rho[u], 1.0 / rho[u]);
      const Eigen::Vector3d xp = rot * x + tr;
      if (!(xp.z() > 0.1)) continue;
      const double up = r.fx * xp.x() / xp.z() + r.cx, vp = r.fy * xp.y() / xp.z() + r.cy;
      float a = 0.0f, b = 0.0f;
      if (!sample(ir, ur, vr, &a) || !sample(ip, up, vp, &b)) continue;
      ps[u] = std::abs(i0[u] - static_cast<float>(stereo.gain * a + stereo.bias_grey));
      pt[u] = std::abs(i0[u] - static_cast<float>(temporal.gain * b + temporal.bias_grey));
      pv[u] = 1.0f;
    }
  }
  // local means over the window, counting only measured pixels
  const int w = 2 * options_.window_px + 1;
  cv::Mat ms, mt, mv;
  cv::boxFilter(es, ms, CV_32F, cv::Size(w, w), cv::Point(-1, -1), false);
  cv::boxFilter(et, mt, CV_32F, cv::Size(w, w), cv::Point(-1, -1), false);
  cv::boxFilter(valid, mv, CV_32F, cv::Size(w, w), cv::Point(-1, -1), false);
  std::vector<float> all_s, all_t;
  for (int v = 0; v < il.rows; ++v) {
    const float* pv = valid.ptr<float>(v);
    const float* a = ms.ptr<float>(v);
    const float* b = mt.ptr<float>(v);
    const float* n = mv.ptr<float>(v);
    for (int u = 0; u < il.cols; ++u) {
      if (pv[u] == 0.0f || n[u] < 1.0f) continue;
      all_s.push_back(a[u] / n[u]);
      all_t.push_back(b[u] / n[u]);
    }
  }
  out.surface_pixels = static_cast<int>(all_s.size());
  if (all_s.empty()) return out;
  const double med_s = std::max(0.1, medianOf(all_s)), med_t = std::max(0.1, medianOf(all_t));
  const double usual = std::max(1.0, med_t / med_s);  // the temporal pair's usual excess
  cv::Mat flag(il.size(), CV_8U, cv::Scalar(0));
  for (int v = 0; v < il.rows; ++v) {
    const float* pv = valid.ptr<float>(v);
    const float* a = ms.ptr<float>(v);
    const float* b = mt.ptr<float>(v);
    const float* n = mv.ptr<float>(v);
    uint8_t* f = flag.ptr<uint8_t>(v);
    for (int u = 0; u < il.cols; ++u) {
      if (pv[u] == 0.0f || n[u] < 1.0f) continue;
      const double lt = b[u] / n[u], ls = a[u] / n[u];
      if (lt > options_.ratio * usual * ls + options_.margin_grey && lt > options_.share_of_median * med_t) f[u] = 255;
    }
  }
  if (options_.dilation_px > 0) {
    cv::dilate(flag, flag, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * options_.dilation_px + 1, 2 * options_.dilation_px + 1)));
  }
  out.pixels = cv::countNonZero(flag);
  if (out.pixels < options_.min_flagged_share * out.surface_pixels) {
    out.pixels = 0;
    return out;
  }
  out.masks.resize(static_cast<size_t>(left.levels()));
  for (int k = 0; k < left.levels(); ++k) {
    cv::resize(flag, out.masks[static_cast<size_t>(k)], left.level(k).image.size(), 0.0, 0.0, cv::INTER_NEAREST);
  }
  return out;
}

}  // namespace stereo_ground_dem
