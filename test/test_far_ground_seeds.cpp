// FarGroundSeeds: starting heights for unknown vertices from the points of pixels that saw past
// the surface hypothesis (the far side of a crest). MapView's extension around them:
// test_pose_search.cpp, MapView.SeedsAreKeptAndTheBandBetweenFollows.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "stereo_ground_dem/FarGroundSeeds.hpp"
#include "stereo_ground_dem/GroundGrid.hpp"

using namespace stereo_ground_dem;

namespace {

// A 5 x 5 m window, 0.5 m spacing (11 x 11 vertices), its hypothesis 1 m high everywhere.
struct SeedWindow {
  GroundGrid grid = GroundGrid::covering(0.0, 5.0, 0.0, 5.0, 0.5);
  Eigen::VectorXd heights = Eigen::VectorXd::Constant(grid.vertexCount(), 1.0);
  Eigen::VectorXd info = Eigen::VectorXd::Zero(grid.vertexCount());
  int at(double x, double y) const {
    return grid.index(static_cast<int>(std::lround((y - grid.y0()) / 0.5)), static_cast<int>(std::lround((x - grid.x0()) / 0.5)));
  }
};

}  // namespace

// Points in the cells around (2, 2): each counts for its cell's four vertices, the vertex takes
// their median; an outlier (a point of a tree's window) does not move it.
TEST(FarGroundSeeds, UnknownVertexTakesTheMedianOfItsPoints) {
  const SeedWindow w;
  std::vector<Eigen::Vector3d> pts = {{2.1, 2.1, -0.50}, {1.9, 1.8, -0.40}, {2.2, 1.7, -0.45}, {1.8, 2.3, 3.0}};
  const Eigen::VectorXd s = FarGroundSeeds().seeds(w.grid, w.heights, w.info, pts);
  ASSERT_EQ(s.size(), w.grid.vertexCount());
  EXPECT_NEAR(s[w.at(2.0, 2.0)], -0.40, 1e-12);  // all four points: median of -0.5, -0.45, -0.4, 3.0 (upper)
  int seeded = 0;
  for (int v = 0; v < s.size(); ++v) seeded += std::isfinite(s[v]) ? 1 : 0;
  EXPECT_EQ(seeded, 1);  // the neighbours have fewer than min_points (3) points each
}

// Known vertices keep the map's heights; a median above the hypothesis (less than min_drop_m
// below it) is no ground seen past it; points outside the window count for nothing.
TEST(FarGroundSeeds, KnownHigherOrOutsideIsNotSeeded) {
  SeedWindow w;
  const std::vector<Eigen::Vector3d> low = {{2.1, 2.1, 0.0}, {1.9, 1.8, 0.1}, {2.2, 1.7, 0.05}};
  w.info[w.at(2.0, 2.0)] = 4.0;
  EXPECT_FALSE(std::isfinite(FarGroundSeeds().seeds(w.grid, w.heights, w.info, low)[w.at(2.0, 2.0)]));
  w.info.setZero();
  EXPECT_TRUE(std::isfinite(FarGroundSeeds().seeds(w.grid, w.heights, w.info, low)[w.at(2.0, 2.0)]));
  const std::vector<Eigen::Vector3d> high = {{2.1, 2.1, 0.85}, {1.9, 1.8, 0.9}, {2.2, 1.7, 0.95}};  // 0.1 m below
  EXPECT_FALSE(std::isfinite(FarGroundSeeds().seeds(w.grid, w.heights, w.info, high)[w.at(2.0, 2.0)]));
  const std::vector<Eigen::Vector3d> outside = {{7.1, 2.1, 0.0}, {-1.9, 1.8, 0.0}, {2.2, 5.7, 0.0},
                                                {std::numeric_limits<double>::quiet_NaN(), 2.0, 0.0}};
  EXPECT_EQ(FarGroundSeeds().seeds(w.grid, w.heights, w.info, outside).array().isFinite().count(), 0);
  FarGroundSeedsOptions bad;
  bad.min_points = 0;
  EXPECT_THROW(FarGroundSeeds{bad}, std::invalid_argument);
}

