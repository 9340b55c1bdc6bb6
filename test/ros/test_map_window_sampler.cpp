// MapWindowSampler: the layers the node publishes over a window of the map. The window and stride
// arithmetic; heights the images keep contradicting unknown in every layer built from the heights
// and in the OccupancyGrid, while the map keeps them; obstacles lethal; decimation on the lattice.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "../level_ground_views.hpp"
#include "stereo_ground_dem/PhotometricResidualMap.hpp"
#include "stereo_ground_dem/ros/MapWindowSampler.hpp"
#include "stereo_ground_dem/ros/TraversabilityCostTable.hpp"

namespace sgd = stereo_ground_dem;

namespace {

int nanCount(const cv::Mat& m) { return static_cast<int>(m.total()) - cv::countNonZero(m == m); }

/// A level map over x 0..60 m, its residual map after two frames (the second one's left image
/// shows a bright square where the ground at x 11-12 m, y -0.5..0.5 m is: an object the ground does
/// not explain), and an obstacle seen in two frames over x 16-16.5 m, y 2-2.5 m (2 x 2 vertices).
struct Scene {
  sgd::GroundGrid map_window;
  sgd::ElevationMap map;
  sgd::PhotometricResidualMap residual{0.5};
  const sgd::GroundGrid obstacle = sgd::GroundGrid::covering(16.0, 16.5, 2.0, 2.5, 0.5);
  Scene() : map(sgd::test::levelGroundMap(&map_window)) {
    const sgd::StereoRig k = sgd::test::levelGroundRig();
    auto pose = [](double x, double right) {
      Eigen::Isometry3d p = sgd::test::levelGroundCamera(x);
      p.translate(Eigen::Vector3d(right, 0.0, 0.0));
      return p;
    };
    auto pixel = [&](double x, double y) {
      const Eigen::Vector3d p = pose(1.0, 0.0).inverse() * Eigen::Vector3d(x, y, 0.0);
      return cv::Point(static_cast<int>(k.fx * p.x() / p.z() + k.cx), static_cast<int>(k.fy * p.y() / p.z() + k.cy));
    };
    residual.update(map, map_window, sgd::test::levelGroundImage(pose(0.0, 0.0)),
                    sgd::test::levelGroundImage(pose(0.0, 0.54)), k, pose(0.0, 0.0), sgd::VerticalMisalignment(), {},
                    nullptr);
    cv::Mat left1 = sgd::test::levelGroundImage(pose(1.0, 0.0));
    cv::rectangle(left1, cv::Rect(pixel(12.0, 0.5), pixel(11.0, -0.5)), cv::Scalar(250.0), cv::FILLED);
    const sgd::PhotometricParams same;
    residual.update(map, map_window, left1, sgd::test::levelGroundImage(pose(1.0, 0.54)), k, pose(1.0, 0.0),
                    sgd::VerticalMisalignment(), {}, &same);
    const int m = obstacle.vertexCount();
    for (int frame = 0; frame < 2; ++frame) {
      map.updateObstacles(obstacle, std::vector<uint8_t>(m, 1), std::vector<uint8_t>(m, 0),
                          Eigen::VectorXd::Constant(m, 0.8), frame);
    }
  }
};

}  // namespace

TEST(MapWindowSampler, WindowAndStride) {
  // the vertex rectangle nearest the centre, spanning at least the size
  const sgd::GroundGrid g = sgd::MapWindowSampler::window(0.5, 10.0, 0.0, 4.0, 3.0);
  EXPECT_EQ(g.cols, 9);
  EXPECT_EQ(g.rows, 7);
  EXPECT_DOUBLE_EQ(g.xOfCol(4), 10.0);
  EXPECT_DOUBLE_EQ(g.yOfRow(3), 0.0);
  EXPECT_DOUBLE_EQ(g.xOfCol(g.cols - 1) - g.xOfCol(0), 4.0);
  const sgd::GroundGrid odd = sgd::MapWindowSampler::window(0.5, 10.1, 0.2, 3.3, 0.0);
  EXPECT_EQ(odd.cols, 8);  // ceil(6.6) + 1: at least 3.3 m
  EXPECT_EQ(odd.rows, 2);  // at least 2 x 2 vertices
  EXPECT_NEAR(0.5 * (odd.xOfCol(0) + odd.xOfCol(odd.cols - 1)), 10.1, 0.25);
  EXPECT_EQ(sgd::MapWindowSampler::stride(100, 100, 0), 1);  // no limit
  EXPECT_EQ(sgd::MapWindowSampler::stride(100, 100, 10000), 1);
  EXPECT_EQ(sgd::MapWindowSampler::stride(100, 100, 9999), 2);  // 50 x 50
  EXPECT_EQ(sgd::MapWindowSampler::stride(101, 101, 2500), 3);  // 51 x 51 > 2500 >= 34 x 34
}

