// Every formula of METHOD.md sections 2 and 4 against numeric differentiation.
#include <gtest/gtest.h>

#include <Eigen/LU>

#include "stereo_ground_dem/PlaneGeometry.hpp"
#include "stereo_ground_dem/Se3.hpp"

using namespace stereo_ground_dem;

namespace {

Eigen::Matrix3d kittiK() {
  Eigen::Matrix3d k;
  k << 707.0912, 0, 601.8873, 0, 707.0912, 183.1104, 0, 0, 1;
  return k;
}

/// camera_T_ground of a camera at (x, y, h) looking along +x, pitched down and rolled a little.
Eigen::Isometry3d cameraPose(double x, double y, double h, double pitch, double roll, double yaw) {
  Eigen::Matrix3d base;  // ground (x fwd, y left, z up) -> optical (x right, y down, z fwd)
  base << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  const Eigen::Matrix3d r_gc =
      (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
          .toRotationMatrix() *
      base.transpose();
  Eigen::Isometry3d ground_T_camera = Eigen::Isometry3d::Identity();
  ground_T_camera.linear() = r_gc;
  ground_T_camera.translation() = Eigen::Vector3d(x, y, h);
  return ground_T_camera.inverse();
}

struct Scene {
  Eigen::Matrix3d k = kittiK();
  Eigen::Isometry3d cam = cameraPose(0.0, 0.1, 1.65, 0.03, -0.01, 0.02);
  std::array<Eigen::Vector2d, 3> xy{Eigen::Vector2d(10.0, 0.0), Eigen::Vector2d(10.5, 0.0),
                                    Eigen::Vector2d(10.5, 0.5)};
  Eigen::Vector3d z{0.02, -0.01, 0.03};
  Eigen::Isometry3d rig = Eigen::Isometry3d(Eigen::Translation3d(-0.537, 0.0, 0.0));
  Eigen::Isometry3d prev = cameraPose(-1.2, 0.05, 1.63, 0.025, 0.0, 0.01);  // previous frame

  Eigen::Vector3d plane(const Eigen::Isometry3d& pose, const Eigen::Vector3d& heights) const {
    Eigen::Vector3d m;
    EXPECT_TRUE(PlaneGeometry::cameraPlane(pose, PlaneGeometry::heightsToPlane(xy) * heights, &m));
    return m;
  }
  /// the reference pixel whose warp lands on target pixel xj: H^{-1} xj
  static Eigen::Vector2d backWarp(const Eigen::Matrix3d& h, const Eigen::Vector2d& xj) {
    const Eigen::Vector3d u = h.inverse() * xj.homogeneous();
    return u.hnormalized();
  }
};

}  // namespace

TEST(PlaneGeometry, PlaneThroughVerticesInCameraFrame) {
  const Scene s;
  const Eigen::Vector3d m = s.plane(s.cam, s.z);
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d xc = s.cam * Eigen::Vector3d(s.xy[i].x(), s.xy[i].y(), s.z[i]);
    EXPECT_NEAR(m.dot(xc), 1.0, 1e-12);
  }
}

TEST(PlaneGeometry, PlaneJacobianMatchesNumeric) {
  const Scene s;
  const Eigen::Matrix3d minv = PlaneGeometry::heightsToPlane(s.xy);
  const Eigen::Matrix3d analytic = PlaneGeometry::cameraPlaneJacobian(s.cam, minv * s.z) * minv;
  const double h = 1e-6;
  for (int i = 0; i < 3; ++i) {
    Eigen::Vector3d zp = s.z, zm = s.z;
    zp[i] += h;
    zm[i] -= h;
    const Eigen::Vector3d numeric = (s.plane(s.cam, zp) - s.plane(s.cam, zm)) / (2 * h);
    EXPECT_NEAR((numeric - analytic.col(i)).norm(), 0.0, 1e-8 * analytic.norm()) << "height " << i;
  }
}

TEST(PlaneGeometry, MotionJacobianMatchesNumeric) {
  const Scene s;
  const Eigen::Vector3d m = s.plane(s.cam, s.z);
  const auto analytic = PlaneGeometry::cameraPlaneMotionJacobian(m);
  const double h = 1e-6;
  for (int i = 0; i < 6; ++i) {
    Vector6d xi = Vector6d::Zero();
    xi[i] = h;
    const Eigen::Vector3d numeric =
        (s.plane(Se3::exp(xi) * s.cam, s.z) - s.plane(Se3::exp(-xi) * s.cam, s.z)) / (2 * h);
    EXPECT_NEAR((numeric - analytic.col(i)).norm(), 0.0, 1e-8) << "twist component " << i;
  }
}

