// The incremental mode's tracking parts on their own: MotionPredictor (prediction scaled by the
// stamp gap, rotation and speed hypotheses, the wrong-stamp hypothesis, the search grid),
// TrackingCheck (every failure reason and its threshold) and DisparityPlaneFit (the dominant
// plane of sparse matches, with outliers, at any attitude; refusals).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "stereo_ground_dem/DisparityPlaneFit.hpp"
#include "stereo_ground_dem/MotionPredictor.hpp"
#include "stereo_ground_dem/Se3.hpp"
#include "stereo_ground_dem/StereoEstimator.hpp"
#include "stereo_ground_dem/TrackingCheck.hpp"

using namespace stereo_ground_dem;

namespace {

constexpr double kDeg = M_PI / 180.0;

/// The twist taking `a` to `b` (b = exp(xi) a).
Vector6d between(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) { return Se3::log(b * a.inverse()); }

/// Camera 1.65 m above level ground looking along +x, moving 1.2 m forward and yawing 0.02 rad per 0.1 s.
struct Drive {
  MotionPredictor p;
  Vector6d step_per_frame;
  Eigen::Isometry3d pose1;
  Drive() {
    Eigen::Isometry3d camera_T_ground = Eigen::Isometry3d::Identity();
    camera_T_ground.translation() = Eigen::Vector3d(0.0, 1.65, 0.0);
    step_per_frame << 0.0, 0.0, -1.2, 0.0, 0.02, 0.0;
    p.setPose(camera_T_ground, 10.0);
    pose1 = Se3::exp(step_per_frame) * camera_T_ground;
    p.update(pose1, 10.1);
  }
};

}  // namespace

TEST(MotionPredictor, ConstantVelocityScalesWithTheStampGap) {
  Drive d;
  ASSERT_TRUE(d.p.velocityKnown());
  EXPECT_NEAR((d.p.velocity() - d.step_per_frame / 0.1).norm(), 0.0, 1e-9);
  EXPECT_NEAR((between(d.pose1, d.p.predict(10.2)) - d.step_per_frame).norm(), 0.0, 1e-9);
  // two frames dropped: three steps
  EXPECT_NEAR((between(d.pose1, d.p.predict(10.4)) - 3.0 * d.step_per_frame).norm(), 0.0, 1e-9);
  // a stamp that does not increase: the nominal period
  EXPECT_DOUBLE_EQ(d.p.gap(10.1), 0.1);
  EXPECT_DOUBLE_EQ(d.p.gap(10.05), 0.1);
  d.p.forgetVelocity();
  EXPECT_FALSE(d.p.velocityKnown());
  EXPECT_TRUE(d.p.predict(10.2).isApprox(d.pose1, 1e-12));
  // Dead reckoning over failed frames: the untrusted velocity still moves the pose on, by the gap.
  EXPECT_NEAR((between(d.pose1, d.p.coast(10.2)) - d.step_per_frame).norm(), 0.0, 1e-9);
  EXPECT_NEAR((between(d.pose1, d.p.coast(10.4)) - 3.0 * d.step_per_frame).norm(), 0.0, 1e-9);
  // ... until a pose is set without one
  d.p.setPose(d.pose1, 10.5);
  EXPECT_TRUE(d.p.coast(10.7).isApprox(d.pose1, 1e-12));
}

// A state continued on another clock: the step after it took an unknown time and measures no
// velocity; the step after that does.
TEST(MotionPredictor, AStepFromAGuessedStampMeasuresNoVelocity) {
  Drive d;
  d.p.restore(d.pose1, 10.1, Vector6d::Zero(), 0.0, false);
  d.p.distrustLastStamp();
  const Eigen::Isometry3d back = Se3::exp(-12.0 * d.step_per_frame) * d.pose1;  // 12 frames back
  d.p.update(back, 10.2);
  EXPECT_FALSE(d.p.velocityKnown());
  EXPECT_TRUE(d.p.predict(10.3).isApprox(back, 1e-12));
  EXPECT_TRUE(d.p.coast(10.3).isApprox(back, 1e-12));
  const Eigen::Isometry3d next = Se3::exp(d.step_per_frame) * back;
  d.p.update(next, 10.3);
  EXPECT_TRUE(d.p.velocityKnown());
  EXPECT_NEAR((between(next, d.p.predict(10.4)) - d.step_per_frame).norm(), 0.0, 1e-9);
}

