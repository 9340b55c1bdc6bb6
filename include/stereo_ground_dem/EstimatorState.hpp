#pragma once
/// \file EstimatorState.hpp
/// Everything an IncrementalEstimator carries from one frame to the next, apart from the map: the
/// ground frame, the last good pose and the velocity, the previous images (the temporal pairs'
/// partners), the running residual levels, the rectification estimate and the counters. Saved
/// with the map (io/MapStateFile.hpp), it lets a later run continue the same map as if the frames
/// had come in one run (`dem_offline --resume`, `~load_map`).

#include <Eigen/Geometry>
#include <array>
#include <opencv2/core.hpp>
#include <vector>

#include "stereo_ground_dem/PhotometricParams.hpp"
#include "stereo_ground_dem/Se3.hpp"
#include "stereo_ground_dem/VerticalMisalignment.hpp"

namespace stereo_ground_dem {

struct EstimatorState {
  bool initialized = false;
  int frame_counter = 0;  ///< frames processed so far (the next frame's FrameResult::frame_index)
  Eigen::Isometry3d ground_T_camera0 = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d ground_T_camera = Eigen::Isometry3d::Identity();  ///< last good frame
  // the motion predictor
  Eigen::Isometry3d last_camera_T_ground = Eigen::Isometry3d::Identity();
  double last_stamp_s = 0.0;
  Vector6d velocity = Vector6d::Zero();  ///< twist per second, camera frame
  double velocity_gap_s = 0.0;
  bool velocity_known = false;
  // running levels of good frames
  double residual_level_grey = 0.0;
  double temporal_residual_level_grey = 0.0;  ///< ... of the temporal pair (0: unknown)
  double prealign_level = 0.0;
  double observed_level_vertices = 0.0;  ///< ... of the ground vertices observed per frame (0: unknown)
  std::array<PhotometricParams, 3> last_photometric;
  int consecutive_failures = 0;
  int failures_total = 0;
  int recoveries = 0;
  int rejected_total = 0;
  // the rectification: the monitor's normal equations and the model in use
  Matrix6d rectification_information = Matrix6d::Zero();
  Vector6d rectification_information_vector = Vector6d::Zero();
  int rectification_pairs = 0;
  VerticalMisalignment rectification;
  bool rectification_set = false;
  /// The last good frame's level-0 pyramid images (CV_32F grey, 8-bit units, pre-smoothed: the
  /// pyramid is rebuilt from them without smoothing again), its obstacle and moving-texture masks
  /// per level (CV_8U; the latter empty when nothing moved), the moving texture it shares with the
  /// frame before it (carried into the next frame), and the last accepted left image (the
  /// frozen-frame test).
  cv::Mat previous_left, previous_right;
  std::vector<cv::Mat> previous_obstacles;
  std::vector<cv::Mat> previous_moving, carried_moving;
  cv::Mat last_left;

  /// For a state continued on another clock (a node restarted, a ROS-stamped state continued
  /// offline, a sequence resumed at an earlier frame): the saved velocity and stamp do not apply,
  /// so the next frame (stamped next_stamp_s) is searched from the saved pose as after a failure,
  /// one nominal frame period later.
  void rebaseClock(double next_stamp_s, double nominal_frame_period_s) {
    last_stamp_s = next_stamp_s - nominal_frame_period_s;
    velocity = Vector6d::Zero();
    velocity_gap_s = 0.0;
    velocity_known = false;
    clock_rebased = true;
  }
  /// Set by rebaseClock() (not saved): the first step after it measures no velocity
  /// (MotionPredictor::distrustLastStamp).
  bool clock_rebased = false;
};

}  // namespace stereo_ground_dem
