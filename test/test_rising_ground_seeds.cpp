// RisingGroundSeeds: starting heights for ground rising out of the surface hypothesis, from the
// points of the pixels the obstacle test took for upright; upright things' points seed nothing.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/RisingGroundSeeds.hpp"

using namespace stereo_ground_dem;

namespace {

// A 20 x 10 m window, 0.5 m spacing, its hypothesis level at 0 and unknown; the camera at the
// origin, 1.65 m up.
struct RiseWindow {
  GroundGrid grid = GroundGrid::covering(0.0, 20.0, -5.0, 5.0, 0.5);
  Eigen::VectorXd heights = Eigen::VectorXd::Zero(grid.vertexCount());
  Eigen::VectorXd info = Eigen::VectorXd::Zero(grid.vertexCount());
  Eigen::Vector3d camera{0.0, 0.0, 1.65};
  int at(double x, double y) const {
    return grid.index(static_cast<int>(std::lround((y - grid.y0()) / 0.5)), static_cast<int>(std::lround((x - grid.x0()) / 0.5)));
  }
  Eigen::VectorXd seeds(const std::vector<Eigen::Vector3d>& pts, RisingGroundSeedsOptions o = {}) const {
    return RisingGroundSeeds(o).seeds(grid, heights, info, camera, pts);
  }
};

// Points every 0.1 m over x in [x0, x1], y in [y0, y1], at height f(x, y).
template <typename F>
std::vector<Eigen::Vector3d> sheet(double x0, double x1, double y0, double y1, F f) {
  std::vector<Eigen::Vector3d> p;
  for (double x = x0; x <= x1 + 1e-9; x += 0.1)
    for (double y = y0; y <= y1 + 1e-9; y += 0.1) p.emplace_back(x, y, f(x, y));
  return p;
}

int count(const Eigen::VectorXd& s) { return static_cast<int>(s.array().isFinite().count()); }

}  // namespace

// A hill rising at 15 deg out of the level hypothesis; its points (the pixels the obstacle test
// flagged) begin at x = 9 m, 0.16 m up, next to vertices whose pixels fit the hypothesis: its
// vertices start at the slope's height, exactly. Where the points begin higher than one step
// (0.18 m at 20 deg) above such vertices, nothing grows (a thing standing on the ground).
TEST(RisingGroundSeeds, GroundRisingFromTheSurfaceStartsOnIt) {
  const RiseWindow w;
  const double g = std::tan(15.0 * M_PI / 180.0);
  const auto hill = [g](double x, double) { return 0.16 + g * (x - 9.0); };
  const Eigen::VectorXd s = w.seeds(sheet(9.0, 14.0, -3.0, 3.0, hill));
  EXPECT_NEAR(s[w.at(9.0, 0.0)], 0.16, 1e-9);
  EXPECT_NEAR(s[w.at(11.0, 0.0)], 0.16 + 2.0 * g, 1e-9);
  EXPECT_NEAR(s[w.at(13.0, 1.5)], 0.16 + 4.0 * g, 1e-9);
  EXPECT_FALSE(std::isfinite(s[w.at(8.5, 0.0)]));   // before the points
  EXPECT_FALSE(std::isfinite(s[w.at(15.0, 0.0)]));  // past them
  // x 9-14, y -3-3 (11 x 13), and some of the next row and column, whose cells hold the edges'
  // points (measured: 153)
  EXPECT_GE(count(s), 11 * 13);
  EXPECT_LE(count(s), 11 * 13 + 11 + 13);
  EXPECT_EQ(count(w.seeds(sheet(9.0, 14.0, -3.0, 3.0, [g](double x, double) { return 0.3 + g * (x - 9.0); }))), 0);
  // known vertices keep the map's heights; points beyond max_range_m count for nothing
  RiseWindow known = w;
  known.info[w.at(11.0, 0.0)] = 5.0;
  EXPECT_FALSE(std::isfinite(known.seeds(sheet(9.0, 14.0, -3.0, 3.0, hill))[w.at(11.0, 0.0)]));
  RisingGroundSeedsOptions near;
  near.max_range_m = 8.0;
  EXPECT_EQ(count(w.seeds(sheet(9.0, 14.0, -3.0, 3.0, hill), near)), 0);
}

// Steeper than max_slope_deg (20 deg): no seed; points along one line across the view (one
// depth step of whole-pixel disparities) still give the slope along the line.
TEST(RisingGroundSeeds, SteepOrLinearPoints) {
  const RiseWindow w;
  const double steep = std::tan(30.0 * M_PI / 180.0);
  EXPECT_EQ(count(w.seeds(sheet(9.0, 14.0, -3.0, 3.0, [steep](double x, double) { return 0.16 + steep * (x - 9.0); }))), 0);
  // a bank rising sideways at 10 deg from y = 1 (0.16 m up there), its points on lines x = 9.0,
  // 9.5, ..., 12.0
  const double g = std::tan(10.0 * M_PI / 180.0);
  std::vector<Eigen::Vector3d> lines;
  for (double x = 9.0; x <= 12.0 + 1e-9; x += 0.5)
    for (double y = 1.0; y <= 5.0 + 1e-9; y += 0.05) lines.emplace_back(x, y, 0.16 + g * (y - 1.0));
  const Eigen::VectorXd s = w.seeds(lines);
  EXPECT_NEAR(s[w.at(10.0, 3.0)], 0.16 + 2.0 * g, 1e-6);
  EXPECT_GE(count(s), 12);
}

// Upright things seed nothing: a wall beside the path and a car's back (points stacked from
// the foot to the top) fit no plane; the car's roof (a plane, 1.4 m up) stands off the ground
// around it; a patch of fewer than min_region_vertices vertices is dropped.
TEST(RisingGroundSeeds, UprightThingsSeedNothing) {
  const RiseWindow w;
  std::vector<Eigen::Vector3d> wall;  // y = -3, x 6-14, 0-2 m high
  for (double x = 6.0; x <= 14.0; x += 0.1)
    for (double z = 0.0; z <= 2.0; z += 0.1) wall.emplace_back(x, -3.0, z);
  EXPECT_EQ(count(w.seeds(wall)), 0);
  std::vector<Eigen::Vector3d> car = sheet(10.0, 14.0, -1.0, 1.0, [](double, double) { return 1.4; });  // roof
  for (double y = -1.0; y <= 1.0; y += 0.1)
    for (double z = 0.0; z <= 1.4; z += 0.1) car.emplace_back(10.0, y, z);  // back
  EXPECT_EQ(count(w.seeds(car)), 0);
  // the same roof 0.17 m up (a low platform, within one step of the ground): seeded
  EXPECT_GT(count(w.seeds(sheet(10.0, 14.0, -1.0, 1.0, [](double, double) { return 0.17; }))), 12);
  RisingGroundSeedsOptions big;
  big.min_region_vertices = 100;
  EXPECT_EQ(count(w.seeds(sheet(10.0, 14.0, -1.0, 1.0, [](double, double) { return 0.17; }), big)), 0);
  RisingGroundSeedsOptions bad;
  bad.max_slope_deg = 90.0;
  EXPECT_THROW(RisingGroundSeeds{bad}, std::invalid_argument);
}
