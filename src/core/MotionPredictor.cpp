#include "stereo_ground_dem/MotionPredictor.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stereo_ground_dem {

bool MotionPredictorOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(nominal_frame_period_s > 0.0)) return bad("nominal_frame_period_s must be > 0");
  if (!(search_max_m >= search_min_m)) return bad("need motion_search_max_m >= motion_search_min_m");
  if (!(search_step_m > 0.0) || !(search_max_step_m > 0.0)) return bad("the motion search steps must be > 0");
  if (!(search_max_reverse_m >= 0.0)) return bad("search_max_reverse_m must be >= 0");
  if (search_yaw_rad.empty()) return bad("search_yaw_rad needs at least one yaw rate (0)");
  for (double y : search_yaw_rad)
    if (!std::isfinite(y) || std::abs(y) > 0.5) return bad("search_yaw_rad values must be finite and within +-0.5 rad");
  for (double p : search_pitch_rad)
    if (!std::isfinite(p) || std::abs(p) > 0.2) return bad("search_pitch_rad values must be finite and within +-0.2 rad");
  if (!(rotation_step_rad > 0.0 && rotation_step_rad < 0.2)) return bad("rotation_step_rad must be in (0, 0.2)");
  return true;
}

MotionPredictor::MotionPredictor(const MotionPredictorOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("MotionPredictorOptions: " + why);
}

void MotionPredictor::reset() {
  last_camera_T_ground_.setIdentity();
  last_stamp_s_ = 0.0;
  velocity_.setZero();
  last_gap_s_ = 0.0;
  velocity_known_ = false;
  last_stamp_trusted_ = true;
}

void MotionPredictor::setPose(const Eigen::Isometry3d& camera_T_ground, double stamp_s) {
  last_camera_T_ground_ = camera_T_ground;
  last_stamp_s_ = stamp_s;
  velocity_.setZero();
  last_gap_s_ = 0.0;
  velocity_known_ = false;
  last_stamp_trusted_ = true;
}

void MotionPredictor::restore(const Eigen::Isometry3d& camera_T_ground, double stamp_s, const Vector6d& velocity,
                              double gap_s, bool velocity_known) {
  last_camera_T_ground_ = camera_T_ground;
  last_stamp_s_ = stamp_s;
  velocity_ = velocity;
  last_gap_s_ = gap_s;
  velocity_known_ = velocity_known;
  last_stamp_trusted_ = true;
}

void MotionPredictor::update(const Eigen::Isometry3d& camera_T_ground, double stamp_s) {
  if (!last_stamp_trusted_) {
    setPose(camera_T_ground, stamp_s);
    return;
  }
  const double dt = gap(stamp_s);
  velocity_ = Se3::log(camera_T_ground * last_camera_T_ground_.inverse()) / dt;
  velocity_known_ = true;
  last_gap_s_ = dt;
  last_camera_T_ground_ = camera_T_ground;
  last_stamp_s_ = stamp_s;
}

double MotionPredictor::gap(double stamp_s) const {
  const double dt = stamp_s - last_stamp_s_;
  return dt > 0.0 ? dt : options_.nominal_frame_period_s;
}

Eigen::Isometry3d MotionPredictor::predict(double stamp_s) const {
  if (!velocity_known_) return last_camera_T_ground_;
  return Se3::exp(velocity_ * gap(stamp_s)) * last_camera_T_ground_;
}

Eigen::Isometry3d MotionPredictor::coast(double stamp_s) const {
  return Se3::exp(velocity_ * gap(stamp_s)) * last_camera_T_ground_;
}

std::vector<Eigen::Isometry3d> MotionPredictor::hypotheses(double stamp_s) const {
  const double dt = gap(stamp_s);
  const Vector6d step = velocity_ * dt;
  Vector6d no_turn = step;
  no_turn.tail<3>().setZero();
  std::vector<Eigen::Isometry3d> out;
  out.push_back(Se3::exp(step) * last_camera_T_ground_);
  out.push_back(Se3::exp(no_turn) * last_camera_T_ground_);
  // attitude steps around the translation alone: a bump ends a pitch rate as often as it starts one
  for (const Eigen::Isometry3d& p : attitudeSteps(Se3::exp(no_turn) * last_camera_T_ground_)) out.push_back(p);
  for (double f : {0.5, 1.5}) out.push_back(Se3::exp(step * f) * last_camera_T_ground_);
  // A stamp gap unlike the last one may be a wrong stamp rather than dropped frames: the last
  // step as it was, whatever the stamps say.
  if (last_gap_s_ > 0.0 && (dt > 1.5 * last_gap_s_ || dt < last_gap_s_ / 1.5)) {
    out.push_back(Se3::exp(velocity_ * last_gap_s_) * last_camera_T_ground_);
  }
  return out;
}

std::vector<Eigen::Isometry3d> MotionPredictor::attitudeSteps(const Eigen::Isometry3d& camera_T_ground) const {
  // steps of rotation_step_rad and twice that about each camera axis: x (pitch) first, then z
  // (roll), then y (yaw)
  std::vector<Eigen::Isometry3d> out;
  const double d = options_.rotation_step_rad;
  for (double k : {1.0, 2.0}) {
    for (int axis : {0, 2, 1}) {
      for (double sign : {1.0, -1.0}) {
        Vector6d xi = Vector6d::Zero();
        xi[3 + axis] = sign * k * d;
        out.push_back(Se3::exp(xi) * camera_T_ground);
      }
    }
  }
  return out;
}

std::vector<Eigen::Isometry3d> MotionPredictor::searchGrid(double stamp_s) const {
  const double scale = gap(stamp_s) / options_.nominal_frame_period_s;
  const double t0 = std::max(options_.search_min_m * scale, -options_.search_max_reverse_m);
  const double t1 = options_.search_max_m * scale;
  const double step = std::min(options_.search_step_m * scale, options_.search_max_step_m);
  std::vector<Eigen::Isometry3d> out;
  for (double yaw : options_.search_yaw_rad) {
    for (double t = t0; t <= t1 + 1e-9; t += step) {
      Vector6d xi = Vector6d::Zero();
      xi[2] = -t;  // forward along the optical axis: new_T_old translates by -t along z
      xi[4] = yaw * scale;
      out.push_back(Se3::exp(xi) * last_camera_T_ground_);
    }
  }
  return out;
}

}  // namespace stereo_ground_dem
