#include <gtest/gtest.h>

#include <random>

#include "stereo_ground_dem/GroundGrid.hpp"

using stereo_ground_dem::GroundGrid;

TEST(GroundGrid, IndexConventions) {
  const GroundGrid g = GroundGrid::covering(4.0, 40.0, -20.0, 20.0, 0.5, 8);
  EXPECT_EQ(g.col0 % 8, 0);
  EXPECT_EQ(g.row0 % 8, 0);
  EXPECT_LE(g.x0(), 4.0);
  EXPECT_GE(g.xOfCol(g.cols - 1), 40.0);
  EXPECT_LE(g.y0(), -20.0);
  EXPECT_GE(g.yOfRow(g.rows - 1), 20.0);
  // row runs along y, column along x
  const int v = g.index(3, 5);
  EXPECT_DOUBLE_EQ(g.position(v).x(), g.x0() + 5 * 0.5);
  EXPECT_DOUBLE_EQ(g.position(v).y(), g.y0() + 3 * 0.5);
  // the two triangles of a square share the diagonal and cover the square once
  const auto a = g.triangle(0), b = g.triangle(1);
  EXPECT_EQ(a[0], g.index(0, 0));
  EXPECT_EQ(a[1], g.index(0, 1));
  EXPECT_EQ(a[2], g.index(1, 1));
  EXPECT_EQ(b[0], g.index(0, 0));
  EXPECT_EQ(b[1], g.index(1, 1));
  EXPECT_EQ(b[2], g.index(1, 0));
}

TEST(GroundGrid, TrianglesAreCounterClockwiseSeenFromAbove) {
  const GroundGrid g = GroundGrid::covering(0, 3, 0, 2, 1.0);
  for (int t = 0; t < g.triangleCount(); ++t) {
    const auto tri = g.triangle(t);
    const Eigen::Vector2d p0 = g.position(tri[0]), p1 = g.position(tri[1]), p2 = g.position(tri[2]);
    const double cross = (p1 - p0).x() * (p2 - p0).y() - (p1 - p0).y() * (p2 - p0).x();
    EXPECT_NEAR(cross, 1.0, 1e-12) << "triangle " << t;  // twice the area 1/2: positive orientation
  }
}

TEST(GroundGrid, RefinementIsExact) {
  // A random coarse mesh, prolongated to the fine grid, gives the same surface everywhere.
  const GroundGrid fine = GroundGrid::covering(-3.0, 13.0, -7.0, 5.0, 0.5, 8);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  for (int factor : {2, 4, 8}) {
    const GroundGrid coarse = fine.coarsened(factor);
    Eigen::VectorXd zc(coarse.vertexCount());
    for (int i = 0; i < zc.size(); ++i) zc[i] = uni(rng);
    const Eigen::VectorXd zf = fine.prolongationFrom(coarse) * zc;
    // coarse vertices keep their heights
    for (int r = 0; r < coarse.rows; ++r)
      for (int c = 0; c < coarse.cols; ++c)
        EXPECT_DOUBLE_EQ(zf[fine.index(r * factor, c * factor)], zc[coarse.index(r, c)]);
    // and the piecewise-linear surfaces agree at random points
    for (int k = 0; k < 500; ++k) {
      const double x = fine.x0() + (0.5 + 0.5 * uni(rng)) * (fine.cols - 1) * fine.resolution_m;
      const double y = fine.y0() + (0.5 + 0.5 * uni(rng)) * (fine.rows - 1) * fine.resolution_m;
      EXPECT_NEAR(fine.interpolate(zf, x, y), coarse.interpolate(zc, x, y), 1e-12)
          << "factor " << factor << " at " << x << ", " << y;
    }
    // rows of P sum to one (interpolation reproduces constants)
    const Eigen::VectorXd ones = fine.prolongationFrom(coarse) * Eigen::VectorXd::Ones(zc.size());
    EXPECT_NEAR((ones.array() - 1.0).abs().maxCoeff(), 0.0, 1e-12);
  }
}

TEST(GroundGrid, InterpolationReproducesPlanes) {
  const GroundGrid g = GroundGrid::covering(0, 10, -5, 5, 0.5);
  Eigen::VectorXd z(g.vertexCount());
  for (int v = 0; v < g.vertexCount(); ++v) z[v] = 0.1 * g.position(v).x() - 0.3 * g.position(v).y() + 2;
  EXPECT_NEAR(g.interpolate(z, 3.14, -1.23), 0.1 * 3.14 + 0.3 * 1.23 + 2, 1e-12);
  EXPECT_TRUE(std::isnan(g.interpolate(z, 11.0, 0.0)));
}

TEST(GroundGrid, RejectsNonNestedGrids) {
  const GroundGrid g = GroundGrid::covering(0.25, 10, -5, 5, 0.5, 1);
  GroundGrid odd = g;
  odd.col0 = 1;
  EXPECT_FALSE(odd.isCoarsenableBy(2));
  EXPECT_THROW(odd.coarsened(2), std::invalid_argument);
}
