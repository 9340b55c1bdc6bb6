// Stereo mode (one pair) against exact ground truth from the synthetic renderer.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include <opencv2/core.hpp>

#include "stereo_ground_dem/StereoEstimator.hpp"
#include "stereo_ground_dem/sim/SequenceGenerator.hpp"
#include "stereo_ground_dem/sim/StereoRenderer.hpp"
#include "synthetic_pair.hpp"

using namespace stereo_ground_dem;

namespace {

using test::quantiles;
using Errors = test::Quantiles;
using Case = test::SyntheticPair;
Case render(sim::SceneKind kind) { return test::renderPair(kind); }

using test::heightErrors;

StereoResult run(const Case& c, const StereoEstimatorOptions& o = StereoEstimatorOptions()) {
  const StereoEstimator est(c.rig, o);
  return est.estimate(c.pair.left.image, c.pair.right.image);
}

}  // namespace

// Measured: flat median 0.20 cm, p95 0.84 cm; gain 1.2042, bias 9.60 (with the tracked frames' blur,
// before stereo_presmooth_sigma_px: 0.22 / 0.90 cm, 1.2005, 9.94).
TEST(StereoEstimator, FlatRoadHeightsGainAndBias) {
  const Case c = render(sim::SceneKind::kFlatRoad);
  const StereoResult r = run(c);
  ASSERT_TRUE(r.ok) << r.message;
  const Errors e = quantiles(heightErrors(c, r, 5.0, 20.0));
  std::printf("heights 5-20 m: n=%zu median %.2f cm p95 %.2f cm; gain %.4f bias %.2f\n", e.count, 100 * e.median, 100 * e.p95, r.photometric.gain, r.photometric.bias_grey);
  EXPECT_GT(e.count, 1000u);
  EXPECT_LT(e.median, 0.005);
  EXPECT_LT(e.p95, 0.015);
  EXPECT_NEAR(r.photometric.gain, 1.2, 0.012 * 0.5);  // within 0.5 % (issue: 1 %)
  EXPECT_NEAR(r.photometric.bias_grey, 10.0, 0.5);   // within 0.5 level (issue: 1)
  // The ground frame: camera 1.65 m above the plane fitted through level ground.
  EXPECT_NEAR(r.ground_T_camera.translation().z(), 1.65, 0.01);
  // Farther away the mesh is still centimetre-accurate on a flat road.
  const Errors far = quantiles(heightErrors(c, r, 20.0, 40.0));
  EXPECT_LT(far.median, 0.01);
  EXPECT_LT(far.p95, 0.03);
}

// Ground without texture (a blank patch in both images, as sky behind a crest or glare would be)
// measures nothing: its vertices stay unknown instead of getting heights the smoothness invents.
// Measured: 0 of 133 vertices inside the patch observed (textured_gradient_grey_per_px 1), 104 of
// 133 with the test off (0); 4,229 -> 4,049 vertices observed in all.
TEST(StereoEstimator, UntexturedGroundStaysUnknown) {
  Case c = render(sim::SceneKind::kFlatRoad);
  // rows 230-290: ~26-11 m ahead; the right patch is wider by the disparity (<= 35 px there)
  c.pair.left.image(cv::Rect(500, 230, 200, 60)).setTo(120);
  c.pair.right.image(cv::Rect(440, 230, 260, 60)).setTo(120);
  int inside[2] = {0, 0}, observed_inside[2] = {0, 0}, observed[2] = {0, 0};
  for (int off : {0, 1}) {
    StereoEstimatorOptions o;
    if (off) o.aligner.textured_gradient_grey_per_px = 0.0;
    const StereoResult r = run(c, o);
    ASSERT_TRUE(r.ok) << r.message;
    const Eigen::Isometry3d camera_T_ground = r.ground_T_camera.inverse();
    for (int v = 0; v < r.grid.vertexCount(); ++v) {
      const Eigen::Vector2d xy = r.grid.position(v);
      observed[off] += std::isfinite(r.heights[v]);
      // (height 0: the road is flat, and the fitted ground frame is its plane within a centimetre)
      const Eigen::Vector3d p = camera_T_ground * Eigen::Vector3d(xy.x(), xy.y(), 0.0);
      if (!(p.z() > 1.0)) continue;
      const double u = c.rig.fx * p.x() / p.z() + c.rig.cx, w = c.rig.fy * p.y() / p.z() + c.rig.cy;
      // every triangle around the vertex inside the patch: ~20 px and 6 rows of margin
      if (u < 525 || u > 675 || w < 238 || w > 282) continue;
      ++inside[off];
      observed_inside[off] += std::isfinite(r.heights[v]);
    }
  }
  std::printf("[ texture  ] observed inside the blank patch: %d of %d (test on), %d of %d (off); in all %d, %d\n",
              observed_inside[0], inside[0], observed_inside[1], inside[1], observed[0], observed[1]);
  ASSERT_GT(inside[0], 50);
  EXPECT_EQ(observed_inside[0], 0);
  EXPECT_GT(observed_inside[1], 0.6 * inside[1]);  // the test is what keeps them unknown
  EXPECT_GT(observed[0], observed[1] - 2 * inside[0]);  // and only them (with their borders)
}