TEST(MotionPredictor, HypothesesCoverTurnsAttitudeStepsAndSpeedChanges) {
  Drive d;
  const std::vector<Eigen::Isometry3d> h = d.p.hypotheses(10.2);
  ASSERT_EQ(h.size(), 16u);  // cv, no turn, 12 attitude steps, half, double
  EXPECT_NEAR((between(d.pose1, h[0]) - d.step_per_frame).norm(), 0.0, 1e-9);
  Vector6d no_turn = d.step_per_frame;
  no_turn.tail<3>().setZero();
  EXPECT_NEAR((between(d.pose1, h[1]) - no_turn).norm(), 0.0, 1e-9);
  // attitude steps: 1.5 and 3 degrees about x, z, y of the camera, both signs, around h[1]
  const double step = d.p.options().rotation_step_rad;
  EXPECT_NEAR(step, 1.5 * kDeg, 0.02 * kDeg);
  const int axes[3] = {0, 2, 1};
  for (int k = 0; k < 12; ++k) {
    const Vector6d xi = between(h[1], h[2 + k]);
    const double expected = (k < 6 ? 1.0 : 2.0) * step * ((k % 2) ? -1.0 : 1.0);
    EXPECT_NEAR(xi[3 + axes[(k / 2) % 3]], expected, 1e-12) << k;
    EXPECT_NEAR(xi.head<3>().norm(), 0.0, 1e-12) << k;
    EXPECT_NEAR(xi.tail<3>().norm(), std::abs(expected), 1e-12) << k;
  }
  EXPECT_NEAR((between(d.pose1, h[14]) - 0.5 * d.step_per_frame).norm(), 0.0, 1e-9);
  EXPECT_NEAR((between(d.pose1, h[15]) - 1.5 * d.step_per_frame).norm(), 0.0, 1e-9);
}

TEST(MotionPredictor, AStampGapUnlikeTheLastOneAddsTheUnscaledStep) {
  Drive d;
  // 5 s instead of 0.1 s: a wrong stamp or 49 dropped frames; both are tried
  const std::vector<Eigen::Isometry3d> h = d.p.hypotheses(15.1);
  ASSERT_EQ(h.size(), 17u);
  EXPECT_NEAR((between(d.pose1, h[0]) - 50.0 * d.step_per_frame).norm(), 0.0, 1e-7);
  EXPECT_NEAR((between(d.pose1, h.back()) - d.step_per_frame).norm(), 0.0, 1e-9);
  // a gap within 1.5x of the last: no extra hypothesis
  EXPECT_EQ(d.p.hypotheses(10.24).size(), 16u);
  EXPECT_EQ(d.p.hypotheses(10.26).size(), 17u);
}

TEST(MotionPredictor, SearchGridSpansForwardMotionAndYawWithACappedReverse) {
  MotionPredictor p;
  p.setPose(Eigen::Isometry3d::Identity(), 0.0);
  const MotionPredictorOptions& o = p.options();
  std::vector<Eigen::Isometry3d> g = p.searchGrid(0.1);
  // -1 .. 3 m in 0.2 m steps (21) for each of 5 yaw rates
  ASSERT_EQ(g.size(), 21u * o.search_yaw_rad.size());
  double min_t = 1e9, max_t = -1e9;
  for (const auto& x : g) {
    const double forward = -x.translation().z();
    min_t = std::min(min_t, forward);
    max_t = std::max(max_t, forward);
  }
  EXPECT_NEAR(min_t, -1.0, 1e-9);
  EXPECT_NEAR(max_t, 3.0, 1e-9);
  // three periods: up to 9 m forward in steps of at most 0.6 m, still at most 1 m backwards
  g = p.searchGrid(0.3);
  min_t = 1e9, max_t = -1e9;
  for (const auto& x : g) {
    min_t = std::min(min_t, -x.translation().z());
    max_t = std::max(max_t, -x.translation().z());
  }
  EXPECT_NEAR(min_t, -1.0, 1e-9);
  EXPECT_GT(max_t, 8.9 - 0.6);
  EXPECT_LE(max_t, 9.0 + 1e-9);
  EXPECT_EQ(g.size(), 17u * o.search_yaw_rad.size());  // -1 .. 8.6 in 0.6 m
}

