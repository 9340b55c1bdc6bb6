// DemMetrics' obstacle-layer classes on hand-made layers: a cell a moving obstacle left is "seen
// again" (and, still marked, a ghost) only when a later frame had it in the image, 4-30 m ahead,
// with nothing standing in the line of sight. A car driving toward the camera hides the ground it
// has just left behind it; the same car driving away leaves that ground in plain view.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/StereoRig.hpp"
#include "stereo_ground_dem/eval/DemMetrics.hpp"
#include "stereo_ground_dem/sim/StereoRenderer.hpp"
#include "stereo_ground_dem/sim/SyntheticScene.hpp"

using namespace stereo_ground_dem;

namespace {

struct Scored {
  int seen = 0, ghosts = 0;
  int left_seen = 0, left = 0;  ///< cells within 0.5 m of the van's centre line on the stretch it left
};

/// A camera standing 1.65 m above a flat road, looking along +x; one 3 m tall van on the camera's
/// line (y = 0) from x = 14 m, driving at `speed_mps` along x for 6 frames (0.1 s apart); every
/// cell of the obstacle layer marked.
Scored score(double speed_mps) {
  sim::SceneOptions so = sim::SceneOptions::standard(sim::SceneKind::kFlatRoad, 1);
  so.boxes.clear();
  so.poles.clear();
  sim::BoxObstacle van;
  van.center_xy = {speed_mps < 0.0 ? 22.0 : 14.0, 0.0};
  van.length_m = 4.0;
  van.width_m = 2.0;
  van.height_m = 3.0;
  van.velocity_xy = {speed_mps, 0.0};
  so.boxes.push_back(van);
  const sim::SyntheticScene scene(so);
  const StereoRig rig = sim::StereoRenderer::kittiLikeRig(1.0);
  Eigen::Isometry3d g_T_c0 = Eigen::Isometry3d::Identity();
  g_T_c0.linear() << 0, 0, 1, -1, 0, 0, 0, -1, 0;  // optical z along ground x, x along -y
  g_T_c0.translation() = Eigen::Vector3d(0.0, 0.0, 1.65);
  std::vector<Eigen::Isometry3d> c0_T_c(6, Eigen::Isometry3d::Identity());
  std::vector<double> times;
  for (int k = 0; k < 6; ++k) times.push_back(0.1 * k);
  const GroundGrid grid = GroundGrid::covering(5.0, 30.0, -5.0, 5.0, 0.5);
  const cv::Mat elevation(grid.rows, grid.cols, CV_32F, cv::Scalar(0.0f));
  const cv::Mat marked(grid.rows, grid.cols, CV_32F, cv::Scalar(1.0f));
  const DemMetrics m = DemMetrics::compute(grid, elevation, cv::Mat(), g_T_c0, scene, g_T_c0, c0_T_c, times, rig,
                                           cv::Mat(), marked);
  Scored s;
  s.seen = m.obs_path_seen;
  s.ghosts = m.obs_path_ghost;
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      const double x = grid.xOfCol(c), y = grid.yOfRow(r);
      // the stretch the van left: 20.5-24 m driving toward the camera, 12-16 m driving away
      const bool left = speed_mps < 0.0 ? x >= 20.5 && x <= 24.0 : x >= 12.0 && x <= 16.0;
      if (std::abs(y) > 0.5 || !left) continue;
      ++s.left;
      const uint8_t cls = m.obstacle_class.at<uint8_t>(r, c);
      s.left_seen += cls == 3 || cls == 4;
    }
  }
  return s;
}

}  // namespace

TEST(DemMetrics, GroundAMoverLeftCountsAsSeenOnlyInALineOfSight) {
  // Toward the camera (centre 22 -> 17.5 m): the ground it left (20.5-24 m) lies behind it, hidden.
  const Scored toward = score(-10.0);
  // Away from the camera (centre 14 -> 18.5 m): the ground it left (12-16 m) lies in front of it.
  const Scored away = score(10.0);
  std::printf("toward: %d cells seen again (%d ghosts), on its centre line %d of %d; away: %d (%d), %d of %d\n",
              toward.seen, toward.ghosts, toward.left_seen, toward.left, away.seen, away.ghosts, away.left_seen, away.left);
  ASSERT_GT(toward.left, 10);
  EXPECT_EQ(toward.left_seen, 0);
  EXPECT_EQ(away.left_seen, away.left);
  EXPECT_EQ(toward.ghosts, toward.seen);  // every cell is marked
  EXPECT_EQ(away.ghosts, away.seen);
}