// Measured: bump median 0.27 cm, p95 1.30 cm (0.30 / 1.35 with the tracked frames' blur); the bump's
// peak vertices within 2 cm.
TEST(StereoEstimator, SpeedBumpAndCurb) {
  const Case c = render(sim::SceneKind::kBumpAndCurb);
  const StereoResult r = run(c);
  ASSERT_TRUE(r.ok) << r.message;
  const Errors e = quantiles(heightErrors(c, r, 5.0, 20.0));
  std::printf("heights 5-20 m: n=%zu median %.2f cm p95 %.2f cm; gain %.4f bias %.2f\n", e.count, 100 * e.median, 100 * e.p95, r.photometric.gain, r.photometric.bias_grey);
  EXPECT_GT(e.count, 1000u);
  EXPECT_LT(e.median, 0.006);
  EXPECT_LT(e.p95, 0.025);
  EXPECT_NEAR(r.photometric.gain, 1.2, 0.006);
  EXPECT_NEAR(r.photometric.bias_grey, 10.0, 0.5);
  // The bump is really there: vertices on its crest are ~10 cm above the road next to it.
  const Eigen::Isometry3d true_T_est = c.ground_T_left * r.ground_T_camera.inverse();
  const Eigen::Isometry3d est_T_true = true_T_est.inverse();
  auto heightAt = [&](double x, double y) {
    const Eigen::Vector3d pe = est_T_true * Eigen::Vector3d(x, y, 0.0);
    const double z = r.grid.interpolate(r.heights, pe.x(), pe.y());
    return (true_T_est * Eigen::Vector3d(pe.x(), pe.y(), z)).z();
  };
  for (double y : {-2.0, 0.0, 2.0}) {
    EXPECT_NEAR(heightAt(13.0, y), 0.10, 0.02) << "bump crest at y = " << y;
    EXPECT_NEAR(heightAt(10.0, y), 0.00, 0.01) << "road before the bump at y = " << y;
  }
  // The curb: the sidewalk at y < -3.75 is 12 cm up.
  for (double x : {8.0, 10.0}) {
    EXPECT_NEAR(heightAt(x, -4.5) - heightAt(x, -3.0), 0.12, 0.03) << "curb step at x = " << x;
  }
}

