#pragma once
/// \file DemPublisher.hpp
/// The outputs of stereo_ground_dem/DemNodelet (docs/ros.md, "Topics" and "Frames and tf"): the
/// local and global HeightGrid and OccupancyGrid, the mesh, odometry with covariance, the path, the
/// camera's attitude above the local ground and tf odom -> base_link (through the static base_link -> camera transform, REP 105).
///
/// Threads: publish(), publishAttitude() and reset() run on the processing thread only (they own the trajectory,
/// covariance and tf state); anySubscriber() and setTraversability() may be called from any thread.

#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <std_msgs/Header.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include <deque>
#include <memory>
#include <mutex>
#include <string>

#include "stereo_ground_dem/ElevationMap.hpp"
#include "stereo_ground_dem/GroundAttitudeEstimator.hpp"
#include "stereo_ground_dem/IncrementalEstimator.hpp"
#include "stereo_ground_dem/ros/MapWindowSampler.hpp"
#include "stereo_ground_dem/ros/MotionCovariance.hpp"
#include "stereo_ground_dem/ros/RosNodeOptions.hpp"
#include "stereo_ground_dem/ros/TraversabilityCostTable.hpp"

namespace stereo_ground_dem {

class DemPublisher {
 public:
  DemPublisher(const RosNodeOptions& options, const TraversabilityOptions& traversability,
               const std::string& logger);

  /// Advertises every output on `pnh` (private topics) with `connect_cb` as the (dis)connect
  /// callback (lazy subscription), and starts the tf listener on `tf_nh` (its callbacks on that
  /// handle's queue: no thread of its own).
  void advertise(ros::NodeHandle& tf_nh, ros::NodeHandle& pnh, const ros::SubscriberStatusCallback& connect_cb);
  /// Any subscriber to any output topic (tf has no subscriber count).
  bool anySubscriber() const;
  /// Any subscriber to the whole-map topics (tests and the worker's global map timing).
  bool anyGlobalSubscriber() const;
  void setTraversability(const TraversabilityOptions& options);

  /// Publishes pose, tf, odometry, path and the local (and, at most global_map_rate_hz, the whole)
  /// map of one processed frame; `camera_frame` is the left optical frame; `extra` adds the layers
  /// kept beside the map. Returns a one-line text of the map's known extent (for diagnostics).
  std::string publish(const FrameResult& frame, const ElevationMap& map, const ros::Time& stamp,
                      const std::string& camera_frame, const ExtraLayerSources& extra = ExtraLayerSources());
  /// The camera above the local ground (~ground_attitude) of one mapped frame.
  void publishAttitude(const GroundAttitudeEstimate& attitude, const ros::Time& stamp, const std::string& camera_frame);
  /// The camera's mount on the robot from tf (RosNodeOptions::mount_from_tf): from footprint_frame
  /// -> `camera_frame` when tf has it (*have_height true), else the pitch and roll from base_frame
  /// -> `camera_frame` (*have_height false). The first lookup after a reset waits up to tf_wait_s
  /// for /tf_static. Returns false when tf has neither (or base_frame is ''); `source` names the
  /// transform used. Call from the processing thread.
  bool cameraMount(const std::string& camera_frame, NominalMount* mount, bool* have_height, std::string* source);
  /// Forgets the trajectory, the covariance and the cached camera mount (a new map).
  void reset();
  /// Unregisters every output and the tf listener; waits for a publish() in progress, after which
  /// publish() does nothing.
  void shutdown();

 private:
  bool baseTCamera(const std::string& camera_frame, Eigen::Isometry3d* base_T_camera);
  void publishPose(const FrameResult& fr, const std_msgs::Header& header, const std::string& camera_frame);
  void publishLayers(const DemLayers& d, const std_msgs::Header& header, ros::Publisher& grid_pub,
                     ros::Publisher& occupancy_pub, ros::Publisher* mesh_pub);
  MapWindowSampler sampler() const;

  const RosNodeOptions options_;
  const std::string logger_;
  std::mutex publish_mutex_;  ///< held by publish() and shutdown()
  bool shut_down_ = false;
  ros::Publisher pub_dem_, pub_dem_global_, pub_occupancy_, pub_occupancy_global_, pub_mesh_, pub_odom_, pub_path_,
      pub_attitude_;
  std::shared_ptr<tf2_ros::Buffer> tf_buffer_;
  std::shared_ptr<tf2_ros::TransformListener> tf_listener_;
  std::shared_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;

  mutable std::mutex traversability_mutex_;
  TraversabilityOptions traversability_;
  TraversabilityCostTable cost_table_;

  // processing thread only
  MotionCovariance covariance_;
  bool have_previous_pose_ = false;
  Eigen::Isometry3d previous_child_pose_ = Eigen::Isometry3d::Identity();
  std::string previous_child_frame_;
  double previous_stamp_s_ = 0.0;
  std::deque<geometry_msgs::PoseStamped> path_;
  bool have_base_T_camera_ = false;
  Eigen::Isometry3d base_T_camera_ = Eigen::Isometry3d::Identity();
  std::string base_T_camera_frame_;  ///< the camera frame the cached transform is for
  bool tf_waited_ = false;
  ros::WallTime last_tf_warning_;
  ros::WallTime last_global_publish_;
};

}  // namespace stereo_ground_dem
