#include <gtest/gtest.h>

#include <cmath>

#include "stereo_ground_dem/GroundAttitudeEstimator.hpp"
#include "stereo_ground_dem/StereoEstimator.hpp"

namespace sgd = stereo_ground_dem;

namespace {

/// A camera (x right, y down, z forward) whose body frame (forward, left, up) sits on the plane
/// z = a x + b y + c at `height_m` above the plane point below (x, y), heading `yaw` within the
/// plane, then pitched and rolled relative to it (Z-Y-X Euler, REP 103 signs).
Eigen::Isometry3d cameraOnPlane(const Eigen::Vector3d& abc, double x, double y, double yaw, double height_m,
                                double pitch, double roll) {
  const Eigen::Vector3d n = Eigen::Vector3d(-abc.x(), -abc.y(), 1.0).normalized();
  const Eigen::Vector3d heading(std::cos(yaw), std::sin(yaw), 0.0);
  const Eigen::Vector3d f0 = (heading - heading.dot(n) * n).normalized();
  Eigen::Matrix3d plane;
  plane << f0, n.cross(f0), n;
  const Eigen::Matrix3d body = plane * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                               Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()).toRotationMatrix();
  Eigen::Isometry3d g_t_c = Eigen::Isometry3d::Identity();
  g_t_c.linear() << -body.col(1), -body.col(2), body.col(0);  // camera x = -left, y = -up, z = forward
  g_t_c.translation() = Eigen::Vector3d(x, y, abc.x() * x + abc.y() * y + abc.z()) + height_m * n;
  return g_t_c;
}

}  // namespace

TEST(GroundAttitude, HeightPitchRollRelativeToATiltedPlane) {
  const Eigen::Vector3d abc(0.12, -0.07, 0.4);  // 6.8 % and 4 % grades
  for (const double yaw : {0.0, 0.7, -2.5}) {
    const Eigen::Isometry3d c = cameraOnPlane(abc, 3.0, -1.0, yaw, 1.65, 0.05, -0.03);
    const sgd::GroundAttitudeEstimate e = sgd::GroundAttitudeEstimator::relativeToPlane(abc, c);
    ASSERT_TRUE(e.valid);
    EXPECT_NEAR(e.height_m, 1.65, 1e-12) << yaw;
    EXPECT_NEAR(e.pitch_rad, 0.05, 1e-12) << yaw;
    EXPECT_NEAR(e.roll_rad, -0.03, 1e-12) << yaw;
    EXPECT_NEAR(e.slope_rad, std::acos(1.0 / std::sqrt(1.0 + 0.12 * 0.12 + 0.07 * 0.07)), 1e-12);
  }
  // A level camera on level ground, looking down 3 deg with its left side 2 deg up.
  const Eigen::Isometry3d level = cameraOnPlane(Eigen::Vector3d::Zero(), 0, 0, 0.3, 1.2, 0.0524, 0.0349);
  const sgd::GroundAttitudeEstimate e = sgd::GroundAttitudeEstimator::relativeToPlane(Eigen::Vector3d::Zero(), level);
  EXPECT_NEAR(e.height_m, 1.2, 1e-12);
  EXPECT_NEAR(level.translation().z(), 1.2, 1e-12);
  EXPECT_NEAR(e.pitch_rad, 0.0524, 1e-12);
  EXPECT_NEAR(e.roll_rad, 0.0349, 1e-12);
  EXPECT_LT((level.linear() * Eigen::Vector3d::UnitZ()).z(), -0.05) << "pitch > 0 looks down";
}