// A one-pair run reads pyramids of its own blur (stereo_presmooth_sigma_px, 0 by default), a
// sequence's frames theirs (presmooth_sigma_px, 0.8): unblurred, the one-pair heights are more
// accurate (docs/results.md, "Stereo mode against the LiDAR": KITTI raw 0013's road D1 1.85 ->
// 0.60 %; 11 of the 12 zoo scenes' first frames). Measured on the bump and curb, heights
// 5-20 m: median / 95th 0.31 / 1.35 cm with the blur, 0.27 / 1.30 cm without.
TEST(StereoEstimator, OnePairPyramidsHaveTheirOwnBlur) {
  const Case c = render(sim::SceneKind::kBumpAndCurb);
  StereoEstimatorOptions o;
  ASSERT_EQ(o.stereo_presmooth_sigma_px, 0.0);
  ASSERT_EQ(o.presmooth_sigma_px, 0.8);
  const StereoEstimator est(c.rig, o);
  const ImagePyramid raw(c.pair.left.image, 1);
  EXPECT_EQ(cv::norm(est.makeStereoPyramid(c.pair.left.image).level(0).image, raw.level(0).image, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(est.makePyramid(c.pair.left.image).level(0).image, raw.level(0).image, cv::NORM_INF), 1.0);
  StereoEstimatorOptions blurred = o;
  blurred.stereo_presmooth_sigma_px = 0.8;
  const StereoResult r0 = run(c, o), r8 = run(c, blurred);
  ASSERT_TRUE(r0.ok && r8.ok) << r0.message << r8.message;
  const Errors e0 = quantiles(heightErrors(c, r0, 5.0, 20.0)), e8 = quantiles(heightErrors(c, r8, 5.0, 20.0));
  std::printf("[ blur     ] heights 5-20 m median / p95: unblurred %.2f / %.2f cm, blurred %.2f / %.2f cm\n",
              100 * e0.median, 100 * e0.p95, 100 * e8.median, 100 * e8.p95);
  EXPECT_GT(e0.count, 1000u);
  EXPECT_LT(e0.median, 0.004);
  EXPECT_LT(e0.p95, 0.02);
  EXPECT_LT(e0.p95, e8.p95);
  // the one-pair estimate from images is the one from the stereo pyramids
  const StereoResult rp = est.estimate(est.makeStereoPyramid(c.pair.left.image), est.makeStereoPyramid(c.pair.right.image));
  ASSERT_EQ(rp.heights.size(), r0.heights.size());
  int differ = 0;
  for (int v = 0; v < r0.heights.size(); ++v)
    differ += !(rp.heights[v] == r0.heights[v] || (std::isnan(rp.heights[v]) && std::isnan(r0.heights[v])));
  EXPECT_EQ(differ, 0);
}

TEST(StereoEstimator, ConvergesFromAWrongNominalPose) {
  // 15 cm too high and 1.5 degrees of pitch off: the start-up plane fit corrects it.
  const Case c = render(sim::SceneKind::kFlatRoad);
  StereoEstimatorOptions o;
  o.nominal_height_m = 1.80;
  o.nominal_pitch_down_rad = 1.5 * M_PI / 180.0;
  const StereoResult r = run(c, o);
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_NEAR(r.ground_T_camera.translation().z(), 1.65, 0.01);
  const Errors e = quantiles(heightErrors(c, r, 5.0, 20.0));
  EXPECT_LT(e.median, 0.005);
}

TEST(StereoEstimator, ImpliedDisparityMatchesTheRenderer) {
  const Case c = render(sim::SceneKind::kFlatRoad);
  const StereoEstimator est(c.rig, StereoEstimatorOptions());
  const ImagePyramid left = est.makePyramid(c.pair.left.image);
  const ImagePyramid right = est.makePyramid(c.pair.right.image);
  const StereoResult r = est.estimate(left, right);
  ASSERT_TRUE(r.ok);
  const cv::Mat d = est.impliedDisparity(r, left);
  std::vector<double> err;
  for (int v = 0; v < d.rows; ++v)
    for (int u = 0; u < d.cols; ++u) {
      const float de = d.at<float>(v, u);
      const float rho = c.pair.left.inverse_depth.at<float>(v, u);
      if (de <= 0.0f || rho <= 0.0f) continue;
      err.push_back(std::abs(de - c.rig.disparityTimesDepth() * rho));
    }
  const Errors e = quantiles(err);
  std::cout << "disparity error median " << e.median << " p95 " << e.p95 << " n " << e.count << "\n";
  EXPECT_GT(e.count, 150000u);   // the ground below the 40 m line, full resolution
  EXPECT_LT(e.median, 0.03);     // [px]
  EXPECT_LT(e.p95, 0.12);
}

TEST(StereoEstimator, RejectsBadInputWithAMessage) {
  const StereoRig rig = sim::StereoRenderer::kittiLikeRig(0.25);
  const StereoEstimator est(rig, StereoEstimatorOptions());
  const cv::Mat a(rig.height, rig.width, CV_8U, cv::Scalar(100));
  const cv::Mat b(rig.height + 2, rig.width, CV_8U, cv::Scalar(100));
  StereoResult r = est.estimate(a, b);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.message.find("differ in size"), std::string::npos) << r.message;
  const cv::Mat wrong(rig.height * 2, rig.width * 2, CV_8U, cv::Scalar(100));
  r = est.estimate(wrong, wrong);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.message.find("does not match the calibration"), std::string::npos) << r.message;
  // A flat grey pair has no texture: the start-up fit finds no usable pixels.
  r = est.estimate(a, a);
  EXPECT_FALSE(r.ok);
  EXPECT_FALSE(r.message.empty());
  StereoEstimatorOptions bad;
  bad.grid_resolution_m = -1.0;
  EXPECT_THROW(StereoEstimator(rig, bad), std::invalid_argument);
}

