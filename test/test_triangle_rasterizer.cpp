#include <gtest/gtest.h>

#include <random>

#include "stereo_ground_dem/TriangleRasterizer.hpp"

using stereo_ground_dem::TriangleRasterizer;

TEST(TriangleRasterizer, MeshCoverageIsWatertight) {
  // A jittered grid of vertices triangulated like the ground mesh: every pixel centre strictly
  // inside the mesh's outline is covered, and the pixel count equals the outline's area.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> jitter(-3.0, 3.0);
  const int n = 9;
  std::vector<double> pu(n * n), pv(n * n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      const bool border = r == 0 || c == 0 || r == n - 1 || c == n - 1;
      pu[r * n + c] = 20.0 + 20.0 * c + (border ? 0.0 : jitter(rng));
      pv[r * n + c] = 10.0 + 20.0 * r + (border ? 0.0 : jitter(rng));
    }
  TriangleRasterizer ras;
  ras.reset(220, 200, 1);
  int id = 0, drawn = 0;
  for (int r = 0; r + 1 < n; ++r)
    for (int c = 0; c + 1 < n; ++c) {
      const int a = r * n + c, b = a + 1, d = a + n + 1, e = a + n;
      for (auto tri : {std::array<int, 3>{a, b, d}, std::array<int, 3>{a, d, e}}) {
        TriangleRasterizer::Triangle t{};
        for (int k = 0; k < 3; ++k) {
          t.u[k] = pu[tri[k]] + 0.37;  // off the pixel lattice
          t.v[k] = pv[tri[k]] + 0.61;
        }
        t.rho_a = 0;
        t.rho_b = 0;
        t.rho_c = 0.1;
        t.id = id++;
        drawn += ras.draw(t);
      }
    }
  int covered = 0;
  for (int v = 0; v < 200; ++v)
    for (int u = 0; u < 220; ++u) covered += ras.labels().at<int>(v, u) >= 0;
  // outline: [20.37, 180.37] x [10.61, 170.61] -> pixel centres 21..180 x 11..170 = 160 x 160
  EXPECT_EQ(covered, 160 * 160);
  EXPECT_EQ(drawn, covered);  // equal depths: no pixel is won twice
  EXPECT_EQ(ras.rowBegin(11), 21);
  EXPECT_EQ(ras.rowEnd(11), 180);
  EXPECT_GT(ras.rowBegin(10), ras.rowEnd(10));  // empty row
}

TEST(TriangleRasterizer, NearestSurfaceWins) {
  TriangleRasterizer ras;
  ras.reset(100, 100, 2);
  TriangleRasterizer::Triangle far{{10, 90, 10}, {10, 10, 90}, 0.0, 0.0, 0.05, 0};   // 20 m
  TriangleRasterizer::Triangle near{{30, 60, 30}, {30, 30, 60}, 0.0, 0.0, 0.2, 1};   // 5 m
  ras.draw(far);
  ras.draw(near);
  EXPECT_EQ(ras.labels().at<int>(35, 35), 1);
  EXPECT_FLOAT_EQ(ras.inverseDepth().at<float>(35, 35), 0.2f);
  EXPECT_EQ(ras.labels().at<int>(15, 15), 0);
  // drawing order does not matter
  ras.reset(100, 100, 2);
  ras.draw(near);
  ras.draw(far);
  EXPECT_EQ(ras.labels().at<int>(35, 35), 1);
  // the margin is never covered
  EXPECT_EQ(ras.labels().at<int>(1, 50), -1);
  // inverse depth follows the plane a u + b v + c
  TriangleRasterizer::Triangle slope{{10, 90, 10}, {10, 10, 90}, 0.001, 0.002, 0.01, 2};
  ras.reset(100, 100, 1);
  ras.draw(slope);
  EXPECT_NEAR(ras.inverseDepth().at<float>(20, 30), 0.001 * 30 + 0.002 * 20 + 0.01, 1e-7);
}