TEST(TrackingCheck, EachReasonAtItsThreshold) {
  const TrackingCheck check{TrackingCheckOptions()};
  TrackingEvidence ok;
  ok.step << 0.0, 0.0, -1.2, 0.0, 0.02, 0.0;
  ok.samples = 20000;
  ok.outside = 1000;
  ok.well_known = 1000;
  ok.jumps = 10;
  ok.median_residual_grey = 4.0;
  ok.usual_residual_grey = 3.0;
  EXPECT_EQ(check.failure(ok), "");

  TrackingEvidence e = ok;
  e.degenerate = true;
  EXPECT_EQ(check.failure(e), "normal equations degenerate");
  e = ok;
  e.finite = false;
  EXPECT_EQ(check.failure(e), "estimate is not finite");
  e = ok;
  e.step[2] = -4.9;  // 49 m/s passes, 51 m/s does not
  EXPECT_EQ(check.failure(e), "");
  e.step[2] = -5.1;
  EXPECT_EQ(check.failure(e), "implausible motion: 51 m/s");
  e = ok;
  e.step[3] = 0.29;  // 2.9 rad/s passes, 3.1 does not
  EXPECT_EQ(check.failure(e), "");
  e.step[3] = 0.31;
  EXPECT_EQ(check.failure(e).rfind("implausible rotation: 3.1", 0), 0u) << check.failure(e);
  e = ok;
  e.outside = 12001;  // more than 60 % of the samples
  EXPECT_EQ(check.failure(e), "too few pixels overlap between the images (12001 of 20000 samples outside)");
  e = ok;
  e.samples = 499;
  e.outside = 0;
  EXPECT_NE(check.failure(e), "");
  e = ok;
  e.jumps = 151;  // more than 15 % of 1000
  EXPECT_EQ(check.failure(e), "151 of 1000 well-known vertices moved more than 0.4 m");
  e.well_known = 20;  // too few well-known vertices to judge
  e.jumps = 20;
  EXPECT_EQ(check.failure(e), "");
  e = ok;
  // limit max(3 x usual, usual + 3 grey): 9 grey for a usual 3 grey, 4 grey for a usual 1 grey
  e.median_residual_grey = 8.9;
  EXPECT_EQ(check.failure(e), "");
  e.median_residual_grey = 9.1;
  EXPECT_EQ(check.failure(e), "alignment did not converge: median residual 9.1 grey (usual 3)");
  e.usual_residual_grey = 1.0;
  e.median_residual_grey = 3.9;
  EXPECT_EQ(check.failure(e), "");
  e.median_residual_grey = 4.1;
  EXPECT_NE(check.failure(e), "");
  e.usual_residual_grey = 0.0;  // no level yet: not judged
  EXPECT_EQ(check.failure(e), "");
  // The temporal pair against its own level, the same limit: a final level of the stereo pair alone
  // does not see a wrong motion (the rolling scene from 0.8 m, frame 16: 28.6 grey, usual 1.4).
  e = ok;
  e.usual_temporal_residual_grey = 1.5;  // limit 4.5 grey
  e.temporal_residual_grey = 4.4;
  EXPECT_EQ(check.failure(e), "");
  e.temporal_residual_grey = 4.6;
  EXPECT_EQ(check.failure(e), "the motion does not explain the previous image: its median residual 4.6 grey (usual 1.5)");
  e.usual_temporal_residual_grey = 2.0;  // limit 6 grey
  EXPECT_EQ(check.failure(e), "");
  e.temporal_residual_grey = 6.1;
  EXPECT_NE(check.failure(e), "");
  // Twice the usual stamp gap (frames dropped): the images differ more, the limit doubles (12 grey)
  e.temporal_gap_ratio = 2.0;
  e.temporal_residual_grey = 11.9;
  EXPECT_EQ(check.failure(e), "");
  e.temporal_residual_grey = 12.1;
  EXPECT_EQ(check.failure(e),
            "the motion does not explain the previous image: its median residual 12.1 grey (usual 2, over 2x the "
            "usual stamp gap)");
  e.temporal_gap_ratio = 0.5;  // a shorter gap never tightens it
  e.temporal_residual_grey = 5.9;
  EXPECT_EQ(check.failure(e), "");
  e.temporal_gap_ratio = 1.0;
  e.usual_temporal_residual_grey = 0.0;  // no level yet
  EXPECT_EQ(check.failure(e), "");
  e.usual_temporal_residual_grey = 2.0;
  e.temporal_residual_grey = std::numeric_limits<double>::quiet_NaN();  // not measured
  EXPECT_EQ(check.failure(e), "");
  // The ground support: fewer observed vertices than 0.2 of the usual number
  e = ok;
  e.usual_observed_vertices = 2000.0;  // limit 400
  e.observed_vertices = 401;
  EXPECT_EQ(check.failure(e), "");
  e.observed_vertices = 399;
  EXPECT_EQ(check.failure(e), "the ground support collapsed: 399 vertices observed (usual 2000)");
  e.observed_vertices = 0;
  e.usual_observed_vertices = 0.0;  // no level yet
  EXPECT_EQ(check.failure(e), "");
  TrackingCheckOptions bad;
  bad.max_residual_ratio = 1.0;
  EXPECT_THROW(TrackingCheck{bad}, std::invalid_argument);
  bad = TrackingCheckOptions();
  bad.min_observed_fraction = 1.0;
  EXPECT_THROW(TrackingCheck{bad}, std::invalid_argument);
}

