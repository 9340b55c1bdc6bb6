// Tests of the synthetic stereo renderer: scene heights, exact ray casting, image formation,
// anti-aliasing, determinism, obstacles and the KITTI-style export.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "stereo_ground_dem/CalibrationReader.hpp"
#include "stereo_ground_dem/sim/SequenceGenerator.hpp"
#include "stereo_ground_dem/sim/StereoRenderer.hpp"
#include "stereo_ground_dem/sim/SyntheticScene.hpp"

namespace sgd = stereo_ground_dem;
using sgd::sim::BoxObstacle;
using sgd::sim::PoleObstacle;
using sgd::sim::RenderedImage;
using sgd::sim::RenderOptions;
using sgd::sim::SceneKind;
using sgd::sim::SceneOptions;
using sgd::sim::SequenceGenerator;
using sgd::sim::SequenceOptions;
using sgd::sim::StereoRenderer;
using sgd::sim::SyntheticScene;

namespace {

// 320 x 97: the KITTI rig scaled down, for fast tests.
sgd::StereoRig smallRig() { return StereoRenderer::kittiLikeRig(320.0 / 1226.0); }

Eigen::Isometry3d startPose(const SyntheticScene& scene, double pitch_down_rad = 0.0) {
  SequenceOptions o;
  o.camera_pitch_down_rad = pitch_down_rad;
  return SequenceGenerator::cameraPose(scene, o, 0.0, 0.0, 0.0);
}

// The ground point seen at pixel (u, v) of a camera, from the rendered inverse depth.
Eigen::Vector3d backProject(const sgd::StereoRig& rig, const Eigen::Isometry3d& ground_T_camera,
                            double u, double v, double inverse_depth) {
  const double z = 1.0 / inverse_depth;
  const Eigen::Vector3d pc((u - rig.cx) / rig.fx * z, (v - rig.cy) / rig.fy * z, z);
  return ground_T_camera * pc;
}

class TempDir {
 public:
  TempDir() {
    char name[] = "/tmp/sgd_sim_test_XXXXXX";
    path_ = mkdtemp(name);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

std::vector<std::vector<double>> readNumbers(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::vector<double>> rows;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ss(line);
    std::vector<double> row;
    double v;
    while (ss >> v) row.push_back(v);
    if (!row.empty()) rows.push_back(row);
  }
  return rows;
}

double meanAbsDiff(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  cv::Mat d;
  cv::absdiff(a, b, d);
  return cv::mean(d, mask)[0];
}

}  // namespace

// ------------------------------------------------------------------------------------------------
// Scene heights

TEST(SyntheticScene, FlatRoadIsLevel) {
  const SyntheticScene scene(SceneOptions::standard(SceneKind::kFlatRoad, 3));
  for (double x : {-5.0, 0.0, 7.3, 55.0, 300.0}) {
    for (double y : {-20.0, -3.76, 0.0, 3.1, 12.0}) {
      EXPECT_EQ(scene.terrainHeight(x, y), 0.0) << x << " " << y;
      EXPECT_EQ(scene.terrainGradient(x, y).norm(), 0.0);
    }
  }
  EXPECT_EQ(scene.minTerrainHeight(), 0.0);
  EXPECT_EQ(scene.maxTerrainHeight(), 0.0);
}

TEST(SyntheticScene, BumpAndCurbHeights) {
  const SyntheticScene scene(SceneOptions::standard(SceneKind::kBumpAndCurb, 3));
  const SceneOptions& o = scene.options();
  EXPECT_DOUBLE_EQ(o.bump_center_x_m, 13.0);
  EXPECT_DOUBLE_EQ(o.curb_y_m, -3.75);
  EXPECT_DOUBLE_EQ(o.curb_height_m, 0.12);
  // Bump: raised cosine, 0.10 m peak at x = 13, 1.8 m long.
  EXPECT_NEAR(scene.terrainHeight(13.0, 0.0), 0.10, 1e-12);
  EXPECT_NEAR(scene.terrainHeight(13.0, -3.5), 0.10, 1e-12);
  EXPECT_NEAR(scene.terrainHeight(13.45, 1.0), 0.05, 1e-12);
  EXPECT_NEAR(scene.terrainHeight(12.55, 1.0), 0.05, 1e-12);
  EXPECT_NEAR(scene.terrainHeight(13.0 + 0.9, 0.0), 0.0, 1e-12);
  EXPECT_EQ(scene.terrainHeight(12.0, 0.0), 0.0);
  EXPECT_EQ(scene.terrainHeight(14.0, 0.0), 0.0);
  EXPECT_NEAR(scene.terrainGradient(13.0, 0.0).norm(), 0.0, 1e-12);
  EXPECT_NEAR(scene.terrainGradient(13.45, 0.0).x(), -M_PI * 0.10 / 1.8, 1e-12);
  // Tapered end on the left: half height half-way through the taper.
  EXPECT_NEAR(scene.terrainHeight(13.0, 3.75 + 0.25), 0.05, 1e-12);
  EXPECT_EQ(scene.terrainHeight(13.0, 3.75 + 0.5 + 1e-6), 0.0);
  // Curb: the sidewalk (y < -3.75) is 0.12 m higher, with a vertical face.
  EXPECT_EQ(scene.terrainHeight(5.0, -3.75 + 1e-9), 0.0);
  EXPECT_DOUBLE_EQ(scene.terrainHeight(5.0, -3.75 - 1e-9), 0.12);
  EXPECT_DOUBLE_EQ(scene.terrainHeight(5.0, -8.0), 0.12);
  EXPECT_DOUBLE_EQ(scene.terrainHeight(13.0, -4.0), 0.12);  // the bump ends at the curb
  EXPECT_EQ(scene.terrainHeight(40.0, 2.0), 0.0);
}

TEST(SyntheticScene, OffRoadFeatures) {
  const SceneOptions with = SceneOptions::standard(SceneKind::kOffRoad, 5);
  const SyntheticScene scene(with);
  const SceneOptions& o = scene.options();
  EXPECT_NEAR(scene.terrainHeight(0.0, 0.0), 0.0, 1e-12);  // the vehicle starts at height 0

  // Ruts: 6 cm deep at y = +-0.8, 0.35 m wide; compare with the same scene without ruts.
  SceneOptions no_ruts = with;
  no_ruts.ruts_enabled = false;
  const SyntheticScene smooth(no_ruts);
  for (double x : {2.0, 11.0, 37.5}) {
    for (double yc : {0.8, -0.8}) {
      EXPECT_NEAR(scene.terrainHeight(x, yc) - smooth.terrainHeight(x, yc), -0.06, 1e-12);
      EXPECT_NEAR(scene.terrainHeight(x, yc + 0.35 / 4) - smooth.terrainHeight(x, yc + 0.35 / 4),
                  -0.03, 1e-12);
      EXPECT_EQ(scene.terrainHeight(x, yc + 0.2) - smooth.terrainHeight(x, yc + 0.2), 0.0);
    }
    EXPECT_EQ(scene.terrainHeight(x, 0.0) - smooth.terrainHeight(x, 0.0), 0.0);
  }

  // Terrace: a 0.4 m step on x = 18 (for y > 3) and on y = 3 (for x > 18).
  EXPECT_DOUBLE_EQ(o.terrace_height_m, 0.4);
  for (double x : {20.0, 30.0, 60.0}) {
    EXPECT_NEAR(scene.terrainHeight(x, 3.0 + 1e-9) - scene.terrainHeight(x, 3.0 - 1e-9), 0.4, 1e-6);
  }
  for (double y : {4.0, 8.0}) {
    EXPECT_NEAR(scene.terrainHeight(18.0 + 1e-9, y) - scene.terrainHeight(18.0 - 1e-9, y), 0.4, 1e-6);
  }
  EXPECT_NEAR(scene.terrainHeight(17.0, 2.9) - scene.terrainHeight(17.0, 3.1), 0.0, 0.01);

  // Embankment: 35 degrees, rising 2 m, from y = -6 outwards.
  SceneOptions no_emb = with;
  no_emb.embankment_enabled = false;
  const SyntheticScene flat_side(no_emb);
  const double tan35 = std::tan(35.0 * M_PI / 180.0);
  for (double x : {5.0, 25.0}) {
    EXPECT_NEAR(scene.terrainHeight(x, -7.0) - flat_side.terrainHeight(x, -7.0), tan35, 1e-12);
    EXPECT_NEAR(scene.terrainHeight(x, -12.0) - flat_side.terrainHeight(x, -12.0), 2.0, 1e-12);
    EXPECT_EQ(scene.terrainHeight(x, -5.9) - flat_side.terrainHeight(x, -5.9), 0.0);
  }

  // Rolling terrain: some relief, bounded, and gentle along the driving line.
  SceneOptions rolling_only = SceneOptions::standard(SceneKind::kOffRoad, 5);
  rolling_only.ruts_enabled = rolling_only.terrace_enabled = rolling_only.embankment_enabled = false;
  const SyntheticScene rolling(rolling_only);
  double lo = 1e9, hi = -1e9, max_slope = 0.0;
  for (double x = 0.0; x <= 200.0; x += 0.5) {
    for (double y = -30.0; y <= 30.0; y += 0.5) {
      const double h = rolling.terrainHeight(x, y);
      lo = std::min(lo, h);
      hi = std::max(hi, h);
      if (std::abs(y) < 1.0) max_slope = std::max(max_slope, rolling.terrainGradient(x, y).norm());
    }
  }
  EXPECT_GT(hi - lo, 0.3);
  EXPECT_LT(hi - lo, 1.5);
  EXPECT_LT(max_slope, 0.2);
  EXPECT_GT(max_slope, 0.01);
  EXPECT_GE(lo, rolling.minTerrainHeight());
  EXPECT_LE(hi, rolling.maxTerrainHeight());
}

TEST(SyntheticScene, GradientMatchesNumericDerivative) {
  const SyntheticScene scene(SceneOptions::standard(SceneKind::kOffRoad, 9));
  const SyntheticScene bump(SceneOptions::standard(SceneKind::kBumpAndCurb, 9));
  const double h = 1e-6;
  for (const SyntheticScene* s : {&scene, &bump}) {
    for (double x : {3.3, 12.7, 13.2, 25.1}) {
      for (double y : {-6.5, -0.85, 0.1, 0.75, 3.9, 4.05}) {
        const Eigen::Vector2d g = s->terrainGradient(x, y);
        EXPECT_NEAR(g.x(), (s->terrainHeight(x + h, y) - s->terrainHeight(x - h, y)) / (2 * h), 1e-6);
        EXPECT_NEAR(g.y(), (s->terrainHeight(x, y + h) - s->terrainHeight(x, y - h)) / (2 * h), 1e-6);
      }
    }
  }
}

TEST(SyntheticScene, OptionsValidation) {
  std::string why;
  EXPECT_TRUE(SceneOptions::standard(SceneKind::kOffRoad).isValid(&why)) << why;
  SceneOptions bad = SceneOptions::standard(SceneKind::kOffRoad);
  bad.rut_width_m = 2.0;  // the two ruts would overlap
  EXPECT_FALSE(bad.isValid(&why));
  EXPECT_NE(why.find("rut"), std::string::npos);
  bad = SceneOptions::standard(SceneKind::kFlatRoad);
  bad.boxes.push_back(BoxObstacle());
  bad.boxes.back().width_m = 0.0;
  EXPECT_FALSE(bad.isValid(&why));
  EXPECT_THROW(SyntheticScene{bad}, std::invalid_argument);
}

// ------------------------------------------------------------------------------------------------
// Ray casting

// A ray aimed at a visible terrain point must stop exactly there, and never beyond a point of the
// surface; checked against brute-force dense sampling along random rays.
TEST(SyntheticScene, RayCastingFindsTheFirstHit) {
  for (SceneKind kind : {SceneKind::kBumpAndCurb, SceneKind::kOffRoad}) {
    const SyntheticScene scene(SceneOptions::standard(kind, 11));
    std::mt19937 rng(42);
    std::uniform_real_distribution<double> ux(4.0, 40.0), uy(-9.0, 9.0);
    int exact = 0, total = 0;
    for (int i = 0; i < 150; ++i) {
      const double x = ux(rng), y = uy(rng);
      const Eigen::Vector3d o(0.0, 0.0, 1.65);
      const Eigen::Vector3d target(x, y, scene.terrainHeight(x, y));
      const Eigen::Vector3d d = target - o;
      const auto hit = scene.intersect(o, d, 10.0);
      ASSERT_TRUE(hit.hit());
      EXPECT_LE(hit.t, 1.0 + 1e-9);  // never passes through the surface
      // Brute force: the first sample below the terrain (5 mm steps along the ray).
      const double step = 0.005 / d.norm();
      double t_bf = 1.0;
      for (double t = step; t <= 1.0; t += step) {
        const Eigen::Vector3d p = o + t * d;
        if (p.z() < scene.terrainHeight(p.x(), p.y())) {
          t_bf = t;
          break;
        }
      }
      EXPECT_NEAR(hit.t, t_bf, step + 1e-9) << "ray to " << target.transpose();
      ++total;
      if (std::abs(hit.t - 1.0) < 1e-6) ++exact;
      if (hit.surface == sgd::sim::SurfaceHit::kTerrainTop) {
        EXPECT_NEAR(hit.point.z(), scene.terrainHeight(hit.point.x(), hit.point.y()), 1e-6);
      }
    }
    EXPECT_GT(exact, total * 3 / 4);  // most targets are visible and found exactly
  }
}

TEST(SyntheticScene, VerticalFacesAreHitExactly) {
  const SyntheticScene curb(SceneOptions::standard(SceneKind::kBumpAndCurb, 1));
  const Eigen::Vector3d o(0.0, 0.0, 1.65);
  const Eigen::Vector3d on_face(9.0, -3.75, 0.07);
  const auto hit = curb.intersect(o, on_face - o, 10.0);
  ASSERT_TRUE(hit.hit());
  EXPECT_NEAR((hit.point - on_face).norm(), 0.0, 1e-9);
  EXPECT_NEAR(hit.normal.y(), 1.0, 1e-12);  // facing the road

  const SyntheticScene off(SceneOptions::standard(SceneKind::kOffRoad, 1));
  const double y_face = 3.0;
  const double x = 25.0;
  const double z_mid = 0.5 * (off.terrainHeight(x, y_face - 1e-9) + off.terrainHeight(x, y_face + 1e-9));
  const Eigen::Vector3d terrace(x, y_face, z_mid);
  const auto hit2 = off.intersect(o, terrace - o, 10.0);
  ASSERT_TRUE(hit2.hit());
  EXPECT_NEAR((hit2.point - terrace).norm(), 0.0, 1e-9);
  EXPECT_NEAR(hit2.normal.y(), -1.0, 1e-12);
}

// ------------------------------------------------------------------------------------------------
// Rendering geometry

TEST(StereoRenderer, InverseDepthLandsOnTheTerrain) {
  for (SceneKind kind : {SceneKind::kFlatRoad, SceneKind::kBumpAndCurb, SceneKind::kOffRoad}) {
    const SyntheticScene scene(SceneOptions::standard(kind, 2));
    RenderOptions ro;
    ro.supersampling = 1;
    const auto rig = smallRig();
    const StereoRenderer renderer(scene, rig, ro);
    const Eigen::Isometry3d pose = startPose(scene, 0.05);
    const RenderedImage im = renderer.render(pose);
    int checked = 0, on_face = 0;
    for (int v = 0; v < rig.height; ++v) {
      for (int u = 0; u < rig.width; ++u) {
        const float inv = im.inverse_depth.at<float>(v, u);
        const int label = im.label.at<int>(v, u);
        if (label < 0) {
          EXPECT_EQ(inv, 0.0f);
          continue;
        }
        ASSERT_EQ(label, 0);
        ASSERT_GT(inv, 0.0f);
        const Eigen::Vector3d p = backProject(rig, pose, u, v, inv);
        const double err = std::abs(p.z() - scene.terrainHeight(p.x(), p.y()));
        const SceneOptions& o = scene.options();
        const bool near_step = (o.curb_enabled && std::abs(p.y() - o.curb_y_m) < 1e-3) ||
                               (o.terrace_enabled && (std::abs(p.y() - o.terrace_y_min_m) < 1e-3 ||
                                                      std::abs(p.x() - o.terrace_x_min_m) < 1e-3));
        if (near_step) {
          ++on_face;
          continue;
        }
        EXPECT_LT(err, 1e-3) << "pixel " << u << "," << v << " at " << p.transpose();
        ++checked;
      }
    }
    EXPECT_GT(checked, rig.width * rig.height / 3) << sgd::sim::sceneKindName(kind);
    if (kind == SceneKind::kOffRoad) {
      EXPECT_GT(on_face, 10);  // the terrace step is in view
    }
  }
}

TEST(StereoRenderer, LeftAndRightInverseDepthAgree) {
  for (SceneKind kind : {SceneKind::kFlatRoad, SceneKind::kBumpAndCurb}) {
    const SyntheticScene scene(SceneOptions::standard(kind, 2));
    const SceneOptions& so = scene.options();
    RenderOptions ro;
    ro.supersampling = 1;
    const auto rig = StereoRenderer::kittiLikeRig(0.5);
    const StereoRenderer renderer(scene, rig, ro);
    const Eigen::Isometry3d left_pose = startPose(scene, 0.03);
    const auto pair = renderer.renderPair(left_pose, {}, {}, 0.0, 1);
    const Eigen::Isometry3d right_pose = renderer.rightPose(left_pose);
    EXPECT_NEAR((left_pose.inverse() * right_pose).translation().x(), rig.baseline_m, 1e-12);
    // Planar ground: level, and not on the curb's face.
    auto planar = [&](const Eigen::Vector3d& p) {
      return scene.terrainGradient(p.x(), p.y()).norm() == 0.0 &&
             (!so.curb_enabled || std::abs(p.y() - so.curb_y_m) > 1e-3);
    };
    int checked_planar = 0, checked_curved = 0;
    for (int v = 0; v < rig.height; ++v) {
      for (int u = 0; u < rig.width; ++u) {
        if (pair.left.label.at<int>(v, u) != 0) continue;
        const double inv = pair.left.inverse_depth.at<float>(v, u);
        const double z = 1.0 / inv;
        if (z > 40.0) continue;
        const double ur = u - rig.fx * rig.baseline_m * inv;  // the disparity
        const int u0 = static_cast<int>(std::floor(ur));
        if (u0 < 0 || u0 + 1 >= rig.width) continue;
        if (pair.right.label.at<int>(v, u0) != 0 || pair.right.label.at<int>(v, u0 + 1) != 0) continue;
        const float inv0 = pair.right.inverse_depth.at<float>(v, u0);
        const float inv1 = pair.right.inverse_depth.at<float>(v, u0 + 1);
        const Eigen::Vector3d p_left = backProject(rig, left_pose, u, v, inv);
        const Eigen::Vector3d p0 = backProject(rig, right_pose, u0, v, inv0);
        const Eigen::Vector3d p1 = backProject(rig, right_pose, u0 + 1, v, inv1);
        // Do not interpolate across the curb (the face, or the sidewalk next to the road).
        if (so.curb_enabled && ((p0.y() - so.curb_y_m) * (p1.y() - so.curb_y_m) <= 1e-6 ||
                                (p0.y() - so.curb_y_m) * (p_left.y() - so.curb_y_m) <= 1e-6)) {
          continue;
        }
        // Nor seen at a grazing angle (the side of the bump's tapered end), where neighbouring
        // pixels see points far apart and interpolating between them means nothing.
        if ((p0 - p1).norm() > 3.0 * z / rig.fx) continue;
        // Not occluded in the right view (e.g. the far slope of the bump behind its crest).
        const Eigen::Vector3d c_right = right_pose.translation();
        if (scene.intersect(c_right, p_left - c_right, 2.0).t < 1.0 - 1e-6) continue;
        const double a = ur - u0;
        const Eigen::Vector3d p_right = backProject(rig, right_pose, ur, v, (1 - a) * inv0 + a * inv1);
        // Inverse depth is affine in (u, v) on a plane, so interpolating it is exact there; on
        // the bump the interpolation itself errs by a few millimetres.
        if (planar(p_left) && planar(p0) && planar(p1)) {
          EXPECT_LT((p_left - p_right).norm(), 1e-3 * std::max(1.0, (z / 10.0) * (z / 10.0)))
              << "pixel " << u << "," << v;
          ++checked_planar;
        } else {
          EXPECT_LT((p_left - p_right).norm(), 0.01) << "pixel " << u << "," << v;
          ++checked_curved;
        }
      }
    }
    EXPECT_GT(checked_planar, 10000);
    if (kind == SceneKind::kBumpAndCurb) {
      EXPECT_GT(checked_curved, 500);
    }
  }
}

// ------------------------------------------------------------------------------------------------
// Image formation

TEST(StereoRenderer, GainAndBias) {
  const SyntheticScene scene(SceneOptions::standard(SceneKind::kBumpAndCurb, 4));
  RenderOptions ro;
  ro.noise_std_grey = 0.0;
  const auto rig = smallRig();
  const StereoRenderer renderer(scene, rig, ro);
  const Eigen::Isometry3d pose = startPose(scene);
  const RenderedImage base = renderer.render(pose);
  for (const auto& [gain, bias] : {std::pair{0.8, 20.0}, std::pair{0.6, -5.0}, std::pair{1.2, -25.0}}) {
    const RenderedImage im = renderer.render(pose, {gain, bias});
    int clamped = 0, compared = 0;
    // Both images are rounded: |gain * e1 - e2| <= gain / 2 + 1 / 2 (= 1 for gain <= 1).
    const double tol = std::max(1.0, 0.5 * gain + 0.5) + 1e-9;
    for (int v = 0; v < rig.height; ++v) {
      for (int u = 0; u < rig.width; ++u) {
        const int out = im.image.at<uint8_t>(v, u);
        // Against the noise-free albedo (stored as float: allow its rounding).
        const double exact = gain * base.albedo.at<float>(v, u) + bias;
        if (exact < 0.0) {
          EXPECT_EQ(out, 0);
        } else if (exact > 255.0) {
          EXPECT_EQ(out, 255);
        } else {
          EXPECT_NEAR(out, exact, 0.5 + 1e-4);
        }
        if (out == 0 || out == 255) {
          ++clamped;
          continue;
        }
        EXPECT_LE(std::abs(out - (gain * base.image.at<uint8_t>(v, u) + bias)), tol);
        ++compared;
      }
    }
    EXPECT_GT(compared, rig.width * rig.height / 2);
    EXPECT_LT(clamped, rig.width * rig.height / 2);
  }
  // The noise has the requested standard deviation.
  RenderOptions noisy = ro;
  noisy.noise_std_grey = 2.0;
  const RenderedImage n = StereoRenderer(scene, rig, noisy).render(pose, {}, 0.0, 5);
  cv::Mat diff;
  n.image.convertTo(diff, CV_32F);
  diff -= base.albedo;
  cv::Scalar mean, stddev;
  cv::meanStdDev(diff, mean, stddev);
  EXPECT_NEAR(mean[0], 0.0, 0.1);
  EXPECT_NEAR(stddev[0], std::sqrt(4.0 + 1.0 / 12.0), 0.15);  // noise + rounding
  double lo, hi;
  cv::minMaxLoc(base.image, &lo, &hi);
  EXPECT_GE(lo, 25.0);  // albedo roughly 40..220, sky included
  EXPECT_LE(hi, 235.0);
}

TEST(StereoRenderer, SupersamplingAgreesOnDistantGround) {
  const SyntheticScene scene(SceneOptions::standard(SceneKind::kFlatRoad, 6));
  const auto rig = StereoRenderer::kittiLikeRig(0.5);  // 613 x 185
  RenderOptions ss2;
  ss2.noise_std_grey = 0.0;
  RenderOptions ss4 = ss2;
  ss4.supersampling = 4;
  RenderOptions aliased = ss2;
  aliased.anisotropy = 0.0;  // band limit to the minor axis only: aliases
  RenderOptions aliased4 = aliased;
  aliased4.supersampling = 4;
  const Eigen::Isometry3d pose = startPose(scene);
  const RenderedImage a = StereoRenderer(scene, rig, ss2).render(pose);
  const RenderedImage b = StereoRenderer(scene, rig, ss4).render(pose);
  cv::Mat far = (a.label == 0) & (a.inverse_depth < 1.0f / 30.0f) & (a.inverse_depth > 1.0f / 80.0f);
  ASSERT_GT(cv::countNonZero(far), 2000);
  const double mad = meanAbsDiff(a.albedo, b.albedo, far);
  // Measured 1.0 grey with the default band limit, 8.8 with anisotropy 0 (texture std ~20 grey).
  EXPECT_LT(mad, 1.5);
  const RenderedImage c = StereoRenderer(scene, rig, aliased).render(pose);
  const RenderedImage d = StereoRenderer(scene, rig, aliased4).render(pose);
  EXPECT_GT(meanAbsDiff(c.albedo, d.albedo, far), 2.0 * mad);  // the test can see aliasing

  // Texture contrast near and far: std over a patch and mean horizontal gradient.
  auto patchStats = [&](double z_min, double z_max, double* grad) {
    cv::Mat mask = (a.label == 0) & (a.inverse_depth < 1.0f / z_min) & (a.inverse_depth > 1.0f / z_max);
    // Only the road, around the image centre column.
    mask.colRange(0, static_cast<int>(rig.cx) - 40).setTo(0);
    mask.colRange(static_cast<int>(rig.cx) + 40, rig.width).setTo(0);
    cv::Scalar mean, stddev;
    cv::meanStdDev(a.albedo, mean, stddev, mask);
    cv::Mat du = cv::abs(a.albedo.colRange(1, rig.width) - a.albedo.colRange(0, rig.width - 1));
    *grad = cv::mean(du, mask.colRange(0, rig.width - 1))[0];
    return stddev[0];
  };
  double grad_near = 0.0, grad_far = 0.0;
  EXPECT_GT(patchStats(5.0, 10.0, &grad_near), 5.0);
  EXPECT_GT(patchStats(30.0, 50.0, &grad_far), 3.0);
  EXPECT_GT(grad_near, 2.0);
  EXPECT_GT(grad_far, 0.8);
}

TEST(StereoRenderer, Determinism) {
  const auto rig = smallRig();
  const SyntheticScene s1(SceneOptions::standard(SceneKind::kOffRoad, 1));
  const SyntheticScene s1b(SceneOptions::standard(SceneKind::kOffRoad, 1));
  const SyntheticScene s2(SceneOptions::standard(SceneKind::kOffRoad, 2));
  const Eigen::Isometry3d pose = StereoRenderer::lookingPose({0.0, 0.0, 1.65});
  const RenderedImage a = StereoRenderer(s1, rig).render(pose, {}, 0.0, 9);
  const RenderedImage b = StereoRenderer(s1b, rig).render(pose, {}, 0.0, 9);
  EXPECT_EQ(cv::norm(a.image, b.image, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(a.inverse_depth, b.inverse_depth, cv::NORM_INF), 0.0);
  // The thread count does not matter.
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);
  const RenderedImage c = StereoRenderer(s1, rig).render(pose, {}, 0.0, 9);
  cv::setNumThreads(threads);
  EXPECT_EQ(cv::norm(a.image, c.image, cv::NORM_INF), 0.0);
  // Another noise seed: other noise, same scene.
  const RenderedImage n = StereoRenderer(s1, rig).render(pose, {}, 0.0, 10);
  EXPECT_GT(cv::norm(a.image, n.image, cv::NORM_L1), 0.3 * rig.width * rig.height);
  EXPECT_EQ(cv::norm(a.albedo, n.albedo, cv::NORM_INF), 0.0);
  // Another scene seed: another texture.
  const RenderedImage d = StereoRenderer(s2, rig).render(pose, {}, 0.0, 9);
  const cv::Mat ground = (a.label == 0) & (d.label == 0);
  EXPECT_GT(meanAbsDiff(a.albedo, d.albedo, ground), 5.0);
}

// ------------------------------------------------------------------------------------------------
// Obstacles

TEST(SyntheticScene, ObstacleFootprints) {
  SceneOptions o = SceneOptions::standard(SceneKind::kBumpAndCurb);
  BoxObstacle box;
  box.center_xy = {15.0, 0.0};
  box.yaw_rad = M_PI / 4;
  box.length_m = 4.0;
  box.width_m = 2.0;
  box.height_m = 1.5;
  BoxObstacle moving;
  moving.center_xy = {30.0, 2.0};
  moving.velocity_xy = {5.0, 0.0};
  PoleObstacle pole;
  pole.xy = {10.0, 5.0};
  pole.radius_m = 0.2;
  o.boxes = {box, moving};
  o.poles = {pole};
  const SyntheticScene scene(o);
  EXPECT_EQ(scene.obstacleCount(), 3);
  const double c = std::cos(M_PI / 4), s = std::sin(M_PI / 4);
  EXPECT_EQ(scene.obstacleIdAt(15.0 + 1.9 * c, 1.9 * s), 1);  // along the length axis
  EXPECT_EQ(scene.obstacleIdAt(15.0 - 0.9 * s, 0.9 * c), 1);  // across
  EXPECT_EQ(scene.obstacleIdAt(15.0 - 1.1 * s, 1.1 * c), 0);
  EXPECT_FALSE(scene.insideObstacleFootprint(15.0 + 2.1 * c, 2.1 * s));
  EXPECT_TRUE(scene.insideObstacleFootprint(30.0, 2.0, 0.0));
  EXPECT_FALSE(scene.insideObstacleFootprint(30.0, 2.0, 2.0));
  EXPECT_EQ(scene.obstacleIdAt(40.0, 2.0, 2.0), 2);  // moved 10 m in 2 s
  EXPECT_EQ(scene.obstacleIdAt(10.1, 5.1), 3);
  EXPECT_EQ(scene.obstacleIdAt(10.2, 5.2), 0);
  EXPECT_DOUBLE_EQ(scene.surfaceHeight(15.0, 0.0), 1.5);
  EXPECT_DOUBLE_EQ(scene.surfaceHeight(10.0, 5.0), 3.0);
  EXPECT_DOUBLE_EQ(scene.surfaceHeight(20.0, -1.0), 0.0);
}

TEST(StereoRenderer, BoxOccludesTheGround) {
  SceneOptions o = SceneOptions::standard(SceneKind::kFlatRoad);
  BoxObstacle box;
  box.center_xy = {15.0, 0.0};
  box.length_m = 4.0;
  box.width_m = 2.0;
  box.height_m = 1.5;
  box.velocity_xy = {2.5, 0.0};
  PoleObstacle pole;
  pole.xy = {12.0, 4.0};
  pole.radius_m = 0.15;
  pole.height_m = 3.0;
  o.boxes = {box};
  o.poles = {pole};
  const SyntheticScene scene(o);
  const auto rig = smallRig();
  RenderOptions ro;
  ro.supersampling = 1;
  const StereoRenderer renderer(scene, rig, ro);
  const Eigen::Isometry3d pose = StereoRenderer::lookingPose({0.0, 0.0, 1.65});
  auto pixelOf = [&](const Eigen::Vector3d& g) {
    const Eigen::Vector3d c = pose.inverse() * g;
    return Eigen::Vector2d(rig.fx * c.x() / c.z() + rig.cx, rig.fy * c.y() / c.z() + rig.cy);
  };
  for (double t : {0.0, 2.0}) {
    const RenderedImage im = renderer.render(pose, {}, t);
    const double front = 15.0 + 2.5 * t - 2.0;  // the box's rear face, seen by the camera
    // The face centre: the box, at depth `front` (the camera looks along +x).
    const Eigen::Vector2d px = pixelOf({front, 0.0, 0.75});
    const int u = static_cast<int>(std::lround(px.x())), v = static_cast<int>(std::lround(px.y()));
    EXPECT_EQ(im.label.at<int>(v, u), 1);
    EXPECT_NEAR(1.0 / im.inverse_depth.at<float>(v, u), front, 1e-4);
    // Pixels of ground just behind the box: hidden.
    const Eigen::Vector2d behind = pixelOf({front + 1.0, 0.0, 0.0});
    EXPECT_EQ(im.label.at<int>(static_cast<int>(std::lround(behind.y())),
                               static_cast<int>(std::lround(behind.x()))), 1);
    // Ground in front of the box: terrain.
    const Eigen::Vector2d before = pixelOf({front - 2.0, 0.0, 0.0});
    EXPECT_EQ(im.label.at<int>(static_cast<int>(std::lround(before.y())),
                               static_cast<int>(std::lround(before.x()))), 0);
    // The pole, id 2, at depth 12 - radius on its axis line.
    const Eigen::Vector2d pp = pixelOf({12.0, 4.0, 1.5});
    const int pu = static_cast<int>(std::lround(pp.x())), pv = static_cast<int>(std::lround(pp.y()));
    EXPECT_EQ(im.label.at<int>(pv, pu), 2);
    const double z = 1.0 / im.inverse_depth.at<float>(pv, pu);
    EXPECT_GT(z, 12.0 - 0.15 - 1e-6);
    EXPECT_LT(z, 12.0);
    // Every obstacle pixel back-projects onto the surface of its obstacle.
    int n = 0;
    for (int vv = 0; vv < rig.height; ++vv) {
      for (int uu = 0; uu < rig.width; ++uu) {
        const int id = im.label.at<int>(vv, uu);
        if (id <= 0) continue;
        const Eigen::Vector3d p = backProject(rig, pose, uu, vv, im.inverse_depth.at<float>(vv, uu));
        const double tol = 1e-4 * p.norm();
        if (id == 1) {
          const Eigen::Vector2d c = box.centerAt(t);
          EXPECT_LE(std::abs(p.x() - c.x()), 2.0 + tol);
          EXPECT_LE(std::abs(p.y() - c.y()), 1.0 + tol);
          EXPECT_LE(p.z(), 1.5 + tol);
          // On one of the faces the camera can see: the rear face, the sides or the top.
          const bool on_face = std::abs(p.x() - (c.x() - 2.0)) < tol ||
                               std::abs(std::abs(p.y() - c.y()) - 1.0) < tol ||
                               std::abs(p.z() - 1.5) < tol;
          EXPECT_TRUE(on_face) << p.transpose();
        } else {
          ASSERT_EQ(id, 2);
          EXPECT_NEAR((p.head<2>() - pole.xy).norm(), pole.radius_m, tol);
          EXPECT_LE(p.z(), 3.0 + tol);
        }
        ++n;
      }
    }
    EXPECT_GT(n, 100);
  }
}

// ------------------------------------------------------------------------------------------------
// Sequences and export

TEST(SequenceGenerator, VehicleOnTheTerrain) {
  const SyntheticScene flat(SceneOptions::standard(SceneKind::kFlatRoad));
  SequenceOptions o;
  o.frames = 5;
  o.camera_pitch_down_rad = 0.1;
  const SequenceGenerator gen(flat, smallRig(), o);
  ASSERT_EQ(gen.frames().size(), 5u);
  for (const auto& f : gen.frames()) {
    EXPECT_NEAR(f.ground_T_left.translation().x(), f.index * 1.0, 1e-12);
    EXPECT_NEAR(f.ground_T_left.translation().z(), 1.65, 1e-12);
    EXPECT_NEAR(f.time_s, 0.1 * f.index, 1e-12);
    const Eigen::Vector3d axis = f.ground_T_left.linear().col(2);  // optical axis
    EXPECT_NEAR(axis.z(), -std::sin(0.1), 1e-12);
    EXPECT_NEAR(axis.x(), std::cos(0.1), 1e-12);
    EXPECT_NEAR(f.ground_T_left.linear().col(0).y(), -1.0, 1e-12);  // x_camera = right = -y
  }
  // On the off-road scene the camera stays camera_height_m above the ground plane under it.
  const SyntheticScene off(SceneOptions::standard(SceneKind::kOffRoad, 3));
  SequenceOptions oo;
  oo.frames = 30;
  oo.gain_start = 0.75;
  oo.gain_end = 1.25;
  oo.right_gain_ratio = 1.1;
  oo.yaw_rate_rad_per_frame = -0.01;  // turning right, away from the terrace
  const SequenceGenerator g2(off, smallRig(), oo);
  for (const auto& f : g2.frames()) {
    const Eigen::Vector3d c = f.ground_T_left.translation();
    EXPECT_NEAR(c.z() - off.terrainHeight(c.x(), c.y()), 1.65, 0.1);
    EXPECT_NEAR(f.ground_T_left.linear().determinant(), 1.0, 1e-12);
    EXPECT_NEAR(f.right.gain / f.left.gain, 1.1, 1e-12);
  }
  EXPECT_DOUBLE_EQ(g2.frames().front().left.gain, 0.75);
  EXPECT_DOUBLE_EQ(g2.frames().back().left.gain, 1.25);
  // Heading after 29 frames at 0.01 rad/frame.
  const Eigen::Vector3d axis = g2.frames().back().ground_T_left.linear().col(2);
  EXPECT_NEAR(std::atan2(axis.y(), axis.x()), -0.29, 0.02);
}

TEST(SequenceGenerator, KittiFolderRoundTrip) {
  TempDir dir;
  SceneOptions so = SceneOptions::standard(SceneKind::kBumpAndCurb, 77);
  so.addStandardObstacles();
  const SyntheticScene scene(so);
  SequenceOptions o;
  o.frames = 3;
  o.gain_start = 0.9;
  o.gain_end = 1.1;
  o.right_bias_grey = 3.0;
  const auto rig = smallRig();
  const SequenceGenerator gen(scene, rig, o);
  gen.writeKitti(dir.path());
  const std::string d = dir.path() + "/";

  const sgd::StereoRig back = sgd::CalibrationReader::read(d + "calib.txt");
  EXPECT_NEAR(back.fx, rig.fx, 1e-9);
  EXPECT_NEAR(back.fy, rig.fy, 1e-9);
  EXPECT_NEAR(back.cx, rig.cx, 1e-9);
  EXPECT_NEAR(back.cy, rig.cy, 1e-9);
  EXPECT_NEAR(back.baseline_m, rig.baseline_m, 1e-12);

  const auto poses = readNumbers(d + "poses.txt");
  ASSERT_EQ(poses.size(), 3u);
  for (int i = 0; i < 12; ++i) {
    ASSERT_EQ(poses[0].size(), 12u);
    EXPECT_NEAR(poses[0][static_cast<size_t>(i)], (i % 5 == 0) ? 1.0 : 0.0, 1e-12);
  }
  // Frame 2 is 2 m ahead along the optical axis of camera 0 (level road).
  EXPECT_NEAR(poses[2][3], 0.0, 1e-9);
  EXPECT_NEAR(poses[2][7], 0.0, 1e-9);
  EXPECT_NEAR(poses[2][11], 2.0, 1e-9);

  const auto g = readNumbers(d + "ground_T_camera0.txt");
  ASSERT_EQ(g.size(), 1u);
  ASSERT_EQ(g[0].size(), 16u);
  const Eigen::Matrix4d m = gen.frames()[0].ground_T_left.matrix();
  for (int i = 0; i < 16; ++i) EXPECT_NEAR(g[0][static_cast<size_t>(i)], m(i / 4, i % 4), 1e-12);

  const auto times = readNumbers(d + "times.txt");
  ASSERT_EQ(times.size(), 3u);
  EXPECT_NEAR(times[2][0], 0.2, 1e-12);
  const auto photo = readNumbers(d + "photometry.txt");
  ASSERT_EQ(photo.size(), 3u);
  EXPECT_NEAR(photo[1][0], 1.0, 1e-12);
  EXPECT_NEAR(photo[1][3], 3.0, 1e-12);

  for (int k = 0; k < 3; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", k);
    const cv::Mat l = cv::imread(d + "image_0/" + name, cv::IMREAD_UNCHANGED);
    const cv::Mat r = cv::imread(d + "image_1/" + name, cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(l.empty());
    ASSERT_FALSE(r.empty());
    EXPECT_EQ(l.type(), CV_8U);
    EXPECT_EQ(l.cols, rig.width);
    EXPECT_EQ(l.rows, rig.height);
    EXPECT_GT(cv::norm(l, r, cv::NORM_L1), 0.0);
    if (k == 1) {
      const auto pair = gen.render(1);
      EXPECT_EQ(cv::norm(l, pair.left.image, cv::NORM_INF), 0.0);
      const cv::Mat disp = cv::imread(d + "disp_0/" + name, cv::IMREAD_UNCHANGED);
      ASSERT_EQ(disp.type(), CV_16U);
      const int u = rig.width / 2, v = rig.height - 5;
      EXPECT_NEAR(disp.at<uint16_t>(v, u) / 256.0,
                  rig.fx * rig.baseline_m * pair.left.inverse_depth.at<float>(v, u), 0.5 / 256.0);
    }
  }

  // The scene rebuilds exactly.
  const SyntheticScene again = SyntheticScene::fromYaml(d + "scene.yaml");
  EXPECT_EQ(again.options().seed, 77u);
  EXPECT_EQ(again.options().kind, SceneKind::kBumpAndCurb);
  EXPECT_EQ(again.options().boxes.size(), so.boxes.size());
  EXPECT_EQ(again.options().poles.size(), so.poles.size());
  EXPECT_EQ(again.options().curb_y_m, so.curb_y_m);
  EXPECT_EQ(again.options().embankment_slope_rad, so.embankment_slope_rad);
  EXPECT_TRUE(again.options().boxes[1].velocity_xy == so.boxes[1].velocity_xy);
  for (double x : {5.0, 12.9, 13.3, 40.0}) {
    for (double y : {-4.0, -1.0, 2.0, 4.1}) {
      EXPECT_EQ(again.terrainHeight(x, y), scene.terrainHeight(x, y));
      EXPECT_EQ(again.surfaceHeight(x, y, 0.3), scene.surfaceHeight(x, y, 0.3));
    }
  }
  const SyntheticScene off(SceneOptions::standard(SceneKind::kOffRoad, 1234567890123ULL));
  off.toYaml(d + "off.yaml");
  const SyntheticScene off2 = SyntheticScene::fromYaml(d + "off.yaml");
  EXPECT_EQ(off2.options().seed, 1234567890123ULL);
  EXPECT_EQ(off2.terrainHeight(23.4, 5.6), off.terrainHeight(23.4, 5.6));
  EXPECT_EQ(off2.terrainHeight(3.4, -7.6), off.terrainHeight(3.4, -7.6));

  // Errors name the file.
  std::ofstream(d + "bad.yaml") << "%YAML:1.0\nkind: \"moon\"\n";
  try {
    SyntheticScene::fromYaml(d + "bad.yaml");
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.yaml"), std::string::npos);
  }
}

#ifdef SGD_RENDER_EXE
TEST(RenderCli, WritesAFolderAndRejectsBadArguments) {
  TempDir dir;
  const std::string exe = SGD_RENDER_EXE;
  const std::string out = dir.path() + "/seq";
  const std::string ok_cmd = exe + " --scene offroad --frames 2 --out " + out +
                             " --scale 0.1 --obstacles --gain-drift --quiet";
  ASSERT_EQ(std::system(ok_cmd.c_str()), 0);
  EXPECT_TRUE(std::filesystem::exists(out + "/image_0/000001.png"));
  EXPECT_TRUE(std::filesystem::exists(out + "/image_1/000001.png"));
  EXPECT_TRUE(std::filesystem::exists(out + "/scene.yaml"));
  EXPECT_EQ(SyntheticScene::fromYaml(out + "/scene.yaml").obstacleCount(), 5);
  const auto photo = readNumbers(out + "/photometry.txt");
  ASSERT_EQ(photo.size(), 2u);
  EXPECT_NEAR(photo[0][0], 0.75, 1e-12);
  EXPECT_NEAR(photo[1][0], 1.25, 1e-12);
  for (const std::string& args : std::vector<std::string>{"--scene moon --frames 1 --out " + out, "--frames 1 --out " + out,
                                 "--scene flat --frames x --out " + out,
                                 "--scene flat --frames 0 --out " + out, "--scene flat --frames 1",
                                 "--scene flat --frames 1 --out " + out + " --bogus"}) {
    const std::string cmd = exe + " " + args + " 2>/dev/null";
    EXPECT_NE(std::system(cmd.c_str()), 0) << args;
  }
}
#endif
