#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

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

TEST(GroundGrid, CoveringRefusesExtentsBeyondIntRange) {
  const auto message = [](double x0, double x1, double y0, double y1, double res, int align) -> std::string {
    try {
      GroundGrid::covering(x0, x1, y0, y1, res, align);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "<accepted>";
  };
  // 1e12 m at 0.5 m would be 2e12 columns: int overflow before the check existed
  EXPECT_EQ(message(0.0, 1e12, -5.0, 5.0, 0.5, 1),
            "GroundGrid::covering: extent x [0, 1e+12] y [-5, 5] m at 0.5 m (align 1) is out of range: lattice "
            "indices must be within +-268435456 and the grid at most 268435456 vertices");
  EXPECT_NE(message(-1e9, -1e9 + 10, 0, 10, 0.5, 1).find("is out of range"), std::string::npos);      // far away
  EXPECT_NE(message(0, 100000, 0, 100000, 0.5, 1).find("is out of range"), std::string::npos);        // 4e10 vertices
  EXPECT_NE(message(0, 10, 0, 10, 1e-12, 1).find("is out of range"), std::string::npos);              // tiny cells
  EXPECT_NE(message(-INFINITY, 10, 0, 10, 0.5, 1).find("is out of range"), std::string::npos);
  EXPECT_EQ(message(NAN, 10, 0, 10, 0.5, 1), "GroundGrid::covering: invalid extent, resolution or alignment");
  EXPECT_EQ(message(0, 10, 0, 10, NAN, 1), "GroundGrid::covering: invalid extent, resolution or alignment");
  EXPECT_EQ(message(0, 10, 0, 10, 0.5, 0), "GroundGrid::covering: invalid extent, resolution or alignment");
  // the largest accepted grids still index inside int
  const GroundGrid big = GroundGrid::covering(0.0, 8000.0, 0.0, 8000.0, 0.5, 8);
  EXPECT_EQ(big.cols, 16001);
  EXPECT_EQ(big.vertexCount(), 16001 * 16001);
  const GroundGrid far = GroundGrid::covering(1e8, 1e8 + 10, 0, 10, 0.5, 8);
  EXPECT_EQ(far.col0, 200000000);
  EXPECT_EQ(far.cols, 25);
}

// A point counts for the four vertices of its cell; on the grid's last row or column, for the two
// (or one) that exist; outside, for none.
TEST(GroundGrid, CellVerticesOfAPoint) {
  const GroundGrid g = GroundGrid::covering(0.0, 2.0, 0.0, 1.0, 0.5);  // 5 x 3 vertices
  std::vector<int> v;
  const auto collect = [&](double x, double y) {
    v.clear();
    g.forCellVertices(x, y, [&](int i) { v.push_back(i); });
    std::sort(v.begin(), v.end());
    return v;
  };
  EXPECT_EQ(collect(0.7, 0.2), (std::vector<int>{g.index(0, 1), g.index(0, 2), g.index(1, 1), g.index(1, 2)}));
  EXPECT_EQ(collect(2.0, 0.2), (std::vector<int>{g.index(0, 4), g.index(1, 4)}));
  EXPECT_EQ(collect(2.0, 1.0), (std::vector<int>{g.index(2, 4)}));
  EXPECT_TRUE(collect(2.1, 0.2).empty());
  EXPECT_TRUE(collect(0.5, -0.01).empty());
  EXPECT_TRUE(collect(std::numeric_limits<double>::quiet_NaN(), 0.2).empty());
}