// The ground a pair shows near the mounted attitude: what a frame placed without a velocity after
// a failure must show (IncrementalEstimator: "no ground in view near the mounted attitude"). The
// same pair turned upside down (rotated 180 deg, left and right swapped: positive disparities, the
// ground in the upper half) holds a plane too, but tilted 180 deg from the mount.
TEST(StereoEstimator, GroundPlaneNearTheMountOnlyTheRightWayUp) {
  const Case c = render(sim::SceneKind::kFlatRoad);
  const StereoEstimator est(c.rig, StereoEstimatorOptions());
  const ImagePyramid l = est.makePyramid(c.pair.left.image), r = est.makePyramid(c.pair.right.image);
  const DisparityPlane upright = est.groundPlane(l, r, est.checkPair(l, r));
  ASSERT_TRUE(upright.ok) << upright.message;
  std::printf("upright: height %.4f m, %d inliers, rms %.3f px\n", upright.height_m, upright.inliers, upright.rms_px);
  EXPECT_NEAR(upright.height_m, 1.65, 0.005);  // measured 1.6502 m, 672 inliers
  cv::Mat tl, tr;
  cv::rotate(c.pair.right.image, tl, cv::ROTATE_180);
  cv::rotate(c.pair.left.image, tr, cv::ROTATE_180);
  const ImagePyramid ul = est.makePyramid(tl), ur = est.makePyramid(tr);
  const StereoPairCheck turned = est.checkPair(ul, ur);
  std::printf("upside down: %zu matches\n", turned.points.size());
  EXPECT_GT(turned.points.size(), 320u);  // matched as well, a consistent pair: measured 646
  const DisparityPlane over = est.groundPlane(ul, ur, turned);
  EXPECT_FALSE(over.ok) << "height " << over.height_m;
  EXPECT_FALSE(over.message.empty());
}

TEST(PhotometricParams, InverseCompositionalUpdate) {
  // (1 + dg) I0 + db = a I1 + b  <=>  I0 = a' I1 + b' with a' = a / (1 + dg), b' = (b - db) / (1 + dg)
  const PhotometricParams p{1.3, -7.0};
  const double dg = 0.05, db = 2.5;
  const PhotometricParams q = p.composedWithInverse(dg, db);
  for (double i1 : {0.0, 50.0, 200.0}) {
    const double i0 = q.gain * i1 + q.bias_grey;
    EXPECT_NEAR((1.0 + dg) * i0 + db, p.gain * i1 + p.bias_grey, 1e-12);
  }
}

// min_incidence_ratio in stereo mode: a vertex whose estimated surface the camera sees along its
// rays (or from behind) is left unknown (NaN), as the incremental fusion leaves it unfused. On
// level ground every ratio is ~1, so 0.1 changes nothing; behind the speed bump's crest the back
// face is seen from behind at 13 m (the rays dip 7 deg, the face falls away more steeply).
TEST(StereoEstimator, GrazingVerticesAreLeftUnknown) {
  for (const sim::SceneKind kind : {sim::SceneKind::kFlatRoad, sim::SceneKind::kBumpAndCurb}) {
    const Case c = render(kind);
    StereoResult r[2];
    int observed[2] = {0, 0};
    Errors e[2];
    for (int on : {0, 1}) {
      StereoEstimatorOptions o;
      o.min_incidence_ratio = on ? 0.1 : 0.0;
      r[on] = run(c, o);
      ASSERT_TRUE(r[on].ok) << r[on].message;
      for (int v = 0; v < r[on].grid.vertexCount(); ++v) observed[on] += std::isfinite(r[on].heights[v]);
      e[on] = quantiles(heightErrors(c, r[on], 5.0, 20.0));
    }
    // where the vertices left unknown are (ground frame: x ahead, y left)
    int removed = 0, removed_behind_bump = 0;
    ASSERT_EQ(r[0].grid.vertexCount(), r[1].grid.vertexCount());
    for (int v = 0; v < r[0].grid.vertexCount(); ++v) {
      if (!std::isfinite(r[0].heights[v]) || std::isfinite(r[1].heights[v])) continue;
      ++removed;
      const Eigen::Vector2d xy = r[0].grid.position(v);
      removed_behind_bump += xy.x() > 12.5 && xy.x() < 15.5;
    }
    const bool flat = kind == sim::SceneKind::kFlatRoad;
    std::printf("[ incidence] %s: observed %d -> %d with 0.1 (%d left unknown, %d of them behind the bump's crest); "
                "heights 5-20 m median %.2f -> %.2f cm, p95 %.2f -> %.2f cm\n",
                flat ? "flat" : "bump", observed[0], observed[1], removed, removed_behind_bump, 100 * e[0].median,
                100 * e[1].median, 100 * e[0].p95, 100 * e[1].p95);
    EXPECT_EQ(observed[1], observed[0] - removed);  // nothing new observed
    if (flat) {
      EXPECT_EQ(removed, 0);
    } else {
      // measured: 3 left unknown, all on the bump's far side (seen from behind at 13-14 m)
      EXPECT_GE(removed, 1);
      EXPECT_EQ(removed_behind_bump, removed);
    }
    EXPECT_LT(e[1].p95, 1.05 * e[0].p95);
  }
}