TEST(GroundAttitude, PlaneFromTheMapIgnoresCurbsObstaclesAndFarGround) {
  const Eigen::Vector3d abc(-0.05, 0.03, 0.2);
  sgd::ElevationMap map;
  const sgd::GroundGrid w = sgd::GroundGrid::covering(-30.0, 30.0, -30.0, 30.0, 0.5);
  Eigen::VectorXd z(w.vertexCount());
  std::vector<uint8_t> update(static_cast<size_t>(w.vertexCount()), 1), hit(update.size(), 0), ground(update.size(), 1);
  for (int v = 0; v < w.vertexCount(); ++v) {
    const Eigen::Vector2d p = w.position(v);
    z[v] = abc.x() * p.x() + abc.y() * p.y() + abc.z();
    if (p.y() > 3.0 && p.y() < 3.6) z[v] += 0.2;  // a curb 20 cm high on the left (the row y = 3.5)
    // Something flagged as an obstacle only 10 cm up: within outlier_m, so only the obstacle
    // layer keeps it out of the fit (it would bias the plane by ~2 mm).
    if (p.x() > 4.0 && p.x() < 6.0 && p.y() < -2.0 && p.y() > -4.0) {
      z[v] += 0.1;
      hit[static_cast<size_t>(v)] = 1;
      ground[static_cast<size_t>(v)] = 0;
    }
    if (std::hypot(p.x(), p.y()) > 9.0) z[v] += 3.0;  // beyond the radius: a hill that must not count
  }
  map.fuse(w, z, Eigen::VectorXd::Zero(w.vertexCount()), Eigen::VectorXd::Constant(w.vertexCount(), 100.0), update, 0);
  map.updateObstacles(w, hit, ground, Eigen::VectorXd::Zero(w.vertexCount()), 0);  // two frames' evidence
  map.updateObstacles(w, hit, ground, Eigen::VectorXd::Zero(w.vertexCount()), 1);
  const Eigen::Isometry3d c = cameraOnPlane(abc, 0.2, -0.1, 0.4, 1.5, 0.08, 0.02);
  const sgd::GroundAttitudeEstimate e = sgd::GroundAttitudeEstimator().estimate(map, c);
  ASSERT_TRUE(e.valid);
  EXPECT_NEAR(e.height_m, 1.5, 1e-4);
  EXPECT_NEAR(e.pitch_rad, 0.08, 1e-5);
  EXPECT_NEAR(e.roll_rad, 0.02, 1e-5);
  EXPECT_LT(e.rms_m, 1e-5);
  // The 8 m disc holds ~804 vertices (pi 8^2 / 0.25); the curb's row and the obstacle are out.
  EXPECT_GT(e.vertices, 700);
  EXPECT_LT(e.vertices, 790);

  // Only the ground 4-8 m ahead known (the first frame): too little of the disc, no estimate.
  sgd::ElevationMap ahead;
  Eigen::VectorXd z_ahead = z;
  std::vector<uint8_t> ahead_only(update.size(), 0);
  for (int v = 0; v < w.vertexCount(); ++v) {
    const Eigen::Vector2d p = w.position(v);
    ahead_only[static_cast<size_t>(v)] = p.x() > 4.0 && p.x() < 8.0;
  }
  ahead.fuse(w, z_ahead, Eigen::VectorXd::Zero(w.vertexCount()), Eigen::VectorXd::Constant(w.vertexCount(), 100.0),
             ahead_only, 0);
  EXPECT_FALSE(sgd::GroundAttitudeEstimator().estimate(ahead, cameraOnPlane(abc, 0.0, 0.0, 0.0, 1.5, 0.0, 0.0)).valid);

  // As exact far from the map's origin (the fit is centred on the nadir).
  {
    sgd::ElevationMap far_map;
    const sgd::GroundGrid wf = sgd::GroundGrid::covering(4990.0, 5010.0, -3010.0, -2990.0, 0.5);
    Eigen::VectorXd zf(wf.vertexCount());
    for (int v = 0; v < wf.vertexCount(); ++v) {
      zf[v] = abc.x() * wf.position(v).x() + abc.y() * wf.position(v).y() + abc.z();
    }
    far_map.fuse(wf, zf, Eigen::VectorXd::Zero(wf.vertexCount()), Eigen::VectorXd::Constant(wf.vertexCount(), 100.0),
                 std::vector<uint8_t>(static_cast<size_t>(wf.vertexCount()), 1), 0);
    const sgd::GroundAttitudeEstimate f =
        sgd::GroundAttitudeEstimator().estimate(far_map, cameraOnPlane(abc, 5000.0, -3000.0, 1.0, 1.5, 0.08, 0.02));
    ASSERT_TRUE(f.valid) << "5.8 km from the origin";
    EXPECT_NEAR(f.height_m, 1.5, 1e-4);
    EXPECT_NEAR(f.pitch_rad, 0.08, 1e-5);
    EXPECT_NEAR(f.roll_rad, 0.02, 1e-5);
  }

  // Where the map knows nothing: no estimate, NaN values.
  const Eigen::Isometry3d away = cameraOnPlane(abc, 100.0, 100.0, 0.0, 1.5, 0.0, 0.0);
  const sgd::GroundAttitudeEstimate none = sgd::GroundAttitudeEstimator().estimate(map, away);
  EXPECT_FALSE(none.valid);
  EXPECT_TRUE(std::isnan(none.height_m) && std::isnan(none.pitch_rad) && std::isnan(none.roll_rad));
  EXPECT_EQ(none.vertices, 0);
}