TEST(MapWindowSampler, ContradictedHeightsAreUnknownInEveryLayerBuiltFromThem) {
  const Scene s;
  const sgd::GroundGrid w = sgd::MapWindowSampler::window(0.5, 13.0, 0.0, 10.0, 8.0);
  const sgd::MapWindowSampler sampler;
  sgd::ExtraLayerSources extra;
  extra.residual = &s.residual;
  const sgd::DemLayers plain = sampler.sample(s.map, w);
  const sgd::DemLayers d = sampler.sample(s.map, w, 0, extra);
  ASSERT_TRUE(d.grid.sameLayout(w));
  const cv::Mat contradicted = s.residual.contradicted(w);
  const int n = cv::countNonZero(contradicted);
  // within the square's cells (x 11-12 m, y -0.5..0.5 m: 3 x 3 vertices; measured 5)
  EXPECT_GE(n, 4);
  EXPECT_LE(n, 9);
  for (int v = 0; v < w.vertexCount(); ++v) {
    const Eigen::Vector2d p = w.position(v);
    if (contradicted.at<uint8_t>(w.rowOf(v), w.colOf(v))) EXPECT_TRUE(p.x() >= 11.0 && p.x() <= 12.0 && std::abs(p.y()) <= 0.5);
  }
  // the map keeps every height; the published elevation loses exactly the contradicted ones
  EXPECT_EQ(nanCount(*plain.find("elevation")), 0);
  EXPECT_EQ(plain.knownCount(), w.vertexCount());
  EXPECT_EQ(d.knownCount(), w.vertexCount() - n);
  for (const char* name : {"elevation", "variance", "slope", "traversability", "traversability_confidence"}) {
    const cv::Mat& l = *d.find(name);
    EXPECT_EQ(cv::countNonZero((l == l) & contradicted), 0) << name << " known on a contradicted cell";
  }
  EXPECT_EQ(nanCount(*d.find("variance")), n);
  // what is not a height stays: the residual itself, the observation count, the obstacle evidence
  const cv::Mat& rate = *d.find("residual_outlier_rate");
  EXPECT_EQ(cv::countNonZero(rate >= 0.5f), n);
  EXPECT_EQ(nanCount(*d.find("observations")), 0);
  // the obstacle: lethal whatever its heights, elsewhere the level ground is free
  const int m = s.obstacle.vertexCount();
  EXPECT_EQ(cv::countNonZero(*d.find("obstacle") >= 0.5f), m);
  for (int v = 0; v < m; ++v) {
    const int r = s.obstacle.row0 + s.obstacle.rowOf(v) - w.row0, c = s.obstacle.col0 + s.obstacle.colOf(v) - w.col0;
    EXPECT_EQ(d.find("obstacle")->at<float>(r, c), 1.0f);
    EXPECT_EQ(d.find("traversability")->at<float>(r, c), 0.0f);
    EXPECT_EQ(d.find("traversability_confidence")->at<float>(r, c), 0.0f);
  }
  // the OccupancyGrid: contradicted cells unknown, the obstacle lethal, level ground free
  const sgd::TraversabilityCostTable table;
  const nav_msgs::OccupancyGrid og =
      table.toOccupancyGrid(d.grid, *d.find("traversability"), *d.find("observations"), 1, std_msgs::Header(),
                            *d.find("obstacle"), *d.find("traversability_confidence"), 0.0);
  int unknown = 0, lethal = 0, free = 0;
  for (int r = 0; r < w.rows; ++r) {
    for (int c = 0; c < w.cols; ++c) {
      const int8_t v = og.data[static_cast<size_t>(r * w.cols + c)];
      if (contradicted.at<uint8_t>(r, c)) EXPECT_EQ(v, sgd::TraversabilityCostTable::kUnknown);
      unknown += v == sgd::TraversabilityCostTable::kUnknown;
      lethal += v == sgd::TraversabilityCostTable::kLethal;
      free += v == sgd::TraversabilityCostTable::kFree;
    }
  }
  std::printf("[ sampler ] %d contradicted, %d unknown, %d lethal, %d free of %d\n", n, unknown, lethal, free,
              w.vertexCount());
  EXPECT_EQ(lethal, m);
  // unknown: exactly the contradicted cells (the slope of their neighbours uses the known ones)
  EXPECT_EQ(unknown, n);
  EXPECT_EQ(free, w.vertexCount() - n - m);
}

