#include "stereo_ground_dem/eval/TrajectoryMetrics.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace stereo_ground_dem {

namespace {
double angleDeg(const Eigen::Matrix3d& r) {
  return Eigen::AngleAxisd(r).angle() * 180.0 / M_PI;
}
double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}
}  // namespace

TrajectoryMetrics TrajectoryMetrics::compute(const std::vector<Eigen::Isometry3d>& est,
                                             const std::vector<Eigen::Isometry3d>& gt,
                                             const std::vector<double>& segment_lengths_m) {
  TrajectoryMetrics m;
  const size_t n = std::min(est.size(), gt.size());
  m.frames = static_cast<int>(n);
  if (n == 0) return m;
  std::vector<double> dist(n, 0.0);
  for (size_t k = 1; k < n; ++k) dist[k] = dist[k - 1] + (gt[k].translation() - gt[k - 1].translation()).norm();
  m.path_length_m = dist.back();
  m.end_translation_error_m = (est[n - 1].translation() - gt[n - 1].translation()).norm();
  m.end_drift_pct = m.path_length_m > 0 ? 100.0 * m.end_translation_error_m / m.path_length_m : 0.0;
  m.end_rotation_error_deg = angleDeg(gt[n - 1].linear().transpose() * est[n - 1].linear());
  for (size_t k = 0; k < n; ++k) {
    m.abs_rotation_deg.push_back(angleDeg(gt[k].linear().transpose() * est[k].linear()));
    m.max_rotation_error_deg = std::max(m.max_rotation_error_deg, m.abs_rotation_deg.back());
    if (k == 0) continue;
    const Eigen::Isometry3d rel_e = est[k - 1].inverse() * est[k];
    const Eigen::Isometry3d rel_g = gt[k - 1].inverse() * gt[k];
    const Eigen::Isometry3d err = rel_g.inverse() * rel_e;
    m.rel_translation_m.push_back(err.translation().norm());
    m.rel_rotation_deg.push_back(angleDeg(err.linear()));
  }
  if (!m.rel_translation_m.empty()) {
    const double k = static_cast<double>(m.rel_translation_m.size());
    m.rel_translation_mean_m = std::accumulate(m.rel_translation_m.begin(), m.rel_translation_m.end(), 0.0) / k;
    m.rel_rotation_mean_deg = std::accumulate(m.rel_rotation_deg.begin(), m.rel_rotation_deg.end(), 0.0) / k;
    m.rel_translation_median_m = median(m.rel_translation_m);
    m.rel_rotation_median_deg = median(m.rel_rotation_deg);
    m.rel_translation_max_m = *std::max_element(m.rel_translation_m.begin(), m.rel_translation_m.end());
    m.rel_rotation_max_deg = *std::max_element(m.rel_rotation_deg.begin(), m.rel_rotation_deg.end());
  }
  for (double len : segment_lengths_m) {
    if (len > m.path_length_m) continue;
    SegmentError s;
    s.length_m = len;
    for (size_t i = 0; i < n; ++i) {
      size_t j = i;
      while (j < n && dist[j] - dist[i] < len) ++j;
      if (j >= n) break;
      const Eigen::Isometry3d d_e = est[i].inverse() * est[j];
      const Eigen::Isometry3d d_g = gt[i].inverse() * gt[j];
      const Eigen::Isometry3d err = d_g.inverse() * d_e;
      s.translation_pct += 100.0 * err.translation().norm() / len;
      s.rotation_deg_per_m += angleDeg(err.linear()) / len;
      ++s.count;
    }
    if (s.count > 0) {
      s.translation_pct /= s.count;
      s.rotation_deg_per_m /= s.count;
      m.segments.push_back(s);
    }
  }
  return m;
}

}  // namespace stereo_ground_dem