TEST(GroundAttitude, OptionsAreValidated) {
  sgd::GroundAttitudeOptions o;
  o.radius_m = 0.0;
  EXPECT_THROW(sgd::GroundAttitudeEstimator{o}, std::invalid_argument);
  o = sgd::GroundAttitudeOptions();
  o.min_coverage = 0.0;
  EXPECT_THROW(sgd::GroundAttitudeEstimator{o}, std::invalid_argument);
  o = sgd::GroundAttitudeOptions();
  o.outlier_m = std::nan("");
  EXPECT_THROW(sgd::GroundAttitudeEstimator{o}, std::invalid_argument);
  o = sgd::GroundAttitudeOptions();
  o.radius_m = 500.0;
  EXPECT_THROW(sgd::GroundAttitudeEstimator{o}, std::invalid_argument);
  o = sgd::GroundAttitudeOptions();
  o.mount_min_estimates = o.mount_window_frames + 1;
  EXPECT_THROW(sgd::GroundAttitudeEstimator{o}, std::invalid_argument);
}

// The nominal mount parameters (nominal_height_m, nominal_pitch_down_rad, nominal_roll_rad) read
// back as the attitude above level ground: one sign convention for both.
TEST(GroundAttitude, NominalMountReadsBack) {
  const Eigen::Isometry3d nominal_pose = sgd::StereoEstimator::nominalCameraPose(1.65, 0.03, -0.01).inverse();
  const sgd::GroundAttitudeEstimate nominal = sgd::GroundAttitudeEstimator::relativeToPlane(Eigen::Vector3d::Zero(), nominal_pose);
  EXPECT_NEAR(nominal.height_m, 1.65, 1e-12);
  EXPECT_NEAR(nominal.pitch_rad, 0.03, 1e-12);
  EXPECT_NEAR(nominal.roll_rad, -0.01, 1e-12);
}

// nominalMount inverts nominalCameraPose (the node reads the mount from the base_footprint ->
// camera transform with it): heights, pitches down and up, rolls both ways; a yaw of the camera on
// its base and a shift along the ground do not change the mount.
TEST(GroundAttitude, NominalMountInvertsTheNominalPose) {
  for (double h : {0.3, 0.8, 1.65, 3.0}) {
    for (double p : {-0.4, 0.0, 0.15, 0.6}) {
      for (double r : {-0.2, 0.0, 0.05}) {
        Eigen::Isometry3d ground_T_camera = sgd::StereoEstimator::nominalCameraPose(h, p, r).inverse();
        ground_T_camera = Eigen::Translation3d(0.4, -0.2, 0.0) * Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                          ground_T_camera;
        const sgd::NominalMount m = sgd::StereoEstimator::nominalMount(ground_T_camera);
        EXPECT_NEAR(m.height_m, h, 1e-12);
        EXPECT_NEAR(m.pitch_down_rad, p, 1e-12) << h << " " << p << " " << r;
        EXPECT_NEAR(m.roll_rad, r, 1e-12) << h << " " << p << " " << r;
      }
    }
  }
  // By hand: an optical frame (z forward, x right, y down) 0.8 m up, turned 10 deg about the
  // base's y axis (left): it looks 10 deg down.
  Eigen::Matrix3d optical;
  optical << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  Eigen::Isometry3d base_T_camera = Eigen::Isometry3d::Identity();
  base_T_camera.linear() = Eigen::AngleAxisd(10.0 * M_PI / 180.0, Eigen::Vector3d::UnitY()) * optical;
  base_T_camera.translation() = Eigen::Vector3d(0.2, 0.0, 0.8);
  const sgd::NominalMount m = sgd::StereoEstimator::nominalMount(base_T_camera);
  EXPECT_NEAR(m.height_m, 0.8, 1e-12);
  EXPECT_NEAR(m.pitch_down_rad, 10.0 * M_PI / 180.0, 1e-12);
  EXPECT_NEAR(m.roll_rad, 0.0, 1e-12);
  const Eigen::Vector3d axis = base_T_camera.linear() * Eigen::Vector3d::UnitZ();
  EXPECT_LT(axis.z(), -0.17) << "the optical axis points down";
}