namespace {

StereoRig kittiRig() {
  StereoRig r;
  r.fx = r.fy = 718.856;
  r.cx = 607.19;
  r.cy = 185.22;
  r.baseline_m = 0.537;
  r.width = 1226;
  r.height = 370;
  return r;
}

/// Matches (u, v, d) of the plane {X : down . X = height} seen by `rig` below the horizon, plus
/// `outliers` random matches, with `noise_px` of disparity noise.
std::vector<Eigen::Vector3f> planeMatches(const StereoRig& rig, const Eigen::Vector3d& down, double height, int n,
                                          int outliers, double noise_px, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, noise_px);
  std::vector<Eigen::Vector3f> pts;
  while (static_cast<int>(pts.size()) < n) {
    const double u = u01(rng) * (rig.width - 1), v = u01(rng) * (rig.height - 1);
    const double inv_z = (down.x() * (u - rig.cx) / rig.fx + down.y() * (v - rig.cy) / rig.fy + down.z()) / height;
    const double d = rig.fx * rig.baseline_m * inv_z;
    if (d < 3.0 || d > 150.0) continue;
    pts.emplace_back(static_cast<float>(u), static_cast<float>(v), static_cast<float>(d + noise(rng)));
  }
  for (int k = 0; k < outliers; ++k) {
    pts.emplace_back(static_cast<float>(u01(rng) * (rig.width - 1)), static_cast<float>(u01(rng) * (rig.height - 1)),
                     static_cast<float>(3.0 + 60.0 * u01(rng)));
  }
  return pts;
}

}  // namespace

