#include <gtest/gtest.h>

#include <cmath>

#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/SurfaceIncidence.hpp"

using stereo_ground_dem::GroundGrid;
using stereo_ground_dem::SurfaceIncidence;

namespace {

GroundGrid grid() { return GroundGrid::covering(4.0, 40.0, -10.0, 10.0, 0.5); }

}  // namespace

// Level ground is seen as level ground: ratio 1 everywhere (to rounding).
TEST(SurfaceIncidence, LevelGroundIsOne) {
  const GroundGrid g = grid();
  const Eigen::VectorXd z = Eigen::VectorXd::Constant(g.vertexCount(), -0.2);
  const Eigen::VectorXd r = SurfaceIncidence::ratios(g, z, Eigen::Vector3d(0.0, 0.0, 1.65));
  for (int v = 0; v < g.vertexCount(); ++v) EXPECT_NEAR(r[v], 1.0, 1e-12) << v;
}

// A plane z = a x seen from height h: the ratio is -(n . d) / -d_z with n = (-a, 0, 1) / |.| and
// d = (x, 0, a x - h) / |.|, checked at three vertices on the camera's track.
TEST(SurfaceIncidence, PlaneMatchesTheClosedForm) {
  const GroundGrid g = grid();
  const double a = -0.05, h = 1.65;  // falling away from the camera at 5 %
  Eigen::VectorXd z(g.vertexCount());
  for (int v = 0; v < g.vertexCount(); ++v) z[v] = a * g.position(v).x();
  const Eigen::VectorXd r = SurfaceIncidence::ratios(g, z, Eigen::Vector3d(0.0, 0.0, h));
  for (const double x : {10.0, 20.0, 30.0}) {
    const int c = static_cast<int>(std::lround(x / 0.5)) - g.col0;
    const int row = -g.row0;  // y = 0
    const int v = g.index(row, c);
    const Eigen::Vector3d d = Eigen::Vector3d(x, 0.0, a * x - h).normalized();
    const Eigen::Vector3d n = Eigen::Vector3d(-a, 0.0, 1.0).normalized();
    EXPECT_NEAR(r[v], -n.dot(d) / -d.z(), 1e-12) << x;
  }
  // Falling away at 5 % from 1.65 m: at 30 m the ray falls at (1.65 + 1.5) / 30 = 10.5 %, so the
  // surface is seen at about half of level ground's incidence (measured 0.52).
  const int v30 = g.index(-g.row0, 60 - g.col0);
  EXPECT_NEAR(r[v30], 0.52, 0.01);
}

// The mesh draped from a 0.75 m rail at 12 m down to the ground seen behind it (the line of sight
// over the rail's top) runs along the rays: ratio ~0; a face towards the camera is > 1; back-facing
// (below the ray) is negative.
TEST(SurfaceIncidence, DrapedOverHiddenGroundIsNearZero) {
  const GroundGrid g = grid();
  const double h = 1.65, x_rail = 12.0, top = 0.75;
  const double ray = (h - top) / x_rail;  // the line of sight over the rail falls at 7.5 %
  const double x_seen = h / ray;          // and meets the ground at 22 m
  Eigen::VectorXd z(g.vertexCount());
  for (int v = 0; v < g.vertexCount(); ++v) {
    const double x = g.position(v).x();
    z[v] = x < x_rail - 1.0 ? 0.0 : x <= x_rail ? top * (x - (x_rail - 1.0)) : x < x_seen ? h - ray * x : 0.0;
  }
  const Eigen::VectorXd r = SurfaceIncidence::ratios(g, z, Eigen::Vector3d(0.0, 0.0, h));
  const int row = -g.row0;
  auto at = [&](double x) { return r[g.index(row, static_cast<int>(std::lround(x / 0.5)) - g.col0)]; };
  EXPECT_NEAR(at(16.0), 0.0, 1e-9);   // along the line of sight
  EXPECT_GT(at(11.5), 5.0);           // the rail's face, turned to the camera
  EXPECT_NEAR(at(6.0), 1.0, 1e-12);   // level ground in front
  // steeper than the ray: the camera sees the surface's back
  Eigen::VectorXd zb = z;
  for (int v = 0; v < g.vertexCount(); ++v) {
    const double x = g.position(v).x();
    if (x > x_rail && x < x_seen) zb[v] = top - 2.0 * ray * (x - x_rail);
  }
  const Eigen::VectorXd rb = SurfaceIncidence::ratios(g, zb, Eigen::Vector3d(0.0, 0.0, h));
  EXPECT_LT(rb[g.index(row, 32 - g.col0)], 0.0);
}

TEST(SurfaceIncidence, HolesAndMismatchedSizes) {
  const GroundGrid g = grid();
  Eigen::VectorXd z = Eigen::VectorXd::Zero(g.vertexCount());
  const int v = g.index(5, 5);
  z[v] = std::nan("");
  const Eigen::VectorXd r = SurfaceIncidence::ratios(g, z, Eigen::Vector3d(0.0, 0.0, 1.65));
  EXPECT_TRUE(std::isnan(r[v]));
  EXPECT_NEAR(r[v + 1], 1.0, 1e-12);  // one-sided difference beside the hole
  EXPECT_THROW(SurfaceIncidence::ratios(g, Eigen::VectorXd::Zero(3), Eigen::Vector3d(0.0, 0.0, 1.65)),
               std::invalid_argument);
}
