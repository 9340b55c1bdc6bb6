/// \file render_sequence.cpp
/// sgd_render: renders a synthetic stereo sequence into a KITTI-odometry-style folder with exact
/// ground truth (see SequenceGenerator.hpp for the layout).

#include <chrono>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <string>

#include "stereo_ground_dem/sim/ScenePreset.hpp"
#include "stereo_ground_dem/sim/SequenceGenerator.hpp"

namespace sim = stereo_ground_dem::sim;

namespace {

const char* kUsage =
    "usage: sgd_render --scene NAME --frames N --out DIR [options]\n"
    "  scenes (docs/zoo.md): flat bump offroad crest sag banked_curve bounce tight_curve ramp\n"
    "                        rolling shadows traffic\n"
    "  each scene comes with its drive (trajectory, speed, attitude); these flags override it:\n"
    "  --seed S            texture / terrain seed (default 1)\n"
    "  --speed M           metres per frame (default: the scene's, 1.0 for most)\n"
    "  --yaw-rate R        yaw change per frame [rad]; drives freely from the scene's start pose\n"
    "                      instead of following its road (default: the scene's drive)\n"
    "  --pitch-down R      camera pitch, positive looks down [rad] (default 0)\n"
    "  --camera-height H   [m] (default 1.65)\n"
    "  --gain-drift        left gain drifts 0.75 -> 1.25; right gain x1.03, right bias +4 grey\n"
    "  --obstacles         add the standard obstacles (parked and moving cars, a wall, poles)\n"
    "  --scale F           image size and intrinsics relative to KITTI 1226x370 (default 1)\n"
    "  --supersampling N   rays per pixel per axis (default 2)\n"
    "  --noise SIGMA       sensor noise [grey] (default 1.0)\n"
    "  --no-truth-maps     do not write disp_0/ and label_0/\n"
    "  --quiet             no progress output\n";

[[noreturn]] void die(const std::string& msg) {
  std::cerr << "sgd_render: " << msg << "\n";
  std::exit(2);
}

double parseDouble(const std::string& flag, const std::string& text) {
  try {
    size_t pos = 0;
    const double v = std::stod(text, &pos);
    if (pos == text.size()) return v;
  } catch (const std::exception&) {
  }
  die(flag + " expects a number, got '" + text + "'");
}

long long parseInt(const std::string& flag, const std::string& text) {
  try {
    size_t pos = 0;
    const long long v = std::stoll(text, &pos);
    if (pos == text.size()) return v;
  } catch (const std::exception&) {
  }
  die(flag + " expects an integer, got '" + text + "'");
}

}  // namespace

int main(int argc, char** argv) {
  std::string scene_name;
  std::string out_dir;
  long long frames = -1;
  long long seed = 1;
  double scale = 1.0;
  bool gain_drift = false, obstacles = false, quiet = false, no_truth_maps = false;
  double speed = -1.0, yaw_rate = 0.0, pitch_down = 0.0, camera_height = 1.65;
  bool yaw_rate_given = false;
  sim::RenderOptions render;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) die(a + " needs a value");
      return argv[++i];
    };
    if (a == "-h" || a == "--help") {
      std::cout << kUsage;
      return 0;
    } else if (a == "--scene") {
      scene_name = value();
    } else if (a == "--frames") {
      frames = parseInt(a, value());
    } else if (a == "--out") {
      out_dir = value();
    } else if (a == "--seed") {
      seed = parseInt(a, value());
      if (seed < 0) die("--seed must be >= 0");
    } else if (a == "--speed") {
      speed = parseDouble(a, value());
      if (!(speed >= 0.0)) die("--speed must be >= 0");
    } else if (a == "--yaw-rate") {
      yaw_rate = parseDouble(a, value());
      yaw_rate_given = true;
    } else if (a == "--pitch-down") {
      pitch_down = parseDouble(a, value());
    } else if (a == "--camera-height") {
      camera_height = parseDouble(a, value());
    } else if (a == "--gain-drift") {
      gain_drift = true;
    } else if (a == "--obstacles") {
      obstacles = true;
    } else if (a == "--scale") {
      scale = parseDouble(a, value());
    } else if (a == "--supersampling") {
      render.supersampling = static_cast<int>(parseInt(a, value()));
    } else if (a == "--noise") {
      render.noise_std_grey = parseDouble(a, value());
    } else if (a == "--no-truth-maps") {
      no_truth_maps = true;
    } else if (a == "--quiet") {
      quiet = true;
    } else {
      die("unknown argument '" + a + "' (see --help)");
    }
  }
  if (scene_name.empty()) die("--scene is required (see --help)");
  if (frames < 0) die("--frames is required");
  if (out_dir.empty()) die("--out is required");
  sim::SceneKind kind;
  if (!sim::sceneKindFromName(scene_name, &kind)) {
    die("unknown scene '" + scene_name + "' (see --help)");
  }
  if (frames < 1 || frames > 100000) die("--frames must be in 1..100000");
  if (!(scale > 0.05 && scale <= 4.0)) die("--scale must be in (0.05, 4]");
  sim::ScenePreset preset = sim::ScenePreset::forKind(kind, static_cast<uint64_t>(seed));
  sim::SequenceOptions& seq = preset.sequence;
  seq.frames = static_cast<int>(frames);
  seq.noise_seed = static_cast<uint64_t>(seed);
  if (speed >= 0.0) seq.speed_m_per_frame = speed;
  if (yaw_rate_given) {
    // Free driving from the scene's start pose.
    if (seq.follow_road_path) {
      const sim::RoadPath path(preset.scene.road_path);
      const sim::RoadPath::Pose p = path.poseAt(path.arcLengthAfter(seq.path_offset_m, seq.path_start_m));
      seq.start_xy_m = p.xy + seq.path_offset_m * p.normal();
      seq.start_yaw_rad = p.heading_rad;
      seq.follow_road_path = false;
    }
    seq.yaw_rate_rad_per_frame = yaw_rate;
  }
  seq.camera_pitch_down_rad = pitch_down;
  seq.camera_height_m = camera_height;
  if (no_truth_maps) seq.write_truth_maps = false;
  if (gain_drift) {
    seq.gain_start = 0.75;
    seq.gain_end = 1.25;
    seq.right_gain_ratio = 1.03;
    seq.right_bias_grey = 4.0;
  }
  std::string why;
  if (!seq.isValid(&why)) die(why);
  if (!render.isValid(&why)) die(why);
  sim::SceneOptions scene_options = preset.scene;
  if (obstacles) scene_options.addStandardObstacles();
  try {
    const sim::SyntheticScene scene(scene_options);
    const auto rig = sim::StereoRenderer::kittiLikeRig(scale);
    const sim::SequenceGenerator generator(scene, rig, seq, render);
    const auto t0 = std::chrono::steady_clock::now();
    generator.writeKitti(out_dir);
    const double s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (!quiet) {
      std::cout << "sgd_render: wrote " << frames << " " << rig.width << "x" << rig.height
                << " stereo pairs of scene '" << sim::sceneKindName(kind) << "' to " << out_dir
                << " in " << s << " s\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "sgd_render: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