TEST(DisparityPlaneFit, RecoversThePlaneAtAnyAttitudeThroughOutliers) {
  const StereoRig rig = kittiRig();
  const DisparityPlaneFit fit;
  // level; pitched down 8 deg and rolled 5 deg; camera 1.2 m high and pitched up 6 deg
  const Eigen::Vector3d downs[] = {
      Eigen::Vector3d::UnitY(),
      (Eigen::AngleAxisd(5 * kDeg, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(-8 * kDeg, Eigen::Vector3d::UnitX()) *
       Eigen::Vector3d::UnitY()),
      Eigen::AngleAxisd(6 * kDeg, Eigen::Vector3d::UnitX()) * Eigen::Vector3d::UnitY()};
  const double heights[] = {1.65, 1.65, 1.2};
  for (int k = 0; k < 3; ++k) {
    const auto pts = planeMatches(rig, downs[k], heights[k], 400, 150, 0.2, 7 + k);
    // only matches below the principal point's row are used
    int below = 0;
    for (int i = 0; i < 400; ++i) below += pts[static_cast<size_t>(i)].y() > rig.cy;
    const DisparityPlane p = fit.fit(pts, rig);
    ASSERT_TRUE(p.ok) << k << ": " << p.message;
    EXPECT_LT(std::acos(std::min(1.0, p.down.dot(downs[k]))), 0.15 * kDeg) << k;
    EXPECT_NEAR(p.height_m, heights[k], 0.01) << k;
    EXPECT_GE(p.inliers, 0.97 * below) << k;
    EXPECT_LE(p.inliers, below + 30) << k;  // a few outliers fall on the plane by chance
    EXPECT_LT(p.rms_px, 0.3) << k;
  }
}

TEST(DisparityPlaneFit, RefusesTooFewMatchesAndPlanesThatAreNoGround) {
  const StereoRig rig = kittiRig();
  const DisparityPlaneFit fit;
  // 20 matches: fewer than min_inliers
  DisparityPlane p = fit.fit(planeMatches(rig, Eigen::Vector3d::UnitY(), 1.65, 20, 0, 0.1, 3), rig);
  EXPECT_FALSE(p.ok);
  EXPECT_FALSE(p.message.empty());
  // a wall facing the camera 8 m ahead: constant disparity, normal along the optical axis
  std::vector<Eigen::Vector3f> wall;
  for (int k = 0; k < 400; ++k) {
    wall.emplace_back(static_cast<float>(100 + (k * 37) % 1000), static_cast<float>(20 + (k * 53) % 330),
                      static_cast<float>(rig.fx * rig.baseline_m / 8.0));
  }
  p = fit.fit(wall, rig);
  EXPECT_FALSE(p.ok);
  EXPECT_FALSE(p.message.empty());
  // the ceiling of a tunnel 3 m above: the plane is above the camera
  p = fit.fit(planeMatches(rig, -Eigen::Vector3d::UnitY(), 3.0, 400, 0, 0.1, 5), rig);
  EXPECT_FALSE(p.ok);
}

// Beside a low camera the dominant plane of the matches may be a slope beside the track: more
// matches, tilted 32 deg, 4.2 m "below" a camera 0.8 m high (the off-road scene rendered from 0.8 m:
// the start-up took it for the ground, end rotation 2.9-3.5 deg, coverage 26 %). The ground a vehicle
// starts on is near the attitude its camera is mounted at (nearAttitude).
TEST(DisparityPlaneFit, TheGroundNearTheMountedAttitudeNotTheDominantSlope) {
  const StereoRig rig = kittiRig();
  const Eigen::Vector3d slope_down = Eigen::AngleAxisd(-30 * kDeg, Eigen::Vector3d::UnitZ()) * Eigen::Vector3d::UnitY();
  std::vector<Eigen::Vector3f> pts = planeMatches(rig, slope_down, 4.2, 400, 0, 0.2, 11);
  const auto ground = planeMatches(rig, Eigen::Vector3d::UnitY(), 0.8, 150, 0, 0.2, 12);
  pts.insert(pts.end(), ground.begin(), ground.end());
  const DisparityPlaneFitOptions o;
  // the options' own bound (0.7 rad from the camera's down axis): the slope
  DisparityPlane p = DisparityPlaneFit(o).fit(pts, rig);
  ASSERT_TRUE(p.ok) << p.message;
  EXPECT_NEAR(p.height_m, 4.2, 0.05);
  // within 20 deg of a level camera's ground: the ground
  p = DisparityPlaneFit(o.nearAttitude(Eigen::Vector3d::UnitY(), 0.35)).fit(pts, rig);
  ASSERT_TRUE(p.ok) << p.message;
  EXPECT_NEAR(p.height_m, 0.8, 0.01);
  EXPECT_LT(std::acos(std::min(1.0, p.down.y())), 0.3 * kDeg);
  EXPECT_GE(p.inliers, 0.95 * 150);
  // a camera mounted 17 deg down sees its ground 17 deg from its own down axis: found around the
  // mounted attitude, refused around a level one (the reason names the bound)
  const Eigen::Vector3d mounted = Eigen::AngleAxisd(17 * kDeg, Eigen::Vector3d::UnitX()) * Eigen::Vector3d::UnitY();
  const auto pitched = planeMatches(rig, mounted, 1.65, 300, 0, 0.2, 13);
  p = DisparityPlaneFit(o.nearAttitude(mounted, 0.1)).fit(pitched, rig);
  ASSERT_TRUE(p.ok) << p.message;
  EXPECT_NEAR(p.height_m, 1.65, 0.02);
  p = DisparityPlaneFit(o.nearAttitude(Eigen::Vector3d::UnitY(), 0.2)).fit(pitched, rig);
  EXPECT_FALSE(p.ok);
  EXPECT_NE(p.message.find("tilted at most 11.4"), std::string::npos) << p.message;
  // a looser bound than the options' own is not taken; a bad direction leaves the options as they are
  EXPECT_DOUBLE_EQ(o.nearAttitude(mounted, 1.0).max_tilt_rad, o.max_tilt_rad);
  EXPECT_TRUE(o.nearAttitude(Eigen::Vector3d::Zero(), 0.2).expected_down.isApprox(Eigen::Vector3d::UnitY()));
  EXPECT_DOUBLE_EQ(o.nearAttitude(Eigen::Vector3d::Zero(), 0.2).max_tilt_rad, o.max_tilt_rad);
  DisparityPlaneFitOptions bad = o;
  bad.expected_down = Eigen::Vector3d(0.0, 2.0, 0.0);
  EXPECT_FALSE(bad.isValid(nullptr));
}

// The expected ground follows the mount's nominal pitch (positive down), with the sign of
// StereoEstimator::nominalCameraPose: a camera pitched 0.5 rad down is refused its ground when the
// options say it looks 0.5 rad up.
TEST(DisparityPlaneFit, TheStartUpExpectsTheGroundOfTheNominalPitch) {
  const StereoRig rig = kittiRig();
  const Eigen::Vector3d mounted = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitX()) * Eigen::Vector3d::UnitY();
  const auto pts = planeMatches(rig, mounted, 1.65, 300, 0, 0.2, 14);
  StereoEstimatorOptions so;
  so.nominal_pitch_down_rad = 0.5;
  const DisparityPlaneFitOptions down = so.nearNominalAttitude(so.ground_plane);
  EXPECT_NEAR(down.expected_down.dot(mounted), 1.0, 1e-9);
  EXPECT_DOUBLE_EQ(down.max_tilt_rad, so.nominal_max_tilt_rad);
  const DisparityPlane p = DisparityPlaneFit(down).fit(pts, rig);
  ASSERT_TRUE(p.ok) << p.message;
  EXPECT_NEAR(p.height_m, 1.65, 0.02);
  so.nominal_pitch_down_rad = -0.5;
  EXPECT_FALSE(DisparityPlaneFit(so.nearNominalAttitude(so.ground_plane)).fit(pts, rig).ok);
  // 0: the options' own bound around the camera's axis (0.7 rad: the 0.5 rad ground passes)
  so.nominal_max_tilt_rad = 0.0;
  EXPECT_TRUE(DisparityPlaneFit(so.nearNominalAttitude(so.ground_plane)).fit(pts, rig).ok);
}
