#pragma once
// Shared by the stereo-mode and obstacle tests: a rendered KITTI-like pair with its truth, and
// the median / 95th percentile of a list of errors.
#include <algorithm>
#include <vector>

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

}  // namespace test
}  // namespace stereo_ground_dem
