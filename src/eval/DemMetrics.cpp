#include "stereo_ground_dem/eval/DemMetrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace stereo_ground_dem {

namespace {
void finish(std::vector<double>& e, int seen, HeightErrorStats* s) {
  s->count = static_cast<int>(e.size());
  s->coverage = seen > 0 ? static_cast<double>(e.size()) / seen : 0.0;
  if (e.empty()) return;
  std::sort(e.begin(), e.end());
  s->median_m = e[e.size() / 2];
  s->p95_m = e[std::min(e.size() - 1, e.size() * 95 / 100)];
  double sq = 0.0;
  for (double x : e) sq += x * x;
  s->rmse_m = std::sqrt(sq / e.size());
}
}  // namespace

DemMetrics DemMetrics::compute(const GroundGrid& grid, const cv::Mat& elevation, const cv::Mat& traversability,
                               const Eigen::Isometry3d& est_g_T_c0, const sim::SyntheticScene& scene,
                               const Eigen::Isometry3d& true_g_T_c0, const std::vector<Eigen::Isometry3d>& c0_T_c,
                               const std::vector<double>& times, const StereoRig& rig, const cv::Mat& true_trav) {
  DemMetrics m;
  const Eigen::Isometry3d true_T_est = true_g_T_c0 * est_g_T_c0.inverse();
  std::vector<Eigen::Isometry3d> c_T_g;  // true camera_T_ground per frame
  for (const auto& p : c0_T_c) c_T_g.push_back((true_g_T_c0 * p).inverse());
  const double half_fov = std::max(rig.cx, rig.width - 1 - rig.cx) / rig.fx;
  const double edges[5] = {0.0, 10.0, 20.0, 30.0, 40.0};
  std::vector<double> errs[4], err20;
  int seen[4] = {0, 0, 0, 0}, seen20 = 0;
  int tp = 0, fp = 0, fn = 0, tn = 0;
  m.signed_error = cv::Mat(grid.rows, grid.cols, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      const double z_est = elevation.at<float>(r, c);
      const bool known = std::isfinite(z_est);
      const Eigen::Vector3d p_est(grid.xOfCol(c), grid.yOfRow(r), known ? z_est : 0.0);
      Eigen::Vector3d p = true_T_est * p_est;
      const double terrain = scene.terrainHeight(p.x(), p.y());
      if (!known) p = true_T_est * Eigen::Vector3d(p_est.x(), p_est.y(), 0.0);
      bool obstacle = false;
      for (double t : times) obstacle = obstacle || scene.insideObstacleFootprint(p.x(), p.y(), t);
      // smallest depth at which a camera saw the terrain point inside its horizontal field of view
      double best = std::numeric_limits<double>::infinity();
      const Eigen::Vector3d q(p.x(), p.y(), terrain);
      for (const auto& t : c_T_g) {
        const Eigen::Vector3d xc = t * q;
        if (xc.z() > 0.5 && std::abs(xc.x()) <= xc.z() * half_fov && xc.y() > 0.0) best = std::min(best, xc.z());
      }
      if (known) {
        ++m.known_vertices;
        if (obstacle) ++m.obstacle_vertices;
      }
      if (!traversability.empty() && known && std::isfinite(traversability.at<float>(r, c))) {
        bool truth_blocked = obstacle;
        if (!truth_blocked && !true_trav.empty()) {
          const float tt = true_trav.at<float>(r, c);
          truth_blocked = std::isfinite(tt) && tt < 0.5f;
        }
        const bool est_blocked = traversability.at<float>(r, c) < 0.5f;
        tp += truth_blocked && est_blocked;
        fp += !truth_blocked && est_blocked;
        fn += truth_blocked && !est_blocked;
        tn += !truth_blocked && !est_blocked;
      }
      if (known && !obstacle) m.signed_error.at<float>(r, c) = static_cast<float>(p.z() - terrain);
      if (obstacle || !std::isfinite(best)) continue;
      const double e = std::abs(p.z() - terrain);
      for (int b = 0; b < 4; ++b) {
        if (best >= edges[b] && best < edges[b + 1]) {
          ++seen[b];
          if (known) errs[b].push_back(e);
        }
      }
      if (best < 20.0) {
        ++seen20;
        if (known) err20.push_back(e);
      }
    }
  }
  for (int b = 0; b < 4; ++b) {
    HeightErrorStats s;
    s.min_depth_m = edges[b];
    s.max_depth_m = edges[b + 1];
    finish(errs[b], seen[b], &s);
    m.bins.push_back(s);
  }
  m.within_20m.max_depth_m = 20.0;
  finish(err20, seen20, &m.within_20m);
  m.trav_compared = tp + fp + fn + tn;
  m.trav_precision = tp + fp > 0 ? static_cast<double>(tp) / (tp + fp) : 0.0;
  m.trav_recall = tp + fn > 0 ? static_cast<double>(tp) / (tp + fn) : 0.0;
  m.trav_accuracy = m.trav_compared > 0 ? static_cast<double>(tp + tn) / m.trav_compared : 0.0;
  return m;
}

}  // namespace stereo_ground_dem
