#include "stereo_ground_dem/sim/SequenceGenerator.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

namespace stereo_ground_dem::sim {

namespace {

std::string framePath(const std::string& dir, const char* sub, int k) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06d.png", k);
  return (std::filesystem::path(dir) / sub / name).string();
}

void writeImage(const std::string& path, const cv::Mat& image) {
  bool ok = false;
  try {
    ok = cv::imwrite(path, image);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) throw std::runtime_error("cannot write image '" + path + "'");
}

std::ofstream openText(const std::string& path) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write '" + path + "'");
  out.precision(12);
  out << std::scientific;
  return out;
}

void closeText(std::ofstream& out, const std::string& path) {
  out.close();
  if (!out) throw std::runtime_error("error while writing '" + path + "'");
}

}  // namespace

bool SequenceOptions::isValid(std::string* why) const {
  auto bad = [why](const char* msg) {
    if (why) *why = msg;
    return false;
  };
  if (frames < 1) return bad("frames must be >= 1");
  if (!(speed_m_per_frame >= 0.0) || !std::isfinite(speed_m_per_frame)) {
    return bad("speed_m_per_frame must be finite and >= 0");
  }
  if (!(frame_period_s > 0.0) || !std::isfinite(frame_period_s)) {
    return bad("frame_period_s must be positive");
  }
  if (!start_xy_m.allFinite() || !std::isfinite(start_yaw_rad) ||
      !std::isfinite(yaw_rate_rad_per_frame)) {
    return bad("start pose and yaw rate must be finite");
  }
  if (!(camera_height_m > 0.0) || !std::isfinite(camera_height_m)) {
    return bad("camera_height_m must be positive");
  }
  if (!(std::abs(camera_pitch_down_rad) < 0.5 * M_PI)) {
    return bad("camera_pitch_down_rad must be within (-pi/2, pi/2)");
  }
  if (!(vehicle_length_m > 0.0) || !(vehicle_width_m > 0.0)) {
    return bad("vehicle footprint must be positive");
  }
  if (!(gain_start > 0.0) || !(gain_end > 0.0) || !(right_gain_ratio > 0.0) ||
      !std::isfinite(gain_start) || !std::isfinite(gain_end) || !std::isfinite(right_gain_ratio)) {
    return bad("gains must be positive");
  }
  if (!std::isfinite(left_bias_grey) || !std::isfinite(right_bias_grey)) {
    return bad("biases must be finite");
  }
  if (!std::isfinite(path_offset_m) || !std::isfinite(path_start_m)) {
    return bad("path offset and start must be finite");
  }
  if (!(std::abs(attitude_pitch_rad) < 0.3) || !(std::abs(attitude_roll_rad) < 0.3) ||
      !(attitude_jitter_rad >= 0.0 && attitude_jitter_rad < 0.1)) {
    return bad("attitude perturbation: |amplitudes| < 0.3 rad, jitter in [0, 0.1) rad");
  }
  return true;
}

