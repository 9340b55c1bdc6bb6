#pragma once
// Shared by the stereo-mode and obstacle tests: a rendered KITTI-like pair with its truth, and
// the median / 95th percentile of a list of errors.
#include <algorithm>
#include <cmath>
#include <vector>

#include "stereo_ground_dem/StereoEstimator.hpp"
#include "stereo_ground_dem/sim/SequenceGenerator.hpp"
#include "stereo_ground_dem/sim/StereoRenderer.hpp"

namespace stereo_ground_dem {
namespace test {

struct Quantiles {
  double median = 0.0, p95 = 0.0;
  size_t count = 0;
};

inline Quantiles quantiles(std::vector<double> e) {
  Quantiles q;
  q.count = e.size();
  if (e.empty()) return q;
  std::sort(e.begin(), e.end());
  q.median = e[e.size() / 2];
  q.p95 = e[std::min(e.size() - 1, e.size() * 95 / 100)];
  return q;
}

struct SyntheticPair {
  sim::SyntheticScene scene;
  StereoRig rig;
  Eigen::Isometry3d ground_T_left;
  sim::RenderedPair pair;
};

/// A KITTI-like pair of a standard scene (seed 7), sensor noise 1 grey, left = 1.2 x right + 10
/// (gain 20 % and bias 10 levels apart); with the standard obstacles when asked.
inline SyntheticPair renderPair(sim::SceneKind kind, bool obstacles = false) {
  sim::SceneOptions so = sim::SceneOptions::standard(kind, 7);
  if (obstacles) so.addStandardObstacles();
  SyntheticPair c{sim::SyntheticScene(so), sim::StereoRenderer::kittiLikeRig(1.0), {}, {}};
  sim::RenderOptions ro;
  ro.noise_std_grey = 1.0;
  const sim::StereoRenderer renderer(c.scene, c.rig, ro);
  c.ground_T_left = sim::SequenceGenerator::cameraPose(c.scene, sim::SequenceOptions(), 0.0, 0.0, 0.0);
  c.pair = renderer.renderPair(c.ground_T_left, {1.2, 10.0}, {1.0, 0.0}, 0.0, 3);
  return c;
}

/// Absolute height errors [m] of the observed vertices at camera depth [near, far), excluding
/// obstacle footprints, in the true ground frame.
inline std::vector<double> heightErrors(const SyntheticPair& c, const StereoResult& r, double near_m, double far_m) {
  const Eigen::Isometry3d true_T_est = c.ground_T_left * r.ground_T_camera.inverse();
  std::vector<double> e;
  for (int v = 0; v < r.grid.vertexCount(); ++v) {
    if (!std::isfinite(r.heights[v])) continue;
    const Eigen::Vector2d xy = r.grid.position(v);
    const Eigen::Vector3d p = true_T_est * Eigen::Vector3d(xy.x(), xy.y(), r.heights[v]);
    const double depth = (c.ground_T_left.inverse() * p).z();
    if (depth < near_m || depth >= far_m || c.scene.insideObstacleFootprint(p.x(), p.y(), 0.0)) continue;
    e.push_back(std::abs(p.z() - c.scene.terrainHeight(p.x(), p.y())));
  }
  return e;
}

}  // namespace test
}  // namespace stereo_ground_dem
