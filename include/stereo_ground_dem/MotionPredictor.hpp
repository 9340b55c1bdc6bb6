#pragma once
/// \file MotionPredictor.hpp
/// Where the camera of the next frame probably is: the starting poses of the incremental mode's
/// motion-only pre-alignment (IncrementalEstimator, METHOD.md section 6).
///
/// With a known velocity: the constant-velocity prediction (scaled by the stamp gap, so dropped
/// frames are bridged), then hypotheses for what a constant velocity does not predict: the same
/// translation without the rotation rate (a bump's pitch rate ends), attitude steps of
/// `rotation_step_rad` and twice that about each camera axis (bouncing over rough ground: 2-3
/// degrees between frames), half / double the translation (braking, accelerating) and, when the
/// stamp gap differs from the last one by more than 1.5x, the last step unscaled (a wrong stamp,
/// not dropped frames). The tracker tries them in order until one aligns about as well as the
/// usual frame.
///
/// Without one (the first tracked frame, after a failure): a grid of forward translations along
/// the optical axis combined with yaw rates (a vehicle already turning on its first frame); the
/// tracker scores each by its photometric cost alone and aligns from the best few.

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "stereo_ground_dem/Se3.hpp"

namespace stereo_ground_dem {

struct MotionPredictorOptions {
  double nominal_frame_period_s = 0.1;  ///< used when stamps do not increase [s]
  /// The search without a velocity: translations along the optical axis from search_min_m to
  /// search_max_m per nominal frame period, scaled by the stamp gap [m] ...
  double search_min_m = -1.0;
  double search_max_m = 3.0;
  /// ... in steps of search_step_m per period, but never coarser than search_max_step_m [m] ...
  double search_step_m = 0.2;
  double search_max_step_m = 0.6;
  /// ... and never more than this backwards whatever the gap (vehicles rarely reverse) [m] ...
  double search_max_reverse_m = 1.0;
  /// ... combined with these yaw rates per nominal period (positive turns left) [rad].
  std::vector<double> search_yaw_rad = {0.0, 0.025, -0.025, 0.05, -0.05};
  /// ... and each translation's best heading pitched by these angles (positive: down), not scaled
  /// by the gap (a vehicle's pitch does not accumulate) [rad].
  std::vector<double> search_pitch_rad = {0.02, -0.02, 0.04, -0.04};
  double rotation_step_rad = 0.026;     ///< attitude step of the rotation hypotheses (1.5 deg)

  bool isValid(std::string* why) const;
};

class MotionPredictor {
 public:
  explicit MotionPredictor(const MotionPredictorOptions& options = MotionPredictorOptions());

  /// Forgets everything.
  void reset();
  /// A pose whose velocity is unknown (initialization, relocalization).
  void setPose(const Eigen::Isometry3d& camera_T_ground, double stamp_s);
  /// A tracked frame: the velocity becomes the step from the last pose over the stamp gap.
  void update(const Eigen::Isometry3d& camera_T_ground, double stamp_s);
  /// After a failure: the velocity is no longer trusted (the last pose stays; coast() still
  /// extrapolates with it).
  void forgetVelocity() { velocity_known_ = false; }
  /// Dead reckoning: the last pose moved on at the last measured velocity, trusted or not (no
  /// velocity since reset() or setPose(): the last pose). The pose of a frame that failed, and
  /// where a re-initialization after failures places the camera: standing still instead lost the
  /// distance driven meanwhile (the rolling scene from 0.8 m: 4 m over three failed frames).
  Eigen::Isometry3d coast(double stamp_s) const;
  /// Puts back a state read from lastPose(), lastStamp(), velocity(), lastGap() and
  /// velocityKnown() (a saved map continued in another run).
  void restore(const Eigen::Isometry3d& camera_T_ground, double stamp_s, const Vector6d& velocity, double gap_s,
               bool velocity_known);
  /// The last stamp is a guess (a state continued on another clock: EstimatorState::rebaseClock),
  /// so the step to the next pose took an unknown time: the next update() places that pose without
  /// measuring a velocity (as setPose()), the one after it measures one again. A sequence resumed
  /// one frame earlier than its saved state took the step back as -12 m/s.
  void distrustLastStamp() { last_stamp_trusted_ = false; }

  bool velocityKnown() const { return velocity_known_; }
  const Vector6d& velocity() const { return velocity_; }  ///< twist per second, camera frame
  const Eigen::Isometry3d& lastPose() const { return last_camera_T_ground_; }
  double lastStamp() const { return last_stamp_s_; }
  double lastGap() const { return last_gap_s_; }  ///< the stamp gap the velocity was measured over [s]
  /// The time since the last pose, or the nominal period when stamps do not increase [s].
  double gap(double stamp_s) const;

  /// The constant-velocity prediction (the last pose when the velocity is unknown).
  Eigen::Isometry3d predict(double stamp_s) const;
  /// Starting poses with a known velocity, most likely first (see the file comment).
  std::vector<Eigen::Isometry3d> hypotheses(double stamp_s) const;
  /// `camera_T_ground` turned by one and two rotation steps about each camera axis (12 poses).
  std::vector<Eigen::Isometry3d> attitudeSteps(const Eigen::Isometry3d& camera_T_ground) const;
  /// The search grid without a velocity (see the file comment).
  std::vector<Eigen::Isometry3d> searchGrid(double stamp_s) const;

  const MotionPredictorOptions& options() const { return options_; }

 private:
  MotionPredictorOptions options_;
  Eigen::Isometry3d last_camera_T_ground_ = Eigen::Isometry3d::Identity();
  double last_stamp_s_ = 0.0;
  Vector6d velocity_ = Vector6d::Zero();
  double last_gap_s_ = 0.0;  ///< the stamp gap the velocity was measured over [s]
  bool velocity_known_ = false;
  bool last_stamp_trusted_ = true;  ///< false: the next update() measures no velocity
};

}  // namespace stereo_ground_dem
