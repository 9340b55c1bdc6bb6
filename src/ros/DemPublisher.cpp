#include "stereo_ground_dem/ros/DemPublisher.hpp"

#include <nav_msgs/OccupancyGrid.h>
#include <nav_msgs/Odometry.h>
#include <tf2_eigen/tf2_eigen.h>
#include <visualization_msgs/Marker.h>

#include <sstream>

#include "stereo_ground_dem/GroundAttitude.h"
#include "stereo_ground_dem/HeightGrid.h"
#include "stereo_ground_dem/ros/HeightGridConverter.hpp"
#include "stereo_ground_dem/ros/HeightMeshBuilder.hpp"

namespace stereo_ground_dem {

DemPublisher::DemPublisher(const RosNodeOptions& options, const TraversabilityOptions& traversability,
                           const std::string& logger)
    : options_(options), logger_(logger), traversability_(traversability) {
  MapWindowSampler check(traversability);  // throws on invalid options, before anything runs
}

void DemPublisher::advertise(ros::NodeHandle& tf_nh, ros::NodeHandle& pnh,
                             const ros::SubscriberStatusCallback& cb) {
  tf_buffer_ = std::make_shared<tf2_ros::Buffer>();
  tf_listener_ = std::make_shared<tf2_ros::TransformListener>(*tf_buffer_, tf_nh, false);
  // tf_nh's queue is spun by threads other than the one that waits in canTransform (the worker)
  tf_buffer_->setUsingDedicatedThread(true);
  tf_broadcaster_ = std::make_shared<tf2_ros::TransformBroadcaster>();
  pub_dem_ = pnh.advertise<HeightGrid>("dem", 1, cb, cb);
  pub_dem_global_ = pnh.advertise<HeightGrid>("dem_global", 1, cb, cb, ros::VoidConstPtr(), true);
  pub_occupancy_ = pnh.advertise<nav_msgs::OccupancyGrid>("traversability", 1, cb, cb);
  pub_occupancy_global_ =
      pnh.advertise<nav_msgs::OccupancyGrid>("traversability_global", 1, cb, cb, ros::VoidConstPtr(), true);
  pub_mesh_ = pnh.advertise<visualization_msgs::Marker>("mesh", 1, cb, cb);
  pub_odom_ = pnh.advertise<nav_msgs::Odometry>("odom", 10, cb, cb);
  pub_path_ = pnh.advertise<nav_msgs::Path>("path", 1, cb, cb);
  pub_attitude_ = pnh.advertise<GroundAttitude>("ground_attitude", 10, cb, cb);
}

bool DemPublisher::anySubscriber() const {
  return pub_dem_.getNumSubscribers() + pub_occupancy_.getNumSubscribers() + pub_mesh_.getNumSubscribers() +
             pub_odom_.getNumSubscribers() + pub_path_.getNumSubscribers() + pub_attitude_.getNumSubscribers() >
             0 ||
         anyGlobalSubscriber();
}

bool DemPublisher::anyGlobalSubscriber() const {
  return pub_dem_global_.getNumSubscribers() + pub_occupancy_global_.getNumSubscribers() > 0;
}

void DemPublisher::setTraversability(const TraversabilityOptions& options) {
  std::lock_guard<std::mutex> lock(traversability_mutex_);
  traversability_ = options;
}

MapWindowSampler DemPublisher::sampler() const {
  std::lock_guard<std::mutex> lock(traversability_mutex_);
  return MapWindowSampler(traversability_);
}

void DemPublisher::shutdown() {
  std::lock_guard<std::mutex> lock(publish_mutex_);
  shut_down_ = true;
  for (ros::Publisher* p : {&pub_dem_, &pub_dem_global_, &pub_occupancy_, &pub_occupancy_global_, &pub_mesh_,
                            &pub_odom_, &pub_path_, &pub_attitude_}) {
    p->shutdown();
  }
  tf_listener_.reset();
  tf_broadcaster_.reset();
}

void DemPublisher::reset() {
  std::lock_guard<std::mutex> lock(publish_mutex_);
  covariance_.reset();
  have_previous_pose_ = false;
  path_.clear();
  have_base_T_camera_ = false;
  tf_waited_ = false;
  last_global_publish_ = ros::WallTime();
  if (tf_buffer_) tf_buffer_->clear();
}

bool DemPublisher::baseTCamera(const std::string& camera_frame, Eigen::Isometry3d* base_T_camera) {
  if (options_.base_frame.empty()) return false;
  if (have_base_T_camera_ && base_T_camera_frame_ == camera_frame) {
    *base_T_camera = base_T_camera_;
    return true;
  }
  const double wait = tf_waited_ ? 0.0 : options_.tf_wait_s;  // the first frame waits for /tf_static
  tf_waited_ = true;
  std::string err;
  if (tf_buffer_->canTransform(options_.base_frame, camera_frame, ros::Time(0), ros::Duration(wait), &err)) {
    try {
      base_T_camera_ =
          tf2::transformToEigen(tf_buffer_->lookupTransform(options_.base_frame, camera_frame, ros::Time(0)));
      have_base_T_camera_ = true;
      base_T_camera_frame_ = camera_frame;
      ROS_INFO_NAMED(logger_, "using tf %s -> %s: publishing %s -> %s", options_.base_frame.c_str(),
                     camera_frame.c_str(), options_.odom_frame.c_str(), options_.base_frame.c_str());
      *base_T_camera = base_T_camera_;
      return true;
    } catch (const tf2::TransformException& e) {
      err = e.what();
    }
  }
  return false;
}

bool DemPublisher::cameraMount(const std::string& camera_frame, NominalMount* mount, bool* have_height,
                               std::string* source) {
  std::lock_guard<std::mutex> lock(publish_mutex_);
  if (shut_down_) return false;
  Eigen::Isometry3d base_T_camera;
  if (!baseTCamera(camera_frame, &base_T_camera)) return false;  // waits for /tf_static the first time
  *have_height = false;
  *source = options_.base_frame + " -> " + camera_frame + " (pitch, roll)";
  if (!options_.footprint_frame.empty() &&
      tf_buffer_->canTransform(options_.footprint_frame, camera_frame, ros::Time(0), ros::Duration(0.0))) {
    try {
      base_T_camera =
          tf2::transformToEigen(tf_buffer_->lookupTransform(options_.footprint_frame, camera_frame, ros::Time(0)));
      *have_height = true;
      *source = options_.footprint_frame + " -> " + camera_frame;
    } catch (const tf2::TransformException&) {
      // as without the footprint frame
    }
  }
  *mount = StereoEstimator::nominalMount(base_T_camera);
  return true;
}

void DemPublisher::publishPose(const FrameResult& fr, const std_msgs::Header& header,
                               const std::string& camera_frame) {
  Eigen::Isometry3d base_T_camera = Eigen::Isometry3d::Identity();
  const bool have_base = baseTCamera(camera_frame, &base_T_camera);
  const std::string child = have_base ? options_.base_frame : camera_frame;
  const Eigen::Isometry3d odom_T_child = fr.ground_T_camera * base_T_camera.inverse();
  bool publish_tf = options_.publish_tf;
  const ros::WallTime now = ros::WallTime::now();
  if (!have_base && !options_.base_frame.empty() && (now - last_tf_warning_).toSec() > 10.0) {
    last_tf_warning_ = now;
    std::string parent;
    if (tf_buffer_->_getParent(camera_frame, ros::Time(0), parent) && parent != options_.odom_frame) {
      ROS_ERROR_NAMED(logger_,
                      "tf: '%s' already has the parent '%s' but no path to ~base_frame '%s': not publishing tf "
                      "(it would give '%s' two parents). Set ~base_frame to the root of that tree.",
                      camera_frame.c_str(), parent.c_str(), options_.base_frame.c_str(), camera_frame.c_str());
    } else {
      ROS_WARN_NAMED(logger_,
                     "tf: no transform from ~base_frame '%s' to the camera frame '%s' (the camera mount; publish "
                     "it with a static_transform_publisher or robot_state_publisher): publishing %s -> %s and "
                     "odometry of the camera instead. Set ~base_frame to '' to do so on purpose.",
                     options_.base_frame.c_str(), camera_frame.c_str(), options_.odom_frame.c_str(),
                     camera_frame.c_str());
    }
  }
  if (!have_base) {
    std::string parent;
    if (tf_buffer_->_getParent(camera_frame, ros::Time(0), parent) && parent != options_.odom_frame) {
      publish_tf = false;
    }
  }
  if (publish_tf) {
    geometry_msgs::TransformStamped t = tf2::eigenToTransform(odom_T_child);
    t.header = header;
    t.child_frame_id = child;
    tf_broadcaster_->sendTransform(t);
  }

  // covariance (MotionCovariance.hpp explains the conversion)
  const bool first = fr.status == FrameStatus::kInitialized || !have_previous_pose_ || previous_child_frame_ != child;
  bool fallback = false;
  const Matrix6d inc_camera = MotionCovariance::fromInformation(
      fr.motion_information / options_.motion_covariance_scale, MotionCovariance::diagonal(options_.unobserved_std_m, options_.unobserved_std_rad),
      &fallback);
  const Matrix6d inc_child = have_base ? MotionCovariance::changeFrame(inc_camera, base_T_camera) : inc_camera;
  nav_msgs::Odometry odom;
  odom.header = header;
  odom.child_frame_id = child;
  odom.pose.pose = tf2::toMsg(odom_T_child);
  if (first) {
    covariance_.reset();
  } else {
    const Eigen::Isometry3d delta = previous_child_pose_.inverse() * odom_T_child;
    covariance_.accumulate(delta, inc_child);
    const double dt = header.stamp.toSec() - previous_stamp_s_;
    if (dt > 1e-6) {
      const Vector6d twist = Se3::log(delta) / dt;
      odom.twist.twist.linear.x = twist[0];
      odom.twist.twist.linear.y = twist[1];
      odom.twist.twist.linear.z = twist[2];
      odom.twist.twist.angular.x = twist[3];
      odom.twist.twist.angular.y = twist[4];
      odom.twist.twist.angular.z = twist[5];
      odom.twist.covariance = MotionCovariance::toArray(inc_child / (dt * dt));
    }
  }
  odom.pose.covariance =
      MotionCovariance::toArray(MotionCovariance::rotate(covariance_.poseCovarianceInChild(), odom_T_child.linear()));
  if (first) odom.twist.covariance[0] = -1.0;  // the twist is unknown on the first frame
  have_previous_pose_ = true;
  previous_child_pose_ = odom_T_child;
  previous_child_frame_ = child;
  previous_stamp_s_ = header.stamp.toSec();
  if (pub_odom_.getNumSubscribers() > 0) pub_odom_.publish(odom);

  geometry_msgs::PoseStamped ps;
  ps.header = header;
  ps.pose = odom.pose.pose;
  path_.push_back(ps);
  while (static_cast<int>(path_.size()) > options_.path_max_poses) path_.pop_front();
  if (pub_path_.getNumSubscribers() > 0) {
    nav_msgs::Path path;
    path.header = header;
    path.poses.assign(path_.begin(), path_.end());
    pub_path_.publish(path);
  }
}

void DemPublisher::publishLayers(const DemLayers& d, const std_msgs::Header& header, ros::Publisher& grid_pub,
                                 ros::Publisher& occupancy_pub, ros::Publisher* mesh_pub) {
  if (grid_pub.getNumSubscribers() > 0) grid_pub.publish(HeightGridConverter::toMessage(d.grid, d.layers, header));
  if (occupancy_pub.getNumSubscribers() > 0) {
    occupancy_pub.publish(cost_table_.toOccupancyGrid(d.grid, *d.find("traversability"), *d.find("observations"),
                                                      options_.occupancy_unknown_below, header, *d.find("obstacle"),
                                                      *d.find("traversability_confidence"),
                                                      options_.occupancy_min_certainty));
  }
  if (mesh_pub && mesh_pub->getNumSubscribers() > 0) {
    mesh_pub->publish(HeightMeshBuilder::build(d.grid, *d.find("elevation"), header, options_.mesh, d.find("intensity"),
                                              d.find("residual")));
  }
}

std::string DemPublisher::publish(const FrameResult& fr, const ElevationMap& map, const ros::Time& stamp,
                                  const std::string& camera_frame, const ExtraLayerSources& extra) {
  std::lock_guard<std::mutex> lock(publish_mutex_);
  if (shut_down_) return "";
  std_msgs::Header header;
  header.stamp = stamp;
  header.frame_id = options_.odom_frame;
  publishPose(fr, header, camera_frame);

  const MapWindowSampler s = sampler();
  if (pub_dem_.getNumSubscribers() + pub_occupancy_.getNumSubscribers() + pub_mesh_.getNumSubscribers() > 0) {
    // the local window: axis-aligned square ahead of the camera
    Eigen::Vector2d forward = fr.ground_T_camera.linear().col(2).head<2>();
    forward = forward.norm() > 1e-6 ? forward.normalized() : Eigen::Vector2d::UnitX();
    const Eigen::Vector2d c = fr.ground_T_camera.translation().head<2>() + options_.local_map_forward_m * forward;
    const GroundGrid w = MapWindowSampler::window(map.options().resolution_m, c.x(), c.y(), options_.local_map_size_m,
                                                  options_.local_map_size_m);
    publishLayers(s.sample(map, w, options_.global_map_max_cells, extra), header, pub_dem_, pub_occupancy_, &pub_mesh_);
  }
  const GroundGrid known = map.knownBounds();
  const ros::WallTime now = ros::WallTime::now();
  if (options_.global_map_rate_hz > 0.0 && (now - last_global_publish_).toSec() >= 1.0 / options_.global_map_rate_hz &&
      anyGlobalSubscriber() && known.rows > 1 && known.cols > 1) {
    last_global_publish_ = now;
    publishLayers(s.sample(map, known, options_.global_map_max_cells, extra), header, pub_dem_global_, pub_occupancy_global_,
                  nullptr);
  }
  std::ostringstream extent;
  extent.precision(1);
  extent << std::fixed << "x " << known.x0() << " .. " << known.xOfCol(known.cols - 1) << ", y " << known.y0()
         << " .. " << known.yOfRow(known.rows - 1) << " m (" << known.cols << " x " << known.rows << ")";
  return extent.str();
}

void DemPublisher::publishAttitude(const GroundAttitudeEstimate& a, const ros::Time& stamp,
                                   const std::string& camera_frame) {
  std::lock_guard<std::mutex> lock(publish_mutex_);
  if (shut_down_ || pub_attitude_.getNumSubscribers() == 0) return;
  GroundAttitude msg;
  msg.header.stamp = stamp;
  msg.header.frame_id = camera_frame;
  msg.valid = a.valid;
  msg.height = a.height_m;
  msg.pitch = a.pitch_rad;
  msg.roll = a.roll_rad;
  msg.ground_slope = a.slope_rad;
  msg.rms = a.rms_m;
  msg.vertices = a.vertices;
  pub_attitude_.publish(msg);
}

}  // namespace stereo_ground_dem