TEST(PlaneGeometry, InverseCompositionIdentity) {
  // H(m) G(delta)^{-1} = H(m') with m' = m - (1 + m.t') delta / (1 + delta.t'), for a general
  // (rotated) second camera: t' = R^T t.
  const Scene s;
  const Eigen::Vector3d m = s.plane(s.cam, s.z);
  const Eigen::Isometry3d t_jr = s.prev * s.cam.inverse();
  const Eigen::Vector3d tp = t_jr.linear().transpose() * t_jr.translation();
  const Eigen::Vector3d delta(0.003, -0.02, 0.01);
  const Eigen::Matrix3d g = s.k * (Eigen::Matrix3d::Identity() + tp * delta.transpose()) * s.k.inverse();
  Eigen::Matrix3d lhs = PlaneGeometry::homography(s.k, t_jr, m) * g.inverse();
  Eigen::Matrix3d rhs = PlaneGeometry::homography(s.k, t_jr, PlaneGeometry::composeInverse(m, delta, tp));
  lhs /= lhs(2, 2);
  rhs /= rhs(2, 2);
  EXPECT_NEAR((lhs - rhs).norm(), 0.0, 1e-9 * rhs.norm());
  // ... and the homography really maps the plane's pixels: a point on the plane projects by H.
  const Eigen::Vector3d xg(10.3, 0.1, s.z.mean());
  const Eigen::Matrix3d minv = PlaneGeometry::heightsToPlane(s.xy);
  Eigen::Vector3d on_plane = xg;
  on_plane.z() = (minv * s.z).dot(Eigen::Vector3d(xg.x(), xg.y(), 1.0));
  const Eigen::Vector2d u0 = (s.k * (s.cam * on_plane)).hnormalized();
  const Eigen::Vector2d uj = (s.k * (s.prev * on_plane)).hnormalized();
  const Eigen::Vector2d mapped = (PlaneGeometry::homography(s.k, t_jr, m) * u0.homogeneous()).hnormalized();
  EXPECT_NEAR((mapped - uj).norm(), 0.0, 1e-9);
}

// The inverse compositional Jacobians describe how the reference pixel that corresponds to a FIXED
// pixel of the other image moves when a parameter changes (heights, motion). Check each block by
// moving the parameter and re-solving the correspondence exactly.
class IcJacobian : public ::testing::Test {
 protected:
  Scene s;
  Eigen::Vector3d m;
  Eigen::Vector2d u;  // a reference pixel inside the triangle
  Eigen::Vector3d xhat;
  void SetUp() override {
    m = s.plane(s.cam, s.z);
    const Eigen::Vector3d centroid(10.33, 0.17, s.z.mean());
    u = (s.k * (s.cam * centroid)).hnormalized();
    xhat = s.k.inverse() * u.homogeneous();
  }
  Eigen::Matrix<double, 2, 3> numericHeights(const Eigen::Isometry3d& t_jr) const {
    const Eigen::Vector2d xj = (PlaneGeometry::homography(s.k, t_jr, m) * u.homogeneous()).hnormalized();
    Eigen::Matrix<double, 2, 3> d;
    const double h = 1e-6;
    for (int i = 0; i < 3; ++i) {
      Eigen::Vector3d zp = s.z, zm = s.z;
      zp[i] += h;
      zm[i] -= h;
      d.col(i) = (Scene::backWarp(PlaneGeometry::homography(s.k, t_jr, s.plane(s.cam, zp)), xj) -
                  Scene::backWarp(PlaneGeometry::homography(s.k, t_jr, s.plane(s.cam, zm)), xj)) /
                 (2 * h);
    }
    return d;
  }
  Eigen::Matrix<double, 2, 3> analyticHeights(const Eigen::Isometry3d& t_jr) const {
    const Eigen::Vector3d tp = t_jr.linear().transpose() * t_jr.translation();
    const Eigen::Matrix3d minv = PlaneGeometry::heightsToPlane(s.xy);
    const Eigen::Matrix3d a = PlaneGeometry::deltaScale(m, tp) *
                              PlaneGeometry::cameraPlaneJacobian(s.cam, minv * s.z) * minv;
    return PlaneGeometry::planeIncrementDisplacement(s.k, xhat, tp) * a;
  }
};

TEST_F(IcJacobian, HeightsStereoPair) {
  const auto num = numericHeights(s.rig);
  const auto ana = analyticHeights(s.rig);
  EXPECT_GT(ana.norm(), 1.0);  // pixels per metre: a real signal
  EXPECT_NEAR((num - ana).norm(), 0.0, 1e-5 * ana.norm()) << "numeric\n" << num << "\nanalytic\n" << ana;
}