Eigen::Isometry3d SequenceGenerator::cameraPose(const SyntheticScene& scene,
                                                const SequenceOptions& o, double x, double y,
                                                double yaw_rad, double extra_pitch_rad,
                                                double extra_roll_rad) {
  const Eigen::Vector2d p(x, y);
  const Eigen::Vector2d fwd(std::cos(yaw_rad), std::sin(yaw_rad));
  const Eigen::Vector2d left(-fwd.y(), fwd.x());
  const double hl = 0.5 * o.vehicle_length_m, hw = 0.5 * o.vehicle_width_m;
  auto h = [&](double s, double l) {
    const Eigen::Vector2d q = p + s * fwd + l * left;
    return scene.terrainHeight(q.x(), q.y());
  };
  const double fl = h(hl, hw), fr = h(hl, -hw), rl = h(-hl, hw), rr = h(-hl, -hw);
  // Least-squares plane z = z0 + a s + b l through the four corners (s forward, l left).
  const double z0 = 0.25 * (fl + fr + rl + rr);
  const double a = ((fl + fr) - (rl + rr)) / (4.0 * hl);
  const double b = ((fl + rl) - (fr + rr)) / (4.0 * hw);
  const Eigen::Vector3d t_fwd(fwd.x(), fwd.y(), a);
  const Eigen::Vector3d t_left(left.x(), left.y(), b);
  const Eigen::Vector3d up = t_fwd.cross(t_left).normalized();
  const Eigen::Vector3d ex = t_fwd.normalized();
  const Eigen::Vector3d ey = up.cross(ex);
  Eigen::Matrix3d ground_R_body;
  ground_R_body.col(0) = ex;
  ground_R_body.col(1) = ey;
  ground_R_body.col(2) = up;
  if (extra_pitch_rad != 0.0 || extra_roll_rad != 0.0) {
    // Nose down = positive rotation about the body's y (left) axis; left side up = positive
    // rotation about its x (forward) axis.
    ground_R_body = ground_R_body *
                    Eigen::AngleAxisd(extra_pitch_rad, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                    Eigen::AngleAxisd(extra_roll_rad, Eigen::Vector3d::UnitX()).toRotationMatrix();
  }
  const Eigen::Vector3d up_final = ground_R_body.col(2);
  const Eigen::Isometry3d body_T_camera =
      StereoRenderer::lookingPose(Eigen::Vector3d::Zero(), 0.0, o.camera_pitch_down_rad);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = ground_R_body * body_T_camera.linear();
  pose.translation() = Eigen::Vector3d(x, y, z0) + o.camera_height_m * up_final;
  return pose;
}

SequenceGenerator::SequenceGenerator(const SyntheticScene& scene, const StereoRig& rig,
                                     const SequenceOptions& options,
                                     const RenderOptions& render_options)
    : renderer_(scene, rig, render_options), options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("SequenceOptions: " + why);
  const SequenceOptions& o = options_;
  const RoadPath path(renderer_.scene().options().road_path);
  if (o.follow_road_path) {
    if (path.empty()) throw std::invalid_argument("SequenceOptions: follow_road_path on a scene without a road path");
    for (const auto& pc : renderer_.scene().options().road_path.pieces) {
      if (!(1.0 - pc.curvature_per_m * o.path_offset_m > 0.05)) {
        throw std::invalid_argument("SequenceOptions: path_offset_m reaches a road piece's centre");
      }
    }
  }
  Eigen::Vector2d p = o.start_xy_m;
  double yaw = o.start_yaw_rad;
  for (int k = 0; k < o.frames; ++k) {
    if (o.follow_road_path) {
      const double s = path.arcLengthAfter(o.path_offset_m, o.path_start_m + k * o.speed_m_per_frame);
      const RoadPath::Pose pose = path.poseAt(s);
      p = pose.xy + o.path_offset_m * pose.normal();
      yaw = pose.heading_rad;
    } else if (k > 0) {
      // Constant speed and yaw rate: move along the mean heading of the step.
      const double mid = yaw + 0.5 * o.yaw_rate_rad_per_frame;
      p += o.speed_m_per_frame * Eigen::Vector2d(std::cos(mid), std::sin(mid));
      yaw += o.yaw_rate_rad_per_frame;
    }
    Eigen::Vector2d att = Eigen::Vector2d::Zero();
    if (o.attitude_pitch_rad != 0.0 || o.attitude_roll_rad != 0.0 || o.attitude_jitter_rad != 0.0) {
      const uint64_t h = TextureNoise::mix64(TextureNoise::mix64(o.noise_seed ^ 0xA77171DEULL) +
                                             static_cast<uint64_t>(k));
      const double j1 = (static_cast<double>(h >> 32) / 4294967296.0 * 2.0 - 1.0) * o.attitude_jitter_rad;
      const double j2 =
          (static_cast<double>(h & 0xFFFFFFFFULL) / 4294967296.0 * 2.0 - 1.0) * o.attitude_jitter_rad;
      const double sign = (k % 2 == 0) ? 1.0 : -1.0;
      att = Eigen::Vector2d(sign * (o.attitude_pitch_rad + j1), -sign * (o.attitude_roll_rad + j2));
    }
    xy_yaw_.emplace_back(p.x(), p.y(), yaw);
    perturbation_.push_back(att);
    SequenceFrame f;
    f.index = k;
    f.time_s = k * o.frame_period_s;
    f.ground_T_left = cameraPose(renderer_.scene(), o, p.x(), p.y(), yaw, att.x(), att.y());
    const double s = o.frames > 1 ? static_cast<double>(k) / (o.frames - 1) : 0.0;
    f.left.gain = o.gain_start + s * (o.gain_end - o.gain_start);
    f.left.bias_grey = o.left_bias_grey;
    f.right.gain = f.left.gain * o.right_gain_ratio;
    f.right.bias_grey = o.right_bias_grey;
    frames_.push_back(f);
  }
}

