// Tests of the scene zoo (ScenePreset): for every scene, exact ray casting against the height
// field, the YAML round trip, the disparity and label truth against the geometry, the trajectory
// along the road, determinism; the bounce scene's attitude changes; cast shadows; RoadPath.

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

#include "stereo_ground_dem/sim/RoadPath.hpp"
#include "stereo_ground_dem/sim/ScenePreset.hpp"
#include "stereo_ground_dem/sim/SequenceGenerator.hpp"
#include "stereo_ground_dem/sim/StereoRenderer.hpp"
#include "stereo_ground_dem/sim/SyntheticScene.hpp"

namespace sgd = stereo_ground_dem;
using sgd::sim::RenderOptions;
using sgd::sim::RoadPath;
using sgd::sim::RoadPathOptions;
using sgd::sim::SceneKind;
using sgd::sim::SceneOptions;
using sgd::sim::ScenePreset;
using sgd::sim::SequenceGenerator;
using sgd::sim::SequenceOptions;
using sgd::sim::StereoRenderer;
using sgd::sim::SurfaceHit;
using sgd::sim::SyntheticScene;

namespace {

constexpr double kDeg = M_PI / 180.0;

const std::vector<SceneKind> kZoo = {SceneKind::kCrest,      SceneKind::kSag,
                                     SceneKind::kBankedCurve, SceneKind::kBounce,
                                     SceneKind::kTightCurve,  SceneKind::kRamp,
                                     SceneKind::kRolling,     SceneKind::kShadows,
                                     SceneKind::kTraffic};

std::vector<SceneKind> everyScene() { return sgd::sim::allSceneKinds(); }

std::string nameOf(SceneKind k) { return sgd::sim::sceneKindName(k); }

class TempDir {
 public:
  TempDir() {
    char name[] = "/tmp/sgd_zoo_test_XXXXXX";
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

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

SequenceGenerator generator(const SyntheticScene& scene, const ScenePreset& p, int frames,
                            double rig_scale = 0.1, int supersampling = 1) {
  SequenceOptions q = p.sequence;
  q.frames = frames;
  RenderOptions ro;
  ro.supersampling = supersampling;
  return SequenceGenerator(scene, StereoRenderer::kittiLikeRig(rig_scale), q, ro);
}

// Heading of the camera's optical axis in the ground plane [rad].
double cameraHeading(const Eigen::Isometry3d& ground_T_camera) {
  const Eigen::Vector3d z = ground_T_camera.linear().col(2);
  return std::atan2(z.y(), z.x());
}

double wrap(double a) { return std::remainder(a, 2.0 * M_PI); }

}  // namespace

// ------------------------------------------------------------------------------------------------
// RoadPath

TEST(RoadPath, PosesAreContinuousAndCoordinatesInvertThem) {
  RoadPathOptions o;
  o.anchor_xy_m = {3.0, -2.0};
  o.anchor_heading_rad = 0.4;
  o.start_s_m = -30.0;
  o.pieces = {{20.0, 0.0}, {40.0, 1.0 / 25.0}, {15.0, 0.0}, {30.0, -1.0 / 40.0}};
  const RoadPath path(o);
  EXPECT_DOUBLE_EQ(path.startS(), -30.0);
  EXPECT_DOUBLE_EQ(path.endS(), 75.0);
  const RoadPath::Pose a = path.poseAt(0.0);
  EXPECT_NEAR((a.xy - o.anchor_xy_m).norm(), 0.0, 1e-12);
  EXPECT_NEAR(a.heading_rad, 0.4, 1e-12);
  // Continuous position and heading at the joins; the curvature of each piece.
  for (double s : {-10.0, 30.0, 45.0}) {
    const RoadPath::Pose before = path.poseAt(s - 1e-7), after = path.poseAt(s + 1e-7);
    EXPECT_NEAR((before.xy - after.xy).norm(), 2e-7, 1e-9) << s;
    EXPECT_NEAR(before.heading_rad, after.heading_rad, 1e-8) << s;
  }
  EXPECT_DOUBLE_EQ(path.poseAt(10.0).curvature_per_m, 1.0 / 25.0);
  // The arc turns by its length times its curvature.
  EXPECT_NEAR(path.poseAt(30.0).heading_rad - path.poseAt(-10.0).heading_rad, 40.0 / 25.0, 1e-12);
  // (s, n) -> point -> (s, n), near the path, on every piece and beyond the ends.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> us(-45.0, 90.0), un(-6.0, 6.0);
  for (int i = 0; i < 500; ++i) {
    const double s = us(rng), n = un(rng);
    const RoadPath::Pose p = path.poseAt(s);
    const Eigen::Vector2d q = p.xy + n * p.normal();
    const RoadPath::Coordinates c = path.coordinates(q.x(), q.y());
    EXPECT_NEAR(c.s_m, s, 1e-9) << s << " " << n;
    EXPECT_NEAR(c.n_m, n, 1e-9) << s << " " << n;
    EXPECT_NEAR(wrap(c.heading_rad - p.heading_rad), 0.0, 1e-12);
  }
}

TEST(RoadPath, ParallelLaneDistance) {
  RoadPathOptions o;
  o.start_s_m = -10.0;
  o.pieces = {{10.0, 0.0}, {50.0, -1.0 / 20.0}, {100.0, 0.0}};
  const RoadPath path(o);
  // On the straight part the parallel is as long as the centreline; on the right curve, a lane
  // 2 m to the right is on radius 18: 18 / 20 of the centreline's length.
  EXPECT_NEAR(path.arcLengthAfter(-2.0, 0.0), 0.0, 1e-12);
  EXPECT_NEAR(path.arcLengthAfter(-2.0, 9.0), 9.0 * 20.0 / 18.0, 1e-12);
  EXPECT_NEAR(path.arcLengthAfter(-2.0, 45.0 + 5.0), 50.0 + 5.0, 1e-12);
  EXPECT_NEAR(path.arcLengthAfter(-2.0, -7.0), -7.0, 1e-12);
  EXPECT_NEAR(path.arcLengthAfter(3.0, 11.5), 11.5 * 20.0 / 23.0, 1e-12);
}

// ------------------------------------------------------------------------------------------------
// Terrain of the zoo scenes

TEST(SceneZoo, ProfileBankingAndWavesHaveTheirDesignedHeights) {
  const SyntheticScene crest(ScenePreset::forKind(SceneKind::kCrest).scene);
  const SyntheticScene sag(ScenePreset::forKind(SceneKind::kSag).scene);
  const double y = -1.0;  // off the bump's x range below, the road is the profile alone
  // +4 % to -4 % over [10, 70]: z(10) = 0.4, top at x = 40 (z = 1.0), z(70) = 0.4.
  EXPECT_NEAR(crest.terrainHeight(0.0, y), 0.0, 1e-12);
  EXPECT_NEAR(crest.terrainHeight(10.0, y), 0.4, 1e-12);
  EXPECT_NEAR(crest.terrainHeight(40.0, y), 1.0, 1e-12);
  EXPECT_NEAR(crest.terrainHeight(70.0, y), 0.4, 1e-12);
  EXPECT_NEAR(crest.terrainGradient(5.0, y).x(), 0.04, 1e-12);
  EXPECT_NEAR(crest.terrainGradient(40.0, y).x(), 0.0, 1e-12);
  EXPECT_NEAR(crest.terrainGradient(100.0, y).x(), -0.04, 1e-12);
  EXPECT_NEAR(crest.terrainHeight(1000.0, y), -4.0, 1e-9);  // level far away
  EXPECT_NEAR(sag.terrainHeight(40.0, y), -1.0, 1e-12);
  EXPECT_NEAR(sag.terrainHeight(40.0, y) + crest.terrainHeight(40.0, y), 0.0, 1e-12);
  // The bump rides on the profile.
  SceneOptions no_bump = ScenePreset::forKind(SceneKind::kCrest).scene;
  no_bump.bump_enabled = false;
  EXPECT_NEAR(crest.terrainHeight(30.0, 0.0) - SyntheticScene(no_bump).terrainHeight(30.0, 0.0), 0.10, 1e-12);

  // Banking: 5 % across the road, higher outside the left curve (to the right, y < 0 near x = 0).
  const ScenePreset bp = ScenePreset::forKind(SceneKind::kBankedCurve);
  const SyntheticScene banked(bp.scene);
  const Eigen::Vector2d c = bp.scene.bank_center_xy_m;
  for (double rho : {-4.0, -1.0, 0.0, 1.5, 4.9}) {
    const Eigen::Vector2d q = c + (bp.scene.bank_radius_m + rho) * Eigen::Vector2d(std::sin(0.3), -std::cos(0.3));
    EXPECT_NEAR(banked.terrainHeight(q.x(), q.y()), 0.05 * rho, 1e-12) << rho;
  }
  const double top = 0.05 * (bp.scene.bank_half_width_m + 0.5 * bp.scene.bank_transition_m);
  EXPECT_NEAR(banked.terrainHeight(0.0, -30.0), top, 1e-12);       // level beyond the transition
  EXPECT_NEAR(banked.terrainHeight(0.0, 30.0), -top, 1e-12);
  EXPECT_NEAR(banked.terrainHeight(c.x(), c.y()), -top, 1e-12);    // the centre of the curve

  // Washboard (bounce): 4 cm every 2.7 m; the rolling scene's ditch: 35 cm deep.
  const ScenePreset bo = ScenePreset::forKind(SceneKind::kBounce);
  SceneOptions washboard_only = bo.scene;
  washboard_only.rolling_enabled = false;
  washboard_only.potholes.clear();
  const SyntheticScene wb(washboard_only);
  EXPECT_NEAR(wb.terrainHeight(-10.0 + 1.35, 0.0), 0.04, 1e-12);
  EXPECT_NEAR(wb.terrainHeight(-10.0 + 2.7 * 10, 0.0), 0.0, 1e-12);
  EXPECT_NEAR(wb.terrainHeight(-10.0 + 2.7 * 10 + 1.35, 0.0), 0.04, 1e-12);
  EXPECT_EQ(wb.terrainHeight(-10.1, 0.0), 0.0);
  SceneOptions ditch_only = ScenePreset::forKind(SceneKind::kRolling).scene;
  ditch_only.rolling_enabled = ditch_only.ruts_enabled = false;
  ditch_only.profile_curves.clear();
  const SyntheticScene ditch(ditch_only);
  EXPECT_NEAR(ditch.terrainHeight(16.5, 0.0), -0.35, 1e-12);
  EXPECT_EQ(ditch.terrainHeight(13.9, 0.0), 0.0);
}

TEST(SceneZoo, RollingGradesReachFifteenPercent) {
  for (uint64_t seed : {1, 2, 3}) {
    const SyntheticScene s(ScenePreset::forKind(SceneKind::kRolling, seed).scene);
    double max_grade = 0.0, lo = 1e9, hi = -1e9;
    for (double x = 0.0; x <= 120.0; x += 0.25) {
      if (x > 13.0 && x < 20.0) continue;  // the ditch
      max_grade = std::max(max_grade, std::abs(s.terrainGradient(x, 0.0).x()));
      lo = std::min(lo, s.terrainHeight(x, 0.0));
      hi = std::max(hi, s.terrainHeight(x, 0.0));
    }
    EXPECT_GT(max_grade, 0.13) << seed;
    EXPECT_LT(max_grade, 0.22) << seed;
    EXPECT_GT(hi - lo, 2.0) << seed;  // visibly hilly
  }
}

TEST(SceneZoo, GradientMatchesNumericDerivative) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> ux(-20.0, 120.0), uy(-25.0, 25.0);
  for (SceneKind kind : kZoo) {
    const SyntheticScene s(ScenePreset::forKind(kind).scene);
    const double h = 1e-6;
    int checked = 0;
    for (int i = 0; i < 300; ++i) {
      const double x = ux(rng), y = uy(rng);
      const double zx0 = s.terrainHeight(x - h, y), zx1 = s.terrainHeight(x + h, y);
      const double zy0 = s.terrainHeight(x, y - h), zy1 = s.terrainHeight(x, y + h);
      // Skip samples next to a step (curb): the smooth part is what the gradient describes.
      if (std::abs(zx1 - zx0) > 1e-3 || std::abs(zy1 - zy0) > 1e-3) continue;
      const Eigen::Vector2d g = s.terrainGradient(x, y);
      EXPECT_NEAR(g.x(), (zx1 - zx0) / (2 * h), 2e-6) << nameOf(kind) << " " << x << " " << y;
      EXPECT_NEAR(g.y(), (zy1 - zy0) / (2 * h), 2e-6) << nameOf(kind) << " " << x << " " << y;
      ++checked;
    }
    EXPECT_GT(checked, 250) << nameOf(kind);
  }
}

// Rays from the cameras of the drive into the scene: a terrain hit lies on the height field to
// 1e-6 m, and it is the first crossing (brute force, 2 cm steps along the ray).
TEST(SceneZoo, RayHitsAreExactAndFirst) {
  for (SceneKind kind : everyScene()) {
    const ScenePreset p = ScenePreset::forKind(kind, 4);
    const SyntheticScene scene(p.scene);
    const SequenceGenerator gen = generator(scene, p, 31);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> uu(-0.8, 0.8), uv(0.02, 0.35);
    int hits = 0;
    for (int k : {0, 15, 30}) {
      const Eigen::Isometry3d pose = gen.frames()[static_cast<size_t>(k)].ground_T_left;
      const Eigen::Vector3d o = pose.translation();
      for (int i = 0; i < 40; ++i) {
        // Directions in the camera's view below the horizon: x right, y down, z forward.
        const Eigen::Vector3d d = pose.linear() * Eigen::Vector3d(uu(rng), uv(rng), 1.0);
        const SurfaceHit hit = scene.rayCaster().intersectTerrain(o, d, 200.0);
        double t_bf = -1.0;
        const double step = 0.02 / d.norm();
        for (double t = step; t <= 200.0; t += step) {
          const Eigen::Vector3d q = o + t * d;
          if (q.z() < scene.terrainHeight(q.x(), q.y())) {
            t_bf = t;
            break;
          }
        }
        if (t_bf < 0.0) {
          EXPECT_FALSE(hit.hit()) << nameOf(kind);
          continue;
        }
        ASSERT_TRUE(hit.hit()) << nameOf(kind) << " frame " << k;
        EXPECT_LE(hit.t, t_bf + 1e-9) << nameOf(kind);
        EXPECT_GE(hit.t, t_bf - step - 1e-9) << nameOf(kind);
        if (hit.surface == SurfaceHit::kTerrainTop) {
          EXPECT_NEAR(hit.point.z(), scene.terrainHeight(hit.point.x(), hit.point.y()), 1e-6)
              << nameOf(kind);
        }
        ++hits;
      }
    }
    EXPECT_GT(hits, 100) << nameOf(kind);
  }
}

// ------------------------------------------------------------------------------------------------
// YAML

TEST(SceneZoo, YamlRebuildsEveryScene) {
  TempDir dir;
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> ux(-10.0, 100.0), uy(-20.0, 20.0);
  for (SceneKind kind : everyScene()) {
    SceneOptions o = ScenePreset::forKind(kind, 987654321012345ULL).scene;
    if (kind == SceneKind::kRamp) o.addStandardObstacles();  // along the road path
    const SyntheticScene a(o);
    const std::string f1 = dir.path() + "/" + nameOf(kind) + ".yaml";
    const std::string f2 = dir.path() + "/" + nameOf(kind) + "_again.yaml";
    a.toYaml(f1);
    const SyntheticScene b = SyntheticScene::fromYaml(f1);
    b.toYaml(f2);
    EXPECT_EQ(readFile(f1), readFile(f2)) << nameOf(kind);
    EXPECT_EQ(b.options().kind, kind);
    EXPECT_EQ(b.options().seed, 987654321012345ULL);
    EXPECT_EQ(b.obstacleCount(), a.obstacleCount());
    EXPECT_EQ(b.options().cast_shadows, a.options().cast_shadows);
    sgd::sim::TextureFilter filter;
    filter.dp_du = {0.01, 0.0, 0.0};
    filter.dp_dv = {0.0, 0.01, 0.0};
    for (int i = 0; i < 200; ++i) {
      const double x = ux(rng), y = uy(rng), t = 0.05 * i;
      EXPECT_EQ(b.terrainHeight(x, y), a.terrainHeight(x, y)) << nameOf(kind);
      EXPECT_EQ(b.surfaceHeight(x, y, t), a.surfaceHeight(x, y, t)) << nameOf(kind);
      SurfaceHit hit;
      hit.object_id = 0;
      hit.point = {x, y, a.terrainHeight(x, y)};
      const Eigen::Vector2d g = a.terrainGradient(x, y);
      hit.normal = Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
      EXPECT_EQ(b.albedo(hit, filter, t), a.albedo(hit, filter, t)) << nameOf(kind);
    }
  }
  // A scene file written before the zoo (no zoo keys) still loads, as the old scene.
  const SyntheticScene flat(ScenePreset::forKind(SceneKind::kBumpAndCurb, 3).scene);
  const std::string f = dir.path() + "/old.yaml";
  flat.toYaml(f);
  std::string text = readFile(f);
  const size_t cut = text.find("cast_shadows");
  const size_t resume = text.find("boxes:");
  ASSERT_NE(cut, std::string::npos);
  ASSERT_NE(resume, std::string::npos);
  ASSERT_LT(cut, resume);
  text.erase(cut, resume - cut);
  std::ofstream(dir.path() + "/old_cut.yaml") << text;
  const SyntheticScene old = SyntheticScene::fromYaml(dir.path() + "/old_cut.yaml");
  EXPECT_FALSE(old.options().cast_shadows);
  EXPECT_TRUE(old.options().road_path.empty());
  EXPECT_EQ(old.terrainHeight(13.2, 1.0), flat.terrainHeight(13.2, 1.0));
}

// ------------------------------------------------------------------------------------------------
// Truth maps and the KITTI folder

// Every scene's folder: the disparity and label of each pixel centre match a ray cast with the
// written poses; the scene rebuilds from scene.yaml.
TEST(SceneZoo, DisparityAndLabelTruthMatchTheGeometry) {
  for (SceneKind kind : kZoo) {
    TempDir dir;
    const ScenePreset p = ScenePreset::forKind(kind, 2);
    const SyntheticScene scene(p.scene);
    const SequenceGenerator gen = generator(scene, p, 2, 0.15);
    gen.writeKitti(dir.path());
    const std::string d = dir.path() + "/";
    const SyntheticScene again = SyntheticScene::fromYaml(d + "scene.yaml");
    const auto g = readNumbers(d + "ground_T_camera0.txt");
    const auto poses = readNumbers(d + "poses.txt");
    ASSERT_EQ(poses.size(), 2u);
    Eigen::Matrix4d m0;
    for (int i = 0; i < 16; ++i) m0(i / 4, i % 4) = g[0][static_cast<size_t>(i)];
    const auto rig = gen.renderer().rig();
    const double fb = rig.disparityTimesDepth();
    int compared = 0, terrain = 0, obstacles = 0;
    for (int k = 0; k < 2; ++k) {
      Eigen::Matrix4d mk = Eigen::Matrix4d::Identity();
      for (int i = 0; i < 12; ++i) mk(i / 4, i % 4) = poses[static_cast<size_t>(k)][static_cast<size_t>(i)];
      // Written with 13 significant digits: the files' pose agrees with the generator's to
      // ~1e-11; the rays below use the generator's (the renderer's own) pose and directions.
      const Eigen::Isometry3d pose = gen.frames()[static_cast<size_t>(k)].ground_T_left;
      EXPECT_NEAR(((m0 * mk) - pose.matrix()).norm(), 0.0, 1e-9);
      const Eigen::Matrix3d r = pose.linear();
      const Eigen::Vector3d d_du = r.col(0) / rig.fx, d_dv = r.col(1) / rig.fy;
      const Eigen::Vector3d d_00 = r.col(2) - rig.cx * d_du - rig.cy * d_dv;
      char name[32];
      std::snprintf(name, sizeof(name), "%06d.png", k);
      const cv::Mat disp = cv::imread(d + "disp_0/" + name, cv::IMREAD_UNCHANGED);
      const cv::Mat label = cv::imread(d + "label_0/" + name, cv::IMREAD_UNCHANGED);
      ASSERT_EQ(disp.type(), CV_16U);
      ASSERT_EQ(label.type(), CV_16U);
      const double time_s = gen.frames()[static_cast<size_t>(k)].time_s;
      for (int v = 0; v < rig.height; v += 2) {
        for (int u = 0; u < rig.width; u += 2) {
          const Eigen::Vector3d dc = d_00 + u * d_du + v * d_dv;
          const SurfaceHit hit = again.intersect(pose.translation(), dc, 1000.0, time_s);
          const int lab = label.at<uint16_t>(v, u);
          if (!hit.hit()) {
            EXPECT_EQ(lab, 0);
            EXPECT_EQ(disp.at<uint16_t>(v, u), 0);
            continue;
          }
          EXPECT_EQ(lab, hit.object_id + 1) << nameOf(kind) << " " << u << "," << v;
          // t is the depth (the direction's optical z is 1); PNG disparity = round(256 d).
          EXPECT_NEAR(disp.at<uint16_t>(v, u) / 256.0, fb / hit.t, 0.5 / 256.0 + 1e-6)
              << nameOf(kind) << " " << u << "," << v;
          ++compared;
          (hit.object_id == 0 ? terrain : obstacles) += 1;
        }
      }
    }
    EXPECT_GT(terrain, 400) << nameOf(kind);
    EXPECT_GT(compared, 1000) << nameOf(kind);
    if (kind == SceneKind::kRamp || kind == SceneKind::kTraffic || kind == SceneKind::kShadows) {
      EXPECT_GT(obstacles, 20) << nameOf(kind);
    }
  }
}

// ------------------------------------------------------------------------------------------------
// Trajectories

TEST(SceneZoo, CurvesAreDrivenAlongTheRoad) {
  struct Case {
    SceneKind kind;
    double lane_radius;  // of the vehicle's lane [m]
    double yaw_per_m;    // signed yaw per metre driven [rad/m]
  };
  const Case cases[] = {{SceneKind::kBankedCurve, 121.875, 1.0 / 121.875},
                        {SceneKind::kTightCurve, 22.0, -1.0 / 22.0},
                        {SceneKind::kRamp, 90.0, -1.0 / 90.0}};
  for (const Case& c : cases) {
    const ScenePreset p = ScenePreset::forKind(c.kind);
    const SyntheticScene scene(p.scene);
    const SequenceGenerator gen = generator(scene, p, 40);
    const RoadPath path(p.scene.road_path);
    // The curve's centre: from the path at s = 1 (on the arc).
    const RoadPath::Pose on_arc = path.poseAt(1.0);
    const Eigen::Vector2d centre = on_arc.xy + on_arc.normal() / on_arc.curvature_per_m;
    const double speed = p.sequence.speed_m_per_frame;
    EXPECT_DOUBLE_EQ(speed, 1.0);
    for (int k = 0; k < 40; ++k) {
      const Eigen::Vector3d v = gen.vehicleXyYaw(k);
      // Frame 0 at the origin heading along +x; then on the lane's circle.
      EXPECT_NEAR((v.head<2>() - centre).norm(), c.lane_radius, 1e-9) << nameOf(c.kind) << " " << k;
      EXPECT_NEAR(wrap(v.z() - k * speed * c.yaw_per_m), 0.0, 1e-12) << nameOf(c.kind) << " " << k;
      const RoadPath::Coordinates rc = path.coordinates(v.x(), v.y());
      EXPECT_NEAR(rc.n_m, p.sequence.path_offset_m, 1e-9);
      if (k > 0) {
        // The camera turns by the same yaw, and moves 1 m along its lane per frame.
        const double dyaw = cameraHeading(gen.frames()[static_cast<size_t>(k)].ground_T_left) -
                            cameraHeading(gen.frames()[static_cast<size_t>(k) - 1].ground_T_left);
        EXPECT_NEAR(wrap(dyaw), speed * c.yaw_per_m, 1e-9) << nameOf(c.kind);
        const double chord = (v.head<2>() - gen.vehicleXyYaw(k - 1).head<2>()).norm();
        EXPECT_NEAR(chord, 2.0 * c.lane_radius * std::sin(0.5 / c.lane_radius), 1e-9);
      }
    }
    EXPECT_NEAR(gen.vehicleXyYaw(0).head<2>().norm(), 0.0, 1e-12);
  }
  // tight_curve: 2.6 degrees of yaw per frame.
  EXPECT_NEAR(1.0 / 22.0 / kDeg, 2.604, 0.001);

  // The straight scenes: the right lane, 1 m per frame (0.75 on the bounce track).
  for (SceneKind kind : {SceneKind::kCrest, SceneKind::kSag, SceneKind::kShadows, SceneKind::kTraffic,
                         SceneKind::kRolling, SceneKind::kBounce}) {
    const ScenePreset p = ScenePreset::forKind(kind);
    const SyntheticScene scene(p.scene);
    const SequenceGenerator gen = generator(scene, p, 20);
    for (int k = 0; k < 20; ++k) {
      const Eigen::Vector3d v = gen.vehicleXyYaw(k);
      EXPECT_NEAR(v.x(), k * p.sequence.speed_m_per_frame, 1e-12) << nameOf(kind);
      EXPECT_EQ(v.y(), p.sequence.start_xy_m.y());
      EXPECT_EQ(v.z(), 0.0);
    }
  }
  // The crest: the camera rides the grade (+4 % at the start: pitched up by atan(0.04)).
  const ScenePreset cp = ScenePreset::forKind(SceneKind::kCrest);
  const SyntheticScene crest(cp.scene);
  const SequenceGenerator cg = generator(crest, cp, 1);
  EXPECT_NEAR(cg.frames()[0].ground_T_left.linear().col(2).z(), std::sin(std::atan(0.04)), 1e-9);
}

TEST(SceneZoo, BounceAttitudeChangesTwoToThreeDegreesPerFrame) {
  const ScenePreset p = ScenePreset::forKind(SceneKind::kBounce);
  EXPECT_DOUBLE_EQ(p.sequence.speed_m_per_frame, 0.75);
  const SyntheticScene scene(p.scene);
  const SequenceGenerator gen = generator(scene, p, 60);
  double lo = 1e9, hi = 0.0, pitch_lo = 1e9, roll_lo = 1e9, yaw_hi = 0.0;
  for (int k = 1; k < 60; ++k) {
    const Eigen::Matrix3d a = gen.frames()[static_cast<size_t>(k) - 1].ground_T_left.linear();
    const Eigen::Matrix3d b = gen.frames()[static_cast<size_t>(k)].ground_T_left.linear();
    const Eigen::AngleAxisd rel(a.transpose() * b);  // in the previous camera's frame
    const Eigen::Vector3d w = rel.angle() * rel.axis();
    lo = std::min(lo, rel.angle());
    hi = std::max(hi, rel.angle());
    pitch_lo = std::min(pitch_lo, std::abs(w.x()));  // about the camera's x (right) axis
    roll_lo = std::min(roll_lo, std::abs(w.z()));    // about its optical axis
    yaw_hi = std::max(yaw_hi, std::abs(w.y()));
    // The pose is the exact ground truth: the perturbation is what the generator reports.
    const Eigen::Vector3d v = gen.vehicleXyYaw(k);
    const Eigen::Vector2d att = gen.attitudePerturbation(k);
    const Eigen::Isometry3d again =
        SequenceGenerator::cameraPose(scene, gen.options(), v.x(), v.y(), v.z(), att.x(), att.y());
    EXPECT_NEAR((again.matrix() - gen.frames()[static_cast<size_t>(k)].ground_T_left.matrix()).norm(), 0.0, 1e-15);
  }
  // Measured (frames 1-59): 2.30 .. 2.61 degrees in all; pitch changes 1.81 .. 2.21, roll
  // changes 1.25 .. 1.56 degrees. The bounds are the scene's specification (2-3 degrees).
  EXPECT_GE(lo, 2.0 * kDeg);
  EXPECT_LE(hi, 3.0 * kDeg);
  EXPECT_GT(pitch_lo, 1.6 * kDeg);
  EXPECT_GT(roll_lo, 1.0 * kDeg);
  EXPECT_LT(yaw_hi, 0.1 * kDeg);
  // Signs: a positive pitch puts the nose (the optical axis) down, a positive roll the left side
  // up (the camera's x axis, to the right, down).
  const Eigen::Vector3d v0 = gen.vehicleXyYaw(0);
  const Eigen::Matrix3d level = SequenceGenerator::cameraPose(scene, gen.options(), v0.x(), v0.y(), v0.z()).linear();
  const Eigen::Matrix3d nose_down =
      SequenceGenerator::cameraPose(scene, gen.options(), v0.x(), v0.y(), v0.z(), 0.02, 0.0).linear();
  const Eigen::Matrix3d left_up =
      SequenceGenerator::cameraPose(scene, gen.options(), v0.x(), v0.y(), v0.z(), 0.0, 0.02).linear();
  EXPECT_NEAR(nose_down.col(2).z() - level.col(2).z(), -0.02, 1e-3);
  EXPECT_NEAR(left_up.col(0).z() - level.col(0).z(), -0.02, 1e-3);
  // The camera stays about camera_height_m above the ground (the body rotates about the ground
  // point under it).
  for (const auto& f : gen.frames()) {
    const Eigen::Vector3d c = f.ground_T_left.translation();
    EXPECT_NEAR(c.z() - scene.terrainHeight(c.x(), c.y()), 1.65, 0.08);
  }
}

// ------------------------------------------------------------------------------------------------
// Shadows

TEST(SceneZoo, CastShadowsDarkenTheTerrainToTheAmbientShare) {
  const ScenePreset p = ScenePreset::forKind(SceneKind::kShadows);
  const SceneOptions& o = p.scene;
  ASSERT_TRUE(o.cast_shadows);
  SceneOptions unshadowed = o;
  unshadowed.cast_shadows = false;
  const SyntheticScene scene(o), plain(unshadowed);
  const Eigen::Vector3d sun(std::cos(o.sun_elevation_rad) * std::cos(o.sun_azimuth_rad),
                            std::cos(o.sun_elevation_rad) * std::sin(o.sun_azimuth_rad),
                            std::sin(o.sun_elevation_rad));
  const double flat = o.ambient + (1.0 - o.ambient) * sun.z();
  // Whether the segment from p towards the sun passes through an obstacle (sampled, independent
  // of the renderer's shadow rays).
  double top = 0.0;
  for (const auto& b : o.boxes) top = std::max(top, b.height_m);
  for (const auto& pl : o.poles) top = std::max(top, pl.height_m);
  auto blocked = [&](const Eigen::Vector3d& p, double t) {
    for (double s = 0.02; (p + s * sun).z() < top; s += 0.02) {
      const Eigen::Vector3d q = p + s * sun;
      if (scene.obstacleIdAt(q.x(), q.y(), t) > 0 && q.z() < scene.surfaceHeight(q.x(), q.y(), t)) return true;
    }
    return false;
  };
  sgd::sim::TextureFilter filter;
  filter.dp_du = {0.005, 0.0, 0.0};
  filter.dp_dv = {0.0, 0.005, 0.0};
  auto ratio = [&](const Eigen::Vector3d& p, double t) {
    SurfaceHit hit;
    hit.object_id = 0;
    hit.point = p;
    hit.normal = Eigen::Vector3d::UnitZ();
    return scene.albedo(hit, filter, t) / plain.albedo(hit, filter, t);
  };
  // The car ahead (box 0): the ground that the sun sees through its middle.
  const sgd::sim::BoxObstacle& car = o.boxes[0];
  for (double t : {0.0, 2.5}) {
    const Eigen::Vector2d c = car.centerAt(t);
    const Eigen::Vector3d mid(c.x(), c.y(), 0.5 * car.height_m);
    const Eigen::Vector3d shadowed = mid - sun * (mid.z() / sun.z());
    ASSERT_TRUE(blocked(shadowed, t));
    EXPECT_NEAR(ratio(shadowed, t), o.ambient / flat, 1e-12) << t;
    // 2 m to the left of the car's axis, in the sun.
    const Eigen::Vector3d lit(c.x(), c.y() + 2.0, 0.0);
    ASSERT_FALSE(blocked(lit, t));
    EXPECT_DOUBLE_EQ(ratio(lit, t), 1.0) << t;
    // The shadow moves with the car: the ground shadowed at t is in the sun 2.5 s later or earlier.
    const double other = t == 0.0 ? 2.5 : 0.0;
    ASSERT_FALSE(blocked(shadowed, other));
    EXPECT_DOUBLE_EQ(ratio(shadowed, other), 1.0);
  }
  // Poles cast shadows too.
  const sgd::sim::PoleObstacle& pole = o.poles[2];
  const Eigen::Vector3d pole_mid(pole.xy.x(), pole.xy.y(), 3.0);
  const Eigen::Vector3d pole_shadow = pole_mid - sun * (3.0 / sun.z());
  ASSERT_TRUE(blocked(pole_shadow, 0.0));
  EXPECT_NEAR(ratio(pole_shadow, 0.0), o.ambient / flat, 1e-12);
  // In an image: the shadows are dark (frame 0, mean of the road pixels in and out of shadow).
  const SequenceGenerator gen = generator(scene, p, 1, 0.25, 1);
  const sgd::sim::RenderedPair pair = gen.render(0);
  const Eigen::Isometry3d pose = gen.frames()[0].ground_T_left;
  const auto rig = gen.renderer().rig();
  double sum_in = 0.0, sum_out = 0.0;
  int n_in = 0, n_out = 0;
  for (int v = 0; v < rig.height; ++v) {
    for (int u = 0; u < rig.width; ++u) {
      if (pair.left.label.at<int>(v, u) != 0) continue;
      const double z = 1.0 / pair.left.inverse_depth.at<float>(v, u);
      if (z > 30.0) continue;
      const Eigen::Vector3d q = pose * Eigen::Vector3d((u - rig.cx) / rig.fx * z, (v - rig.cy) / rig.fy * z, z);
      if (std::abs(q.y()) > 7.0) continue;  // the asphalt
      if (blocked(q, 0.0)) {
        sum_in += pair.left.albedo.at<float>(v, u);
        ++n_in;
      } else {
        sum_out += pair.left.albedo.at<float>(v, u);
        ++n_out;
      }
    }
  }
  ASSERT_GT(n_in, 30);
  ASSERT_GT(n_out, 300);
  // Asphalt in the sun ~98 grey, in shadow ~98 * 0.3 / 0.60 (a few pixels straddle the edge).
  EXPECT_LT(sum_in / n_in, 0.6 * sum_out / n_out);
}

// ------------------------------------------------------------------------------------------------
// Determinism and the command line

TEST(SceneZoo, ImagesAreDeterministic) {
  for (SceneKind kind : {SceneKind::kRamp, SceneKind::kBounce, SceneKind::kTraffic}) {
    const ScenePreset p = ScenePreset::forKind(kind, 6);
    const SyntheticScene s1(p.scene), s2(p.scene);
    const SequenceGenerator g1 = generator(s1, p, 3, 0.15, 2);
    const SequenceGenerator g2 = generator(s2, p, 3, 0.15, 2);
    const auto a = g1.render(2), b = g2.render(2);
    EXPECT_EQ(cv::norm(a.left.image, b.left.image, cv::NORM_INF), 0.0) << nameOf(kind);
    EXPECT_EQ(cv::norm(a.right.image, b.right.image, cv::NORM_INF), 0.0) << nameOf(kind);
    const int threads = cv::getNumThreads();
    cv::setNumThreads(1);
    const auto c = g1.render(2);
    cv::setNumThreads(threads);
    EXPECT_EQ(cv::norm(a.left.image, c.left.image, cv::NORM_INF), 0.0) << nameOf(kind);
    // Another seed: another texture.
    const ScenePreset q = ScenePreset::forKind(kind, 7);
    const SyntheticScene s3(q.scene);
    const auto d = generator(s3, q, 3, 0.15, 2).render(2);
    EXPECT_GT(cv::norm(a.left.image, d.left.image, cv::NORM_L1), 1.0 * a.left.image.total()) << nameOf(kind);
  }
}

#ifdef SGD_RENDER_EXE
TEST(RenderCli, RendersEveryZooSceneWithoutOtherFlags) {
  TempDir dir;
  const std::string exe = SGD_RENDER_EXE;
  for (SceneKind kind : kZoo) {
    const std::string out = dir.path() + "/" + nameOf(kind);
    const std::string cmd = exe + " --scene " + nameOf(kind) + " --frames 2 --out " + out +
                            " --scale 0.08 --supersampling 1 --quiet";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    EXPECT_TRUE(std::filesystem::exists(out + "/image_1/000001.png"));
    EXPECT_TRUE(std::filesystem::exists(out + "/label_0/000001.png"));
    // scene.yaml is the preset; the poses are the preset's drive.
    const ScenePreset p = ScenePreset::forKind(kind, 1);
    const SyntheticScene back = SyntheticScene::fromYaml(out + "/scene.yaml");
    EXPECT_EQ(back.obstacleCount(), static_cast<int>(p.scene.boxes.size() + p.scene.poles.size()));
    EXPECT_EQ(back.terrainHeight(7.3, -1.2), SyntheticScene(p.scene).terrainHeight(7.3, -1.2));
    const auto poses = readNumbers(out + "/poses.txt");
    ASSERT_EQ(poses.size(), 2u);
    const SyntheticScene scene(p.scene);
    const SequenceGenerator gen = generator(scene, p, 2);
    const Eigen::Matrix4d rel =
        (gen.frames()[0].ground_T_left.inverse() * gen.frames()[1].ground_T_left).matrix();
    for (int i = 0; i < 12; ++i) EXPECT_NEAR(poses[1][static_cast<size_t>(i)], rel(i / 4, i % 4), 1e-9);
  }
  // --yaw-rate overrides the road: free driving from the scene's start pose.
  const std::string out = dir.path() + "/free";
  const std::string cmd = exe + " --scene tight_curve --frames 3 --yaw-rate 0 --speed 2 --out " +
                          out + " --scale 0.08 --supersampling 1 --quiet";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  const auto poses = readNumbers(out + "/poses.txt");
  ASSERT_EQ(poses.size(), 3u);
  EXPECT_NEAR(poses[2][11], 4.0, 1e-9);  // straight ahead, 2 m per frame
  EXPECT_NEAR(poses[2][3], 0.0, 1e-9);
}
#endif
