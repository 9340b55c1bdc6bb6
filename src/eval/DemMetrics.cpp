#include "stereo_ground_dem/eval/DemMetrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

namespace stereo_ground_dem {

namespace {
bool lineOfSight(const sim::SyntheticScene& scene, const Eigen::Vector3d& camera, const Eigen::Vector3d& q);

/// DemMetrics::obs_*: every cell of the obstacle layer with a value, by what the scene had near it.
void obstacleLayer(const GroundGrid& grid, const cv::Mat& obstacles, const sim::SyntheticScene& scene,
                   const Eigen::Isometry3d& true_T_est, const std::vector<Eigen::Isometry3d>& c_T_g,
                   const std::vector<double>& times, double half_fov, DemMetrics* m) {
  const size_t n = std::min(times.size(), c_T_g.size());
  if (n == 0) return;
  const auto& boxes = scene.options().boxes;
  const int nb = static_cast<int>(boxes.size());
  auto movingId = [&](int id) { return id >= 1 && id <= nb && boxes[static_cast<size_t>(id - 1)].velocity_xy.norm() > 0.0; };
  m->obstacle_class = cv::Mat::zeros(grid.rows, grid.cols, CV_8U);
  constexpr double kNear = 0.5;  // [m]
  const double probe[5][2] = {{0, 0}, {kNear, 0}, {-kNear, 0}, {0, kNear}, {0, -kNear}};
  // In a frame's view: 4-30 m ahead, inside the image; with `unobstructed`, also not hidden from
  // the camera by an obstacle at that frame's time (the mover that just left a cell hides it while
  // it drives away from or toward the camera) or by the terrain.
  auto inView = [&](Eigen::Vector3d q, size_t from, bool unobstructed) {
    q.z() = scene.terrainHeight(q.x(), q.y());
    for (size_t k = from; k < n; ++k) {
      const Eigen::Vector3d xc = c_T_g[k] * q;
      if (!(xc.z() >= 4.0 && xc.z() <= 30.0 && std::abs(xc.x()) <= xc.z() * half_fov && xc.y() > 0.0)) continue;
      if (!unobstructed) return true;
      const Eigen::Vector3d o = c_T_g[k].inverse().translation();
      const Eigen::Vector3d d = q - o;
      const double len = d.norm();
      // up to 5 cm before the cell (no mover is within 0.5 m of it after it left)
      if (scene.rayCaster().intersectObstacles(o, d, 1.0 - 0.05 / len, times[k]).hit()) continue;
      if (!lineOfSight(scene, o, q)) continue;
      return true;
    }
    return false;
  };
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      const float value = obstacles.at<float>(r, c);
      {  // recall over the static footprints in view, whatever the layer says
        const Eigen::Vector3d q = true_T_est * Eigen::Vector3d(grid.xOfCol(c), grid.yOfRow(r), 0.0);
        const int id = scene.obstacleIdAt(q.x(), q.y(), times[0]);
        if (id > 0 && !movingId(id) && inView(q, 0, false)) {
          ++m->obs_static_in_view;
          m->obs_static_in_view_marked += std::isfinite(value) && value >= 0.5f;
        }
      }
      if (!std::isfinite(value)) continue;
      const bool marked = value >= 0.5f;
      Eigen::Vector3d p = true_T_est * Eigen::Vector3d(grid.xOfCol(c), grid.yOfRow(r), 0.0);
      bool ever_near = false, near_static = false, near_moving_last = false;
      int last_moving = -1;  // the last frame a moving footprint was near
      for (size_t k = 0; k < n; ++k) {
        bool moving_here = false;
        for (const auto& d : probe) {
          const int id = scene.obstacleIdAt(p.x() + d[0], p.y() + d[1], times[k]);
          if (id <= 0) continue;
          ever_near = true;
          if (movingId(id)) moving_here = true;
          else near_static = true;
        }
        if (moving_here) last_moving = static_cast<int>(k);
        if (k + 1 == n) near_moving_last = moving_here;
      }
      uint8_t& cls = m->obstacle_class.at<uint8_t>(r, c);
      if (!ever_near) {
        ++m->obs_free_known;
        m->obs_free_flagged += marked;
        cls = marked ? 2 : 1;
        continue;
      }
      if (near_static) {
        if (scene.insideObstacleFootprint(p.x(), p.y(), times[0]) && !movingId(scene.obstacleIdAt(p.x(), p.y(), times[0]))) {
          ++m->obs_static_known;
          m->obs_static_marked += marked;
          cls = marked ? 5 : 6;
        }
        continue;
      }
      if (last_moving < 0 || near_moving_last) continue;
      // left by a moving obstacle: seen again by a later frame?
      if (!inView(p, static_cast<size_t>(last_moving) + 1, true)) continue;
      ++m->obs_path_seen;
      m->obs_path_ghost += marked;
      cls = marked ? 4 : 3;
    }
  }
}