// A camera 2 m above (0, 0) sees a point at (10, 0, 0): the ray falls 0.2 m per metre. Its first
// 80 % (ray_share) bounds the vertices it passes over at its height there (x = 5: 1.0 m, x = 7.5:
// 0.5 m); the last 20 % (the point's depth is rough) and vertices off the ray stay unbounded.
TEST(FarGroundSeeds, RaysBoundTheGroundTheyPassOver) {
  const GroundGrid grid = GroundGrid::covering(0.0, 12.0, -2.0, 2.0, 0.5);
  const Eigen::Vector3d camera(0.0, 0.0, 2.0);
  const Eigen::VectorXd c = FarGroundSeeds().ceilings(grid, camera, {Eigen::Vector3d(10.0, 0.0, 0.0)});
  auto at = [&](double x, double y) {
    return c[grid.index(static_cast<int>(std::lround((y - grid.y0()) / 0.5)), static_cast<int>(std::lround((x - grid.x0()) / 0.5)))];
  };
  EXPECT_NEAR(at(5.0, 0.0), 1.0, 1e-9);
  EXPECT_NEAR(at(7.5, 0.0), 0.5, 1e-9);
  EXPECT_NEAR(at(8.0, 0.0), 0.4, 1e-9);  // the last sample: 80 % of the way
  EXPECT_TRUE(std::isinf(at(9.0, 0.0)));
  EXPECT_TRUE(std::isinf(at(5.0, 1.0)));
  // a second, lower ray over the same vertices: the lowest bound counts
  const Eigen::VectorXd c2 =
      FarGroundSeeds().ceilings(grid, camera, {Eigen::Vector3d(10.0, 0.0, 0.0), Eigen::Vector3d(5.0, 0.0, 0.0)});
  EXPECT_NEAR(c2[grid.index(static_cast<int>(std::lround((0.0 - grid.y0()) / 0.5)), 6)], 2.0 - 0.4 * 3.0, 1e-9);  // x = 3
}

// starts(): a seed where an unknown vertex has one; elsewhere a vertex, known or not, standing more
// than ceiling_margin_m (0.1 m) above a far ray starts at the ray; vertices under it keep theirs.
TEST(FarGroundSeeds, StartsAreSeedsThenCeilings) {
  const GroundGrid grid = GroundGrid::covering(0.0, 12.0, -2.0, 2.0, 0.5);
  auto at = [&](double x, double y) {
    return grid.index(static_cast<int>(std::lround((y - grid.y0()) / 0.5)), static_cast<int>(std::lround((x - grid.x0()) / 0.5)));
  };
  Eigen::VectorXd heights = Eigen::VectorXd::Constant(grid.vertexCount(), 0.3);
  Eigen::VectorXd info = Eigen::VectorXd::Constant(grid.vertexCount(), 5.0);
  heights[at(5.0, 0.0)] = 1.0;  // within the margin of the lowest ray (0.93-1.0 m there): kept
  heights[at(7.5, 0.0)] = 0.7;   // 0.2 m above the ray (0.5 m): carved, though known
  info[at(10.0, 0.0)] = 0.0;     // unknown, with three points around it: seeded
  const std::vector<Eigen::Vector3d> pts = {{10.0, 0.0, 0.0}, {10.1, 0.1, -0.1}, {9.9, -0.1, 0.0}};
  const FarGroundStarts s = FarGroundSeeds().starts(grid, heights, info, Eigen::Vector3d(0.0, 0.0, 2.0), pts);
  ASSERT_EQ(s.heights.size(), grid.vertexCount());
  EXPECT_FALSE(std::isfinite(s.heights[at(5.0, 0.0)]));
  const Eigen::VectorXd ceiling = FarGroundSeeds().ceilings(grid, Eigen::Vector3d(0.0, 0.0, 2.0), pts);
  EXPECT_EQ(s.heights[at(7.5, 0.0)], ceiling[at(7.5, 0.0)]);
  EXPECT_NEAR(s.heights[at(7.5, 0.0)], 0.42, 0.01);  // the lowest ray's nearest sample (x = 7.59)
  EXPECT_NEAR(s.heights[at(10.0, 0.0)], 0.0, 1e-12);
  EXPECT_FALSE(std::isfinite(s.heights[at(2.0, 1.5)]));  // off every ray
  // the 0.3 m vertices stand below every ray (no lower than ~0.3 m at 80 % of the way): only x = 7.5
  EXPECT_EQ(s.carved_vertices, 1);
  EXPECT_EQ(s.seeded_vertices, 2);
}