// The ground's down direction in the camera at the nominal mount: level, it is the optical y axis;
// pitched 10 deg down, the optical axis has sin(10 deg) of it.
TEST(GroundAttitude, NominalDownFollowsTheMount) {
  sgd::StereoEstimatorOptions o;
  o.nominal_pitch_down_rad = 0.0;
  o.nominal_roll_rad = 0.0;
  EXPECT_NEAR((o.nominalDown() - Eigen::Vector3d::UnitY()).norm(), 0.0, 1e-12);
  o.nominal_pitch_down_rad = 10.0 * M_PI / 180.0;
  EXPECT_NEAR(o.nominalDown().z(), std::sin(o.nominal_pitch_down_rad), 1e-12);
  EXPECT_NEAR(o.nominalDown().y(), std::cos(o.nominal_pitch_down_rad), 1e-12);
  EXPECT_NEAR(o.nominalDown().x(), 0.0, 1e-12);
  o.nominal_roll_rad = 0.1;  // a roll tips it sideways, a unit vector still
  EXPECT_GT(std::abs(o.nominalDown().x()), 0.09);
  EXPECT_NEAR(o.nominalDown().norm(), 1.0, 1e-12);
}

// The mount check: the typical attitude of recent frames against the one at the start of the map.
TEST(GroundAttitude, MountThatMovedWarnsBumpsDoNot) {
  const sgd::GroundAttitudeEstimator ga;
  auto make = [](double h, double p, double r) {
    sgd::GroundAttitudeEstimate e;
    e.valid = true;
    e.height_m = h;
    e.pitch_rad = p;
    e.roll_rad = r;
    return e;
  };
  std::vector<sgd::GroundAttitudeEstimate> start;
  for (int i = 0; i < 19; ++i) start.push_back(make(1.65 + 0.01 * (i % 3), 0.03 + 0.01 * (i % 2), -0.01));
  start.push_back(sgd::GroundAttitudeEstimate());  // invalid ones do not count
  EXPECT_FALSE(ga.typical(start).valid) << "19 valid estimates: too few";
  start.push_back(make(1.64, 0.03, -0.01));
  const sgd::GroundAttitudeEstimate reference = ga.typical(start);
  ASSERT_TRUE(reference.valid);
  EXPECT_NEAR(reference.height_m, 1.66, 1e-12);  // medians: heights 1.64, 1.65 x 7, 1.66 x 6, 1.67 x 6
  EXPECT_NEAR(reference.pitch_rad, 0.03, 1e-12);  // 0.03 x 11, 0.04 x 9
  EXPECT_NEAR(reference.roll_rad, -0.01, 1e-12);
  EXPECT_EQ(ga.mountWarning(start, reference), "");
  EXPECT_EQ(ga.mountWarning(start, sgd::GroundAttitudeEstimate()), "") << "no reference yet";
  // Bumps: a third of the frames far off, the medians stay.
  std::vector<sgd::GroundAttitudeEstimate> bumpy = start;
  for (int i = 0; i < 9; ++i) bumpy.push_back(make(1.2, 0.3, 0.2));
  EXPECT_EQ(ga.mountWarning(bumpy, reference), "");
  // The mount tilted down by 4 deg.
  std::vector<sgd::GroundAttitudeEstimate> tilted(20, make(1.64, 0.03 + 0.07, -0.01));
  const std::string w = ga.mountWarning(tilted, reference);
  EXPECT_NE(w.find("median of the last 20 frames: height 1.64 m, pitch 5.7 deg, roll -0.6 deg"), std::string::npos) << w;
  EXPECT_NE(w.find("at the start 1.66 m, 1.7 deg, -0.6 deg"), std::string::npos) << w;
  EXPECT_EQ(w.find('\n'), std::string::npos);
  // 2.5 deg: within the 2.9 deg tolerance.
  EXPECT_EQ(ga.mountWarning(std::vector<sgd::GroundAttitudeEstimate>(20, make(1.66, 0.03 + 0.044, -0.01)), reference), "");
  // Sitting 25 cm lower; rolled by 3.4 deg.
  EXPECT_NE(ga.mountWarning(std::vector<sgd::GroundAttitudeEstimate>(20, make(1.41, 0.03, -0.01)), reference)
                .find("height 1.41 m"),
            std::string::npos);
  EXPECT_NE(ga.mountWarning(std::vector<sgd::GroundAttitudeEstimate>(20, make(1.66, 0.03, 0.05)), reference), "");
}