/// Whether the segment from `camera` to the terrain point `q` clears the terrain (sampled every
/// 0.25 m up to 0.3 m before q, 2 cm of slack): the point is not hidden behind a crest or a ridge.
bool lineOfSight(const sim::SyntheticScene& scene, const Eigen::Vector3d& camera, const Eigen::Vector3d& q) {
  const Eigen::Vector3d d = q - camera;
  const double len = d.norm();
  if (!(len > 0.3)) return true;
  const int n = static_cast<int>(std::ceil((len - 0.3) / 0.25));
  for (int i = 1; i <= n; ++i) {
    const Eigen::Vector3d p = camera + d * (std::min(i * 0.25, len - 0.3) / len);
    if (p.z() < scene.terrainHeight(p.x(), p.y()) - 0.02) return false;
  }
  return true;
}

void finish(std::vector<double>& e, int visible, int covered, HeightErrorStats* s) {
  s->count = static_cast<int>(e.size());
  s->coverage = visible > 0 ? static_cast<double>(covered) / visible : 0.0;
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
                               const std::vector<double>& times, const StereoRig& rig, const cv::Mat& true_trav,
                               const cv::Mat& obstacles) {
  DemMetrics m;
  const Eigen::Isometry3d true_T_est = true_g_T_c0 * est_g_T_c0.inverse();
  std::vector<Eigen::Isometry3d> c_T_g;  // true camera_T_ground per frame
  for (const auto& p : c0_T_c) c_T_g.push_back((true_g_T_c0 * p).inverse());
  const double half_fov = std::max(rig.cx, rig.width - 1 - rig.cx) / rig.fx;
  const double edges[5] = {0.0, 10.0, 20.0, 30.0, 40.0};
  std::vector<double> errs[4], err20;
  int visible[4] = {0, 0, 0, 0}, covered[4] = {0, 0, 0, 0}, visible20 = 0, covered20 = 0;
  std::vector<Eigen::Vector3d> centres;  // true camera centres
  for (const auto& t : c_T_g) centres.push_back(t.inverse().translation());
  std::vector<std::pair<double, size_t>> candidates;
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
      // (the heights are scored there); the coverage counts only where that camera's line of
      // sight cleared the terrain (ground hidden behind a crest is not there to be mapped)
      double best = std::numeric_limits<double>::infinity(), best_visible = best;
      const Eigen::Vector3d q(p.x(), p.y(), terrain);
      candidates.clear();
      for (size_t k = 0; k < c_T_g.size(); ++k) {
        const Eigen::Vector3d xc = c_T_g[k] * q;
        if (xc.z() > 0.5 && std::abs(xc.x()) <= xc.z() * half_fov && xc.y() > 0.0) {
          best = std::min(best, xc.z());
          if (xc.z() < edges[4]) candidates.emplace_back(xc.z(), k);
        }
      }
      if (!obstacle && !candidates.empty()) {
        std::sort(candidates.begin(), candidates.end());
        for (const auto& cand : candidates) {
          if (lineOfSight(scene, centres[cand.second], q)) {
            best_visible = cand.first;
            break;
          }
        }
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
        if (best >= edges[b] && best < edges[b + 1] && known) errs[b].push_back(e);
        if (best_visible >= edges[b] && best_visible < edges[b + 1]) {
          ++visible[b];
          covered[b] += known;
        }
      }
      if (best < 20.0 && known) err20.push_back(e);
      if (best_visible < 20.0) {
        ++visible20;
        covered20 += known;
      }
    }
  }
  for (int b = 0; b < 4; ++b) {
    HeightErrorStats s;
    s.min_depth_m = edges[b];
    s.max_depth_m = edges[b + 1];
    finish(errs[b], visible[b], covered[b], &s);
    m.bins.push_back(s);
  }
  m.within_20m.max_depth_m = 20.0;
  finish(err20, visible20, covered20, &m.within_20m);
  if (!obstacles.empty()) obstacleLayer(grid, obstacles, scene, true_T_est, c_T_g, times, half_fov, &m);
  m.trav_compared = tp + fp + fn + tn;
  m.trav_precision = tp + fp > 0 ? static_cast<double>(tp) / (tp + fp) : 0.0;
  m.trav_recall = tp + fn > 0 ? static_cast<double>(tp) / (tp + fn) : 0.0;
  m.trav_accuracy = m.trav_compared > 0 ? static_cast<double>(tp + tn) / m.trav_compared : 0.0;
  return m;
}

}  // namespace stereo_ground_dem