TEST(MapWindowSampler, DecimatedLayersAreTheFullOnesOnTheCoarserLattice) {
  const Scene s;
  sgd::ExtraLayerSources extra;
  extra.residual = &s.residual;
  const sgd::MapWindowSampler sampler;
  const sgd::GroundGrid w = sgd::MapWindowSampler::window(0.5, 13.0, 0.0, 10.0, 8.0);  // 21 x 17
  const sgd::DemLayers coarse = sampler.sample(s.map, w, 60, extra);
  const sgd::DemLayers full = sampler.sample(s.map, sgd::MapWindowSampler::window(0.5, 13.0, 0.0, 14.0, 12.0), 0, extra);
  EXPECT_EQ(coarse.grid.resolution_m, 1.5);  // stride 3: 7 x 6 <= 60 < 11 x 9 (stride 2)
  EXPECT_LE(coarse.grid.vertexCount(), 60);
  // it still covers the window
  EXPECT_LE(coarse.grid.xOfCol(0), w.xOfCol(0));
  EXPECT_GE(coarse.grid.xOfCol(coarse.grid.cols - 1), w.xOfCol(w.cols - 1));
  EXPECT_LE(coarse.grid.yOfRow(0), w.yOfRow(0));
  EXPECT_GE(coarse.grid.yOfRow(coarse.grid.rows - 1), w.yOfRow(w.rows - 1));
  ASSERT_EQ(coarse.layers.size(), full.layers.size());
  int compared = 0, contradicted = 0;
  for (size_t i = 0; i < coarse.layers.size(); ++i) {
    for (int r = 0; r < coarse.grid.rows; ++r) {
      for (int c = 0; c < coarse.grid.cols; ++c) {
        const int fr = static_cast<int>(std::lround(coarse.grid.yOfRow(r) / 0.5)) - full.grid.row0;
        const int fc = static_cast<int>(std::lround(coarse.grid.xOfCol(c) / 0.5)) - full.grid.col0;
        ASSERT_TRUE(fr >= 0 && fr < full.grid.rows && fc >= 0 && fc < full.grid.cols);
        const float a = coarse.layers[i].values.at<float>(r, c), b = full.layers[i].values.at<float>(fr, fc);
        if (std::isnan(b)) {
          EXPECT_TRUE(std::isnan(a)) << coarse.layers[i].name;
        } else {
          EXPECT_FLOAT_EQ(a, b) << coarse.layers[i].name;
        }
        ++compared;
        if (coarse.layers[i].name == "residual_outlier_rate" && a >= 0.5f) ++contradicted;
      }
    }
  }
  EXPECT_EQ(compared, static_cast<int>(coarse.layers.size()) * coarse.grid.vertexCount());
  EXPECT_GE(contradicted, 1);  // a coarse vertex falls into the square (x 12, y 0)
  // The cap holds after the alignment: stride 3 fits 7 x 6 = 42 <= 45 vertices, but the window
  // aligned to multiples of 3 has 8 x 7 = 56; stride 4 then (6 x 5 = 30).
  const sgd::DemLayers capped = sampler.sample(s.map, w, 45, extra);
  EXPECT_EQ(capped.grid.resolution_m, 2.0);
  EXPECT_EQ(capped.grid.vertexCount(), 30);
  for (int cap : {1, 4, 10, 30, 45, 60, 99, 100, 200, 357}) {
    const sgd::DemLayers d = sampler.sample(s.map, w, cap, extra);
    // a window across a multiple of every stride up to its size keeps 3 x 3 at least
    EXPECT_LE(d.grid.vertexCount(), std::max(cap, 9)) << cap;
    EXPECT_LE(d.grid.xOfCol(0), w.xOfCol(0)) << cap;
    EXPECT_GE(d.grid.xOfCol(d.grid.cols - 1), w.xOfCol(w.cols - 1)) << cap;
    EXPECT_LE(d.grid.yOfRow(0), w.yOfRow(0)) << cap;
    EXPECT_GE(d.grid.yOfRow(d.grid.rows - 1), w.yOfRow(w.rows - 1)) << cap;
  }
}
