#pragma once
/// \file RosNodeOptions.hpp
/// The nodelet's own private parameters (docs/ros.md, "Parameters"; the estimator's are the core's
/// ParameterTable names, read by PipelineParameters), read once in onInit and checked: load() throws
/// std::invalid_argument listing every invalid value, so the node refuses to start with the reason.

#include <ros/node_handle.h>

#include <string>
#include <vector>

#include "stereo_ground_dem/ros/HeightMeshBuilder.hpp"

namespace stereo_ground_dem {

struct RosNodeOptions {
  int queue_size = 5;                 ///< synchronizer and subscriber queues [messages]
  bool approximate_sync = false;      ///< approximate instead of exact time synchronization
  double slop_s = 0.01;               ///< approximate sync: max. stamp difference [s]
  bool lazy = true;                   ///< subscribe to the cameras only while an output has a subscriber
  /// Set the process allocator to reuse a frame's large buffers (AllocatorTuning: page faults
  /// 106,500 -> 22,800 on KITTI 06, 189 -> 166 ms median); process-wide, so a shared manager can opt out.
  bool tune_allocator = true;
  /// Hand the allocator's free memory back to the kernel every this many processed frames
  /// (AllocatorTuning::releaseFreeMemory; 0: never): with tune_allocator the manager otherwise
  /// keeps what it freed (2,000-frame soak: +19 MB resident over frames 200-2,000, 15 MB of it free).
  int release_memory_every_frames = 100;
  /// Once tracking starts (or restarts), this many frames with a velocity still make the worker
  /// hold the frame that follows them instead of the newest (StartHoldPolicy; 0: only the frames
  /// without a velocity): KITTI raw 0013's frames as the node kept them at 10 Hz, 2.92 -> 1.21 % drift.
  int start_hold_frames = 2;
  std::string odom_frame = "odom";
  std::string base_frame = "base_link";  ///< '' publishes odom -> camera frame
  std::string camera_frame;           ///< '' takes the left image's header.frame_id
  bool publish_tf = true;
  double tf_wait_s = 0.5;             ///< wait for base_frame -> camera on the first frame [s]
  /// Take the estimator's start-up guess of the mount (nominal_height_m, nominal_pitch_down_rad,
  /// nominal_roll_rad) from tf when it has the camera: all three from footprint_frame -> camera,
  /// or without that frame the pitch and roll from base_frame -> camera (its origin need not be on
  /// the ground) and the height from the parameter. false: the parameters only.
  bool mount_from_tf = true;
  std::string footprint_frame = "base_footprint";  ///< on the ground under the robot, z up (REP 120)
  double local_map_size_m = 50.0;     ///< side of the local window [m]
  double local_map_forward_m = 15.0;  ///< its centre ahead of the camera [m]
  double global_map_rate_hz = 0.5;    ///< whole-map topics at most this often [Hz]; 0: never
  int global_map_max_cells = 250000;  ///< decimation bound of the whole map and of get_submap
  int occupancy_unknown_below = 1;    ///< cells observed by fewer frames are -1 in the OccupancyGrid
  /// > 0.5: cells whose traversable / not decision is less certain (max(P, 1 - P) of the
  /// traversability_confidence layer) are -1 in the OccupancyGrid; 0: off
  double occupancy_min_certainty = 0.0;
  int path_max_poses = 2000;
  std::string save_directory = "stereo_ground_dem_map";  ///< default of ~save_map
  double diagnostic_period_s = 1.0;
  double input_check_period_s = 2.0;
  double unobserved_std_m = 0.5;      ///< covariance of frames without a motion estimate [m]
  double unobserved_std_rad = 0.1;    ///< ... [rad]
  /// Variance factor on the per-frame motion covariance from the estimator's information, which
  /// assumes independent pixel noise: on KITTI 06 (51 frames) the per-frame motion errors against
  /// the ground truth were 43-108x (translation) and 77-110x (rotation) its standard deviations,
  /// so the variances are scaled by 100^2.
  double motion_covariance_scale = 1e4;
  double restart_back_s = 0.05;       ///< a stamp older than the last by more starts a new map [s]
  double max_stamp_gap_s = 2.0;       ///< a stamp newer than the last by more starts a new map [s]
  std::string image_transport = "raw";
  HeightMeshOptions mesh;             ///< mesh_max_triangles

  /// Reads every name of names() from `pnh` (absent: the default above) and checks the values.
  static RosNodeOptions load(const ros::NodeHandle& pnh);
  /// The private parameter names the ROS layer reads.
  static const std::vector<std::string>& names();
};

}  // namespace stereo_ground_dem