RenderedPair SequenceGenerator::render(int k) const {
  const SequenceFrame& f = frames_.at(static_cast<size_t>(k));
  return renderer_.renderPair(f.ground_T_left, f.left, f.right, f.time_s,
                              TextureNoise::mix64(options_.noise_seed) + static_cast<uint64_t>(k));
}

void SequenceGenerator::writeKitti(const std::string& dir) const {
  namespace fs = std::filesystem;
  std::error_code ec;
  std::vector<std::string> subs = {"image_0", "image_1"};
  if (options_.write_truth_maps) {
    subs.push_back("disp_0");
    subs.push_back("label_0");
  }
  for (const auto& sub : subs) {
    fs::create_directories(fs::path(dir) / sub, ec);
    if (ec) {
      throw std::runtime_error("cannot create '" + (fs::path(dir) / sub).string() +
                               "': " + ec.message());
    }
  }
  const StereoRig& rig = renderer_.rig();
  {
    const std::string path = (fs::path(dir) / "calib.txt").string();
    std::ofstream out = openText(path);
    const double p[2][12] = {
        {rig.fx, 0.0, rig.cx, 0.0, 0.0, rig.fy, rig.cy, 0.0, 0.0, 0.0, 1.0, 0.0},
        {rig.fx, 0.0, rig.cx, -rig.fx * rig.baseline_m, 0.0, rig.fy, rig.cy, 0.0, 0.0, 0.0, 1.0,
         0.0}};
    for (int c = 0; c < 2; ++c) {
      out << "P" << c << ":";
      for (double v : p[c]) out << " " << v;
      out << "\n";
    }
    closeText(out, path);
  }
  const Eigen::Isometry3d camera0_T_ground = frames_.front().ground_T_left.inverse();
  {
    const std::string path = (fs::path(dir) / "ground_T_camera0.txt").string();
    std::ofstream out = openText(path);
    const Eigen::Matrix4d m = frames_.front().ground_T_left.matrix();
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) out << m(r, c) << (r == 3 && c == 3 ? "\n" : " ");
    closeText(out, path);
  }
  const std::string poses_path = (fs::path(dir) / "poses.txt").string();
  const std::string times_path = (fs::path(dir) / "times.txt").string();
  const std::string photo_path = (fs::path(dir) / "photometry.txt").string();
  std::ofstream poses = openText(poses_path);
  std::ofstream times = openText(times_path);
  std::ofstream photo = openText(photo_path);
  for (const SequenceFrame& f : frames_) {
    const Eigen::Matrix4d m = (camera0_T_ground * f.ground_T_left).matrix();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) poses << m(r, c) << (r == 2 && c == 3 ? "\n" : " ");
    times << f.time_s << "\n";
    photo << f.left.gain << " " << f.left.bias_grey << " " << f.right.gain << " "
          << f.right.bias_grey << "\n";
  }
  closeText(poses, poses_path);
  closeText(times, times_path);
  closeText(photo, photo_path);
  renderer_.scene().toYaml((fs::path(dir) / "scene.yaml").string());

  const double fb = rig.disparityTimesDepth();
  for (const SequenceFrame& f : frames_) {
    const RenderedPair pair = render(f.index);
    writeImage(framePath(dir, "image_0", f.index), pair.left.image);
    writeImage(framePath(dir, "image_1", f.index), pair.right.image);
    if (!options_.write_truth_maps) continue;
    cv::Mat disp(pair.left.inverse_depth.size(), CV_16U);
    cv::Mat label(pair.left.label.size(), CV_16U);
    for (int v = 0; v < disp.rows; ++v) {
      const auto* inv = pair.left.inverse_depth.ptr<float>(v);
      const auto* lab = pair.left.label.ptr<int32_t>(v);
      auto* dp = disp.ptr<uint16_t>(v);
      auto* lp = label.ptr<uint16_t>(v);
      for (int u = 0; u < disp.cols; ++u) {
        const double d = 256.0 * fb * inv[u];
        dp[u] = static_cast<uint16_t>(std::min(65535.0, std::max(0.0, std::round(d))));
        lp[u] = static_cast<uint16_t>(std::min(65535, std::max(0, lab[u] + 1)));
      }
    }
    writeImage(framePath(dir, "disp_0", f.index), disp);
    writeImage(framePath(dir, "label_0", f.index), label);
  }
}

}  // namespace stereo_ground_dem::sim