TEST_F(IcJacobian, HeightsTemporalPair) {
  const Eigen::Isometry3d t_jr = s.prev * s.cam.inverse();
  const auto num = numericHeights(t_jr);
  const auto ana = analyticHeights(t_jr);
  EXPECT_GT(ana.norm(), 1.0);
  EXPECT_NEAR((num - ana).norm(), 0.0, 1e-5 * ana.norm()) << "numeric\n" << num << "\nanalytic\n" << ana;
}

TEST_F(IcJacobian, MotionStereoPairActsThroughThePlane) {
  // The right camera moves with the reference: a twist changes the plane seen by the rig.
  const Eigen::Vector2d xj = (PlaneGeometry::homography(s.k, s.rig, m) * u.homogeneous()).hnormalized();
  const Eigen::Vector3d tp = s.rig.linear().transpose() * s.rig.translation();
  const Eigen::Matrix<double, 2, 6> ana =
      PlaneGeometry::planeIncrementDisplacement(s.k, xhat, tp) *
      (PlaneGeometry::deltaScale(m, tp) * PlaneGeometry::cameraPlaneMotionJacobian(m));
  const double h = 1e-7;
  for (int i = 0; i < 6; ++i) {
    Vector6d xi = Vector6d::Zero();
    xi[i] = h;
    auto back = [&](const Vector6d& x) {
      const Eigen::Vector3d mp = s.plane(Se3::exp(x) * s.cam, s.z);
      return Scene::backWarp(PlaneGeometry::homography(s.k, s.rig, mp), xj);
    };
    const Eigen::Vector2d num = (back(xi) - back(-xi)) / (2 * h);
    EXPECT_NEAR((num - ana.col(i)).norm(), 0.0, 1e-5 * ana.norm() + 1e-6) << "twist " << i;
  }
}

TEST_F(IcJacobian, MotionTemporalPairMovesOnlyTheReference) {
  // The previous camera is fixed in the ground frame; the reference pose becomes exp(xi) T.
  const Eigen::Isometry3d t_jr = s.prev * s.cam.inverse();
  const Eigen::Vector2d xj = (PlaneGeometry::homography(s.k, t_jr, m) * u.homogeneous()).hnormalized();
  const Eigen::Matrix<double, 2, 6> ana = PlaneGeometry::worldMotionDisplacement(s.k, xhat, m.dot(xhat));
  const double h = 1e-7;
  for (int i = 0; i < 6; ++i) {
    Vector6d xi = Vector6d::Zero();
    xi[i] = h;
    auto back = [&](const Vector6d& x) {
      const Eigen::Isometry3d cam = Se3::exp(x) * s.cam;
      const Eigen::Vector3d mp = s.plane(cam, s.z);
      return Scene::backWarp(PlaneGeometry::homography(s.k, s.prev * cam.inverse(), mp), xj);
    };
    const Eigen::Vector2d num = (back(xi) - back(-xi)) / (2 * h);
    EXPECT_NEAR((num - ana.col(i)).norm(), 0.0, 1e-5 * ana.col(i).norm() + 1e-4) << "twist " << i << "\n"
                                                                                 << num.transpose() << "\n"
                                                                                 << ana.col(i).transpose();
  }
}

TEST(PlaneGeometry, GradientShortcutEqualsDisplacementForm) {
  // The hot loop uses c = (d pi)^T grad I0 and (c . t') xhat: the same row as grad I0 * dG/ddelta.
  const Eigen::Matrix3d k = kittiK();
  const Eigen::Vector3d xhat = k.inverse() * Eigen::Vector3d(800.0, 250.0, 1.0);
  const Eigen::Vector2d grad(12.5, -3.25);
  const Eigen::Vector3d tp(0.3, -0.1, 1.2);
  const Eigen::Vector3d c(grad.x() * k(0, 0), grad.y() * k(1, 1),
                          -(grad.x() * k(0, 0) * xhat.x() + grad.y() * k(1, 1) * xhat.y()));
  const Eigen::RowVector3d shortcut = c.dot(tp) * xhat.transpose();
  const Eigen::RowVector3d full = grad.transpose() * PlaneGeometry::planeIncrementDisplacement(k, xhat, tp);
  EXPECT_NEAR((shortcut - full).norm(), 0.0, 1e-9 * full.norm());
  // and the world-motion row (rho c, xhat x c)
  const double rho = 0.08;
  Vector6d jm;
  jm.head<3>() = rho * c;
  jm.tail<3>() = xhat.cross(c);
  const Vector6d full_m = (grad.transpose() * PlaneGeometry::worldMotionDisplacement(k, xhat, rho)).transpose();
  EXPECT_NEAR((jm - full_m).norm(), 0.0, 1e-9 * full_m.norm());
}
