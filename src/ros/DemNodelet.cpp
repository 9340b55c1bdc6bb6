// stereo_ground_dem/DemNodelet: synchronized rectified stereo in; DEM (HeightGrid), traversability
// (OccupancyGrid), mesh (Marker), Odometry, Path and tf out. The callback converts messages,
// calls the core's IncrementalEstimator, converts back and publishes; every conversion lives in a
// small tested class (include/stereo_ground_dem/ros/). Topics, parameters and frames: docs/ros.md.
#include <cv_bridge/cv_bridge.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <image_transport/image_transport.h>
#include <image_transport/subscriber_filter.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/sync_policies/exact_time.h>
#include <message_filters/synchronizer.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_srvs/Trigger.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/Marker.h>

#include <pluginlib/class_list_macros.hpp>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <memory>
#include <mutex>
#include <sstream>

#include "stereo_ground_dem/DemParametersConfig.h"
#include "stereo_ground_dem/GetSubmap.h"
#include "stereo_ground_dem/HeightGrid.h"
#include "stereo_ground_dem/IncrementalEstimator.hpp"
#include "stereo_ground_dem/ParameterTable.hpp"
#include "stereo_ground_dem/SaveMap.h"
#include "stereo_ground_dem/io/DemExporter.hpp"
#include "stereo_ground_dem/ros/HeightGridConverter.hpp"
#include "stereo_ground_dem/ros/HeightMeshBuilder.hpp"
#include "stereo_ground_dem/ros/InputMonitor.hpp"
#include "stereo_ground_dem/ros/MapWindowSampler.hpp"
#include "stereo_ground_dem/ros/MotionCovariance.hpp"
#include "stereo_ground_dem/ros/PipelineParameters.hpp"
#include "stereo_ground_dem/ros/StereoInputValidator.hpp"
#include "stereo_ground_dem/ros/TraversabilityCostTable.hpp"

namespace stereo_ground_dem {

namespace {

/// The ROS layer's own private parameters (the rest are ParameterTable names).
const std::vector<std::string> kRosParameters = {
    "queue_size", "approximate_sync", "slop_s", "lazy", "odom_frame", "base_frame", "camera_frame",
    "publish_tf", "tf_wait_s", "local_map_size_m", "local_map_forward_m", "global_map_rate_hz",
    "global_map_max_cells", "mesh_max_triangles", "occupancy_unknown_below", "path_max_poses",
    "save_directory", "diagnostic_period_s", "input_check_period_s", "unobserved_std_m", "unobserved_std_rad",
    "image_transport"};

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + v[i];
  return s;
}

}  // namespace

class DemNodelet : public nodelet::Nodelet {
 public:
  ~DemNodelet() override;

 private:
  using Image = sensor_msgs::Image;
  using Info = sensor_msgs::CameraInfo;
  using ExactPolicy = message_filters::sync_policies::ExactTime<Image, Info, Image, Info>;
  using ApproxPolicy = message_filters::sync_policies::ApproximateTime<Image, Info, Image, Info>;
  using ReconfigureServer = dynamic_reconfigure::Server<DemParametersConfig>;

  /// Counters and the last problem, for diagnostics (guarded by stats_mutex_).
  struct Stats {
    long synchronized = 0, processed = 0, initialized = 0, tracked = 0, recovered = 0, failed = 0, rejected = 0,
         skipped = 0;
    int consecutive_bad = 0;
    double last_ms = 0.0, sum_ms = 0.0, max_ms = 0.0;
    double last_latency_ms = std::numeric_limits<double>::quiet_NaN();
    std::string last_problem;
    bool last_problem_error = false;  ///< a skipped frame or a failure to start (not a warning)
    ros::WallTime last_problem_time;
    long synchronized_at_last_report = 0;
    ros::WallTime last_report_time;
    size_t map_tiles = 0;
    double map_memory_mb = 0.0;
    std::string map_extent;
    std::string status;  ///< core status of the last frame
  };

  void onInit() override;
  void readParameters();
  void connectCb();
  bool anySubscriber() const;
  void frameCb(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::CameraInfoConstPtr& left_info,
               const sensor_msgs::ImageConstPtr& right, const sensor_msgs::CameraInfoConstPtr& right_info);
  void countInput(InputMonitor::Topic topic, const ros::Time& stamp);
  void checkInputs(const ros::WallTimerEvent&);
  void reconfigureCb(DemParametersConfig& config, uint32_t level);
  bool resetSrv(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res);
  bool saveSrv(SaveMap::Request& req, SaveMap::Response& res);
  bool submapSrv(GetSubmap::Request& req, GetSubmap::Response& res);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);

  /// Records a problem: counted, shown on diagnostics, logged (as error or warning) when it
  /// differs from the last logged one or every 5 s.
  void reportProblem(const std::string& problem, bool error, bool skipped_frame);
  // with state_mutex_ held:
  void createEstimatorLocked(const StereoRig& rig);
  void resetLocked(const std::string& why);
  bool baseTCameraLocked(const std::string& camera_frame, Eigen::Isometry3d* base_T_camera);
  void publishPoseLocked(const FrameResult& fr, const std_msgs::Header& header, const std::string& camera_frame);
  void publishMapsLocked(const FrameResult& fr, const std_msgs::Header& header);
  void publishLayers(const DemLayers& d, const std_msgs::Header& header, ros::Publisher& grid_pub,
                     ros::Publisher& occupancy_pub, ros::Publisher* mesh_pub);

  // ---- parameters (fixed after onInit, except options_ through dynamic_reconfigure)
  int queue_size_ = 5;
  bool approximate_sync_ = false;
  double slop_s_ = 0.01;
  bool lazy_ = true;
  std::string odom_frame_, base_frame_, camera_frame_param_;
  bool publish_tf_ = true;
  double tf_wait_s_ = 0.5;
  double local_map_size_m_ = 50.0, local_map_forward_m_ = 15.0;
  double global_map_rate_hz_ = 0.5;
  int global_map_max_cells_ = 250000;
  int occupancy_unknown_below_ = 1;
  int path_max_poses_ = 2000;
  std::string save_directory_;
  double unobserved_std_m_ = 0.5, unobserved_std_rad_ = 0.1;
  HeightMeshOptions mesh_options_;

  // ---- ROS plumbing
  std::shared_ptr<image_transport::ImageTransport> it_;
  image_transport::SubscriberFilter sub_left_image_, sub_right_image_;
  message_filters::Subscriber<Info> sub_left_info_, sub_right_info_;
  std::shared_ptr<message_filters::Synchronizer<ExactPolicy>> exact_sync_;
  std::shared_ptr<message_filters::Synchronizer<ApproxPolicy>> approx_sync_;
  ros::Publisher pub_dem_, pub_dem_global_, pub_occupancy_, pub_occupancy_global_, pub_mesh_, pub_odom_, pub_path_;
  ros::ServiceServer srv_reset_, srv_save_, srv_submap_;
  std::shared_ptr<tf2_ros::Buffer> tf_buffer_;
  std::shared_ptr<tf2_ros::TransformListener> tf_listener_;
  std::shared_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  std::shared_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diagnostic_timer_, input_timer_;
  boost::recursive_mutex reconfigure_mutex_;
  std::shared_ptr<ReconfigureServer> reconfigure_server_;
  bool first_reconfigure_ = true;

  std::mutex connect_mutex_;  ///< subscription state
  bool subscribed_ = false;
  ros::WallTime subscribed_since_;

  std::mutex monitor_mutex_;
  std::unique_ptr<InputMonitor> monitor_;

  std::mutex stats_mutex_;
  Stats stats_;
  std::string last_logged_problem_;
  ros::WallTime last_logged_time_;

  // ---- the pipeline (guarded by state_mutex_)
  std::mutex state_mutex_;
  PipelineOptions options_;
  std::unique_ptr<IncrementalEstimator> estimator_;
  StereoRig rig_;
  bool estimator_options_pending_ = false;
  MapWindowSampler sampler_;
  TraversabilityCostTable cost_table_;
  MotionCovariance covariance_;
  StereoInputValidator validator_;  // frame callback only (single-threaded queue)
  double last_stamp_s_ = -1.0;
  bool have_previous_pose_ = false;
  Eigen::Isometry3d previous_child_pose_ = Eigen::Isometry3d::Identity();
  std::string previous_child_frame_;
  double previous_stamp_s_ = 0.0;
  std::deque<geometry_msgs::PoseStamped> path_;
  std::vector<Eigen::Vector2d> trajectory_xy_;
  bool have_base_T_camera_ = false;
  Eigen::Isometry3d base_T_camera_ = Eigen::Isometry3d::Identity();
  std::string base_T_camera_frame_;  ///< the camera frame the cached transform is for
  bool tf_waited_ = false;
  ros::WallTime last_tf_warning_;
  ros::WallTime last_global_publish_;
  ros::Time last_header_stamp_;
};

DemNodelet::~DemNodelet() {
  diagnostic_timer_.stop();
  input_timer_.stop();
  std::lock_guard<std::mutex> lock(connect_mutex_);
  sub_left_image_.unsubscribe();
  sub_right_image_.unsubscribe();
  sub_left_info_.unsubscribe();
  sub_right_info_.unsubscribe();
}

void DemNodelet::readParameters() {
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  // the pipeline: every ParameterTable entry, validated once; refuse to start otherwise
  try {
    options_ = PipelineParameters::load([&pnh](const std::string& name, XmlRpc::XmlRpcValue* v) {
      return pnh.getParam(name, *v);
    });
  } catch (const std::invalid_argument& e) {
    NODELET_FATAL("refusing to start: %s", e.what());
    throw std::runtime_error(std::string("stereo_ground_dem/DemNodelet: ") + e.what());
  }
  // the ROS layer
  pnh.param("queue_size", queue_size_, 5);
  pnh.param("approximate_sync", approximate_sync_, false);
  pnh.param("slop_s", slop_s_, 0.01);
  pnh.param("lazy", lazy_, true);
  pnh.param<std::string>("odom_frame", odom_frame_, "odom");
  pnh.param<std::string>("base_frame", base_frame_, "base_link");
  pnh.param<std::string>("camera_frame", camera_frame_param_, "");
  pnh.param("publish_tf", publish_tf_, true);
  pnh.param("tf_wait_s", tf_wait_s_, 0.5);
  pnh.param("local_map_size_m", local_map_size_m_, 50.0);
  pnh.param("local_map_forward_m", local_map_forward_m_, 15.0);
  pnh.param("global_map_rate_hz", global_map_rate_hz_, 0.5);
  pnh.param("global_map_max_cells", global_map_max_cells_, 250000);
  pnh.param("mesh_max_triangles", mesh_options_.max_triangles, 60000);
  pnh.param("occupancy_unknown_below", occupancy_unknown_below_, 1);
  pnh.param("path_max_poses", path_max_poses_, 2000);
  pnh.param<std::string>("save_directory", save_directory_, "stereo_ground_dem_map");
  pnh.param("unobserved_std_m", unobserved_std_m_, 0.5);
  pnh.param("unobserved_std_rad", unobserved_std_rad_, 0.1);
  std::vector<std::string> bad;
  if (queue_size_ < 1) bad.push_back("~queue_size must be >= 1");
  if (!(slop_s_ > 0.0)) bad.push_back("~slop_s must be > 0");
  if (odom_frame_.empty()) bad.push_back("~odom_frame must not be empty");
  if (!(local_map_size_m_ > 0.0)) bad.push_back("~local_map_size_m must be > 0");
  if (!(global_map_rate_hz_ >= 0.0)) bad.push_back("~global_map_rate_hz must be >= 0");
  if (global_map_max_cells_ < 4) bad.push_back("~global_map_max_cells must be >= 4");
  if (mesh_options_.max_triangles < 2) bad.push_back("~mesh_max_triangles must be >= 2");
  if (path_max_poses_ < 1) bad.push_back("~path_max_poses must be >= 1");
  if (!(unobserved_std_m_ > 0.0) || !(unobserved_std_rad_ > 0.0)) bad.push_back("~unobserved_std_* must be > 0");
  if (!bad.empty()) {
    NODELET_FATAL("refusing to start: %s", joined(bad).c_str());
    throw std::runtime_error("stereo_ground_dem/DemNodelet: " + joined(bad));
  }
  // typos: private parameters nobody reads
  std::vector<std::string> all, mine;
  ros::param::getParamNames(all);
  const std::string prefix = pnh.getNamespace() + "/";
  for (const std::string& n : all) {
    if (n.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string rest = n.substr(prefix.size());
    if (rest.find('/') == std::string::npos) mine.push_back(rest);
  }
  const std::vector<std::string> unknown = PipelineParameters::unknown(mine, kRosParameters);
  if (!unknown.empty()) {
    NODELET_WARN("ignoring unknown private parameters (typos?): %s. Known names: docs/ros.md and docs/parameters.md",
                 joined(unknown).c_str());
  }
}

void DemNodelet::onInit() {
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  ros::NodeHandle& mt_pnh = getMTPrivateNodeHandle();
  readParameters();
  sampler_.setTraversability(options_.traversability);

  it_ = std::make_shared<image_transport::ImageTransport>(nh);
  if (approximate_sync_) {
    approx_sync_ = std::make_shared<message_filters::Synchronizer<ApproxPolicy>>(
        ApproxPolicy(static_cast<uint32_t>(queue_size_)), sub_left_image_, sub_left_info_, sub_right_image_,
        sub_right_info_);
    approx_sync_->setMaxIntervalDuration(ros::Duration(slop_s_));
    approx_sync_->registerCallback(boost::bind(&DemNodelet::frameCb, this, boost::placeholders::_1, boost::placeholders::_2,
                                                     boost::placeholders::_3, boost::placeholders::_4));
  } else {
    exact_sync_ = std::make_shared<message_filters::Synchronizer<ExactPolicy>>(
        ExactPolicy(static_cast<uint32_t>(queue_size_)), sub_left_image_, sub_left_info_, sub_right_image_,
        sub_right_info_);
    exact_sync_->registerCallback(boost::bind(&DemNodelet::frameCb, this, boost::placeholders::_1, boost::placeholders::_2,
                                                     boost::placeholders::_3, boost::placeholders::_4));
  }
  sub_left_image_.registerCallback(boost::function<void(const sensor_msgs::ImageConstPtr&)>(
      [this](const sensor_msgs::ImageConstPtr& m) { countInput(InputMonitor::kLeftImage, m->header.stamp); }));
  sub_right_image_.registerCallback(boost::function<void(const sensor_msgs::ImageConstPtr&)>(
      [this](const sensor_msgs::ImageConstPtr& m) { countInput(InputMonitor::kRightImage, m->header.stamp); }));
  sub_left_info_.registerCallback(boost::function<void(const sensor_msgs::CameraInfoConstPtr&)>(
      [this](const sensor_msgs::CameraInfoConstPtr& m) { countInput(InputMonitor::kLeftInfo, m->header.stamp); }));
  sub_right_info_.registerCallback(boost::function<void(const sensor_msgs::CameraInfoConstPtr&)>(
      [this](const sensor_msgs::CameraInfoConstPtr& m) { countInput(InputMonitor::kRightInfo, m->header.stamp); }));
  monitor_ = std::make_unique<InputMonitor>(
      std::array<std::string, 4>{nh.resolveName("left/image_rect"), nh.resolveName("left/camera_info"),
                                 nh.resolveName("right/image_rect"), nh.resolveName("right/camera_info")},
      approximate_sync_, slop_s_);

  tf_buffer_ = std::make_shared<tf2_ros::Buffer>();
  tf_listener_ = std::make_shared<tf2_ros::TransformListener>(*tf_buffer_, nh);
  tf_broadcaster_ = std::make_shared<tf2_ros::TransformBroadcaster>();

  updater_ = std::make_shared<diagnostic_updater::Updater>(nh, pnh);
  updater_->setHardwareID("stereo camera " + nh.resolveName("left/image_rect") + " / " +
                          nh.resolveName("right/image_rect"));
  updater_->add("stereo_ground_dem " + getName(), this, &DemNodelet::diagnose);
  double diagnostic_period_s = 1.0, input_check_period_s = 2.0;
  pnh.param("diagnostic_period_s", diagnostic_period_s, 1.0);
  pnh.param("input_check_period_s", input_check_period_s, 2.0);
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    stats_.last_report_time = ros::WallTime::now();
  }
  diagnostic_timer_ = mt_pnh.createWallTimer(ros::WallDuration(std::max(0.05, diagnostic_period_s)),
                                             [this](const ros::WallTimerEvent&) { updater_->force_update(); });
  input_timer_ = mt_pnh.createWallTimer(ros::WallDuration(std::max(0.05, input_check_period_s)),
                                        &DemNodelet::checkInputs, this);

  srv_reset_ = mt_pnh.advertiseService("reset", &DemNodelet::resetSrv, this);
  srv_save_ = mt_pnh.advertiseService("save_map", &DemNodelet::saveSrv, this);
  srv_submap_ = mt_pnh.advertiseService("get_submap", &DemNodelet::submapSrv, this);

  reconfigure_server_ = std::make_shared<ReconfigureServer>(reconfigure_mutex_, pnh);
  reconfigure_server_->setCallback(boost::bind(&DemNodelet::reconfigureCb, this, boost::placeholders::_1, boost::placeholders::_2));

  // Outputs last, with the connect callback (lazy subscription), as image_pipeline does.
  const ros::SubscriberStatusCallback cb = boost::bind(&DemNodelet::connectCb, this);
  {
    std::lock_guard<std::mutex> lock(connect_mutex_);
    pub_dem_ = pnh.advertise<HeightGrid>("dem", 1, cb, cb);
    pub_dem_global_ = pnh.advertise<HeightGrid>("dem_global", 1, cb, cb, ros::VoidConstPtr(), true);
    pub_occupancy_ = pnh.advertise<nav_msgs::OccupancyGrid>("traversability", 1, cb, cb);
    pub_occupancy_global_ =
        pnh.advertise<nav_msgs::OccupancyGrid>("traversability_global", 1, cb, cb, ros::VoidConstPtr(), true);
    pub_mesh_ = pnh.advertise<visualization_msgs::Marker>("mesh", 1, cb, cb);
    pub_odom_ = pnh.advertise<nav_msgs::Odometry>("odom", 10, cb, cb);
    pub_path_ = pnh.advertise<nav_msgs::Path>("path", 1, cb, cb);
  }
  connectCb();
  NODELET_INFO("ready: %s sync (queue %d%s) of %s, %s, %s, %s; %s", approximate_sync_ ? "approximate" : "exact",
               queue_size_, approximate_sync_ ? (", slop " + std::to_string(slop_s_) + " s").c_str() : "",
               nh.resolveName("left/image_rect").c_str(), nh.resolveName("left/camera_info").c_str(),
               nh.resolveName("right/image_rect").c_str(), nh.resolveName("right/camera_info").c_str(),
               lazy_ ? "lazy: subscribes while an output has a subscriber" : "always subscribed");
}

bool DemNodelet::anySubscriber() const {
  return pub_dem_.getNumSubscribers() + pub_dem_global_.getNumSubscribers() + pub_occupancy_.getNumSubscribers() +
             pub_occupancy_global_.getNumSubscribers() + pub_mesh_.getNumSubscribers() +
             pub_odom_.getNumSubscribers() + pub_path_.getNumSubscribers() >
         0;
}

void DemNodelet::connectCb() {
  std::lock_guard<std::mutex> lock(connect_mutex_);
  const bool wanted = !lazy_ || anySubscriber();
  if (!wanted && subscribed_) {
    sub_left_image_.unsubscribe();
    sub_left_info_.unsubscribe();
    sub_right_image_.unsubscribe();
    sub_right_info_.unsubscribe();
    subscribed_ = false;
    NODELET_INFO("no subscriber left: stopped listening to the cameras");
  } else if (wanted && !subscribed_) {
    ros::NodeHandle& nh = getNodeHandle();
    const image_transport::TransportHints hints("raw", ros::TransportHints(), getPrivateNodeHandle());
    const uint32_t q = static_cast<uint32_t>(queue_size_);
    sub_left_image_.subscribe(*it_, "left/image_rect", q, hints);
    sub_left_info_.subscribe(nh, "left/camera_info", q);
    sub_right_image_.subscribe(*it_, "right/image_rect", q, hints);
    sub_right_info_.subscribe(nh, "right/camera_info", q);
    subscribed_ = true;
    subscribed_since_ = ros::WallTime::now();
    {
      std::lock_guard<std::mutex> mlock(monitor_mutex_);
      monitor_->check();  // restart the counts
    }
    NODELET_INFO("listening to the cameras");
  }
}

void DemNodelet::countInput(InputMonitor::Topic topic, const ros::Time& stamp) {
  std::lock_guard<std::mutex> lock(monitor_mutex_);
  monitor_->count(topic, stamp.toSec());
}

void DemNodelet::checkInputs(const ros::WallTimerEvent& event) {
  {
    std::lock_guard<std::mutex> lock(connect_mutex_);
    // give a fresh subscription one full period before judging it
    if (!subscribed_ || (event.current_real - subscribed_since_).toSec() < 0.9 * (event.current_real -
                                                                                 event.last_real).toSec()) {
      return;
    }
  }
  std::string problem;
  {
    std::lock_guard<std::mutex> lock(monitor_mutex_);
    problem = monitor_->check();
  }
  if (!problem.empty()) reportProblem(problem, false, false);
}

void DemNodelet::reportProblem(const std::string& problem, bool error, bool skipped_frame) {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  const ros::WallTime now = ros::WallTime::now();
  stats_.last_problem = problem;
  stats_.last_problem_error = error;
  stats_.last_problem_time = now;
  if (skipped_frame) {
    ++stats_.skipped;
    ++stats_.consecutive_bad;
  }
  if (problem != last_logged_problem_ || (now - last_logged_time_).toSec() > 5.0) {
    if (error) NODELET_ERROR("%s%s", problem.c_str(), skipped_frame ? " (frame skipped)" : "");
    else NODELET_WARN("%s", problem.c_str());
    last_logged_problem_ = problem;
    last_logged_time_ = now;
  }
}

void DemNodelet::frameCb(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::CameraInfoConstPtr& left_info,
                         const sensor_msgs::ImageConstPtr& right,
                         const sensor_msgs::CameraInfoConstPtr& right_info) {
  const ros::WallTime received = ros::WallTime::now();
  {
    std::lock_guard<std::mutex> lock(monitor_mutex_);
    monitor_->countSynchronized();
  }
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.synchronized;
  }
  const StereoInputCheck check = validator_.check(*left, *left_info, *right, *right_info);
  if (!check.ok) {
    reportProblem(check.problem, true, true);
    return;
  }
  {
    std::string gap;
    {
      std::lock_guard<std::mutex> lock(monitor_mutex_);
      gap = monitor_->frameGap(left->header.stamp.toSec());
    }
    if (!gap.empty()) reportProblem(gap, false, false);
  }
  cv_bridge::CvImageConstPtr cv_left, cv_right;
  try {
    cv_left = cv_bridge::toCvShare(left);
    cv_right = cv_bridge::toCvShare(right);
  } catch (const cv_bridge::Exception& e) {
    reportProblem(std::string("cannot convert the images: ") + e.what(), true, true);
    return;
  }
  const double stamp_s = left->header.stamp.toSec();
  std_msgs::Header header;
  header.stamp = left->header.stamp;
  header.frame_id = odom_frame_;
  std::string camera_frame = camera_frame_param_.empty() ? left->header.frame_id : camera_frame_param_;
  if (camera_frame.empty()) camera_frame = "camera";

  std::lock_guard<std::mutex> lock(state_mutex_);
  // A stamp more than 50 ms (half a KITTI frame period) older than the last frame: a bag was
  // restarted or looped, or the clock jumped. Start a new map; smaller reorderings are rejected by
  // the estimator (time stamp goes backwards) instead.
  if (estimator_ && last_stamp_s_ >= 0.0 && stamp_s < last_stamp_s_ - 0.05) {
    resetLocked("time jumped back by " + std::to_string(last_stamp_s_ - stamp_s) + " s (bag restarted?)");
  }
  if (estimator_ && check.calibration_changed) {
    resetLocked("the camera calibration changed (camera_info P or size)");
  }
  if (!estimator_ || check.calibration_changed) {
    try {
      createEstimatorLocked(check.rig);
    } catch (const std::exception& e) {
      reportProblem(std::string("cannot start the estimator: ") + e.what(), true, true);
      return;
    }
  }
  FrameResult fr;
  try {
    fr = estimator_->processFrame(cv_left->image, cv_right->image, stamp_s, check.order);
  } catch (const std::exception& e) {
    reportProblem(std::string("estimator: ") + e.what(), true, true);
    return;
  }
  last_stamp_s_ = stamp_s;
  last_header_stamp_ = header.stamp;
  if (fr.status == FrameStatus::kRejectedInput) {
    {
      std::lock_guard<std::mutex> slock(stats_mutex_);
      ++stats_.rejected;
    }
    reportProblem("images rejected by the estimator: " + fr.message, true, true);
    return;
  }
  {
    std::lock_guard<std::mutex> slock(stats_mutex_);
    ++stats_.processed;
    stats_.status = toString(fr.status);
    stats_.last_ms = fr.time_ms;
    stats_.sum_ms += fr.time_ms;
    stats_.max_ms = std::max(stats_.max_ms, fr.time_ms);
    switch (fr.status) {
      case FrameStatus::kInitialized: ++stats_.initialized; stats_.consecutive_bad = 0; break;
      case FrameStatus::kTracked: ++stats_.tracked; stats_.consecutive_bad = 0; break;
      case FrameStatus::kRecovered: ++stats_.recovered; stats_.consecutive_bad = 0; break;
      case FrameStatus::kFailed: ++stats_.failed; ++stats_.consecutive_bad; break;
      case FrameStatus::kRejectedInput: break;
    }
    const ElevationMap& map = estimator_->map();
    stats_.map_tiles = map.tileCount();
    stats_.map_memory_mb = map.memoryBytes() / 1048576.0;
  }
  if (fr.status == FrameStatus::kFailed) {
    reportProblem("tracking failed: " + fr.message + " (pose predicted, map unchanged)", false, false);
  }
  if (estimator_->initialized()) {
    trajectory_xy_.push_back(fr.ground_T_camera.translation().head<2>());
    publishPoseLocked(fr, header, camera_frame);
    publishMapsLocked(fr, header);
  }
  const double latency_ms = (ros::Time::now() - header.stamp).toSec() * 1e3;
  std::lock_guard<std::mutex> slock(stats_mutex_);
  stats_.last_latency_ms = latency_ms;
  NODELET_DEBUG("frame %.3f: %s in %.1f ms (callback %.1f ms)", stamp_s, toString(fr.status), fr.time_ms,
                (ros::WallTime::now() - received).toSec() * 1e3);
}

void DemNodelet::createEstimatorLocked(const StereoRig& rig) {
  estimator_ = std::make_unique<IncrementalEstimator>(rig, options_.estimator);
  rig_ = rig;
  estimator_options_pending_ = false;
  NODELET_INFO("stereo rig from camera_info: %dx%d, fx %.2f fy %.2f cx %.2f cy %.2f px, baseline %.4f m", rig.width,
               rig.height, rig.fx, rig.fy, rig.cx, rig.cy, rig.baseline_m);
}

void DemNodelet::resetLocked(const std::string& why) {
  if (estimator_) {
    if (estimator_options_pending_) {
      estimator_ = std::make_unique<IncrementalEstimator>(rig_, options_.estimator);
      estimator_options_pending_ = false;
    } else {
      estimator_->reset();
    }
  }
  covariance_.reset();
  have_previous_pose_ = false;
  path_.clear();
  trajectory_xy_.clear();
  have_base_T_camera_ = false;
  tf_waited_ = false;
  last_stamp_s_ = -1.0;
  tf_buffer_->clear();
  NODELET_WARN("map reset: %s", why.c_str());
}

bool DemNodelet::baseTCameraLocked(const std::string& camera_frame, Eigen::Isometry3d* base_T_camera) {
  if (base_frame_.empty()) return false;
  if (have_base_T_camera_ && base_T_camera_frame_ == camera_frame) {
    *base_T_camera = base_T_camera_;
    return true;
  }
  const double wait = tf_waited_ ? 0.0 : tf_wait_s_;  // the first frame waits for /tf_static
  tf_waited_ = true;
  std::string err;
  if (tf_buffer_->canTransform(base_frame_, camera_frame, ros::Time(0), ros::Duration(wait), &err)) {
    try {
      base_T_camera_ = tf2::transformToEigen(tf_buffer_->lookupTransform(base_frame_, camera_frame, ros::Time(0)));
      have_base_T_camera_ = true;
      base_T_camera_frame_ = camera_frame;
      NODELET_INFO("using tf %s -> %s: publishing %s -> %s", base_frame_.c_str(), camera_frame.c_str(),
                   odom_frame_.c_str(), base_frame_.c_str());
      *base_T_camera = base_T_camera_;
      return true;
    } catch (const tf2::TransformException& e) {
      err = e.what();
    }
  }
  return false;
}

void DemNodelet::publishPoseLocked(const FrameResult& fr, const std_msgs::Header& header,
                                   const std::string& camera_frame) {
  Eigen::Isometry3d base_T_camera = Eigen::Isometry3d::Identity();
  const bool have_base = baseTCameraLocked(camera_frame, &base_T_camera);
  const std::string child = have_base ? base_frame_ : camera_frame;
  const Eigen::Isometry3d odom_T_child = fr.ground_T_camera * base_T_camera.inverse();
  bool publish_tf = publish_tf_;
  const ros::WallTime now = ros::WallTime::now();
  if (!have_base && !base_frame_.empty() && (now - last_tf_warning_).toSec() > 10.0) {
    last_tf_warning_ = now;
    std::string parent;
    if (tf_buffer_->_getParent(camera_frame, ros::Time(0), parent) && parent != odom_frame_) {
      NODELET_ERROR("tf: '%s' already has the parent '%s' but no path to ~base_frame '%s': not publishing tf "
                    "(it would give '%s' two parents). Set ~base_frame to the root of that tree.",
                    camera_frame.c_str(), parent.c_str(), base_frame_.c_str(), camera_frame.c_str());
    } else {
      NODELET_WARN("tf: no transform from ~base_frame '%s' to the camera frame '%s' (the camera mount; publish it "
                   "with a static_transform_publisher or robot_state_publisher): publishing %s -> %s and "
                   "odometry of the camera instead. Set ~base_frame to '' to do so on purpose.",
                   base_frame_.c_str(), camera_frame.c_str(), odom_frame_.c_str(), camera_frame.c_str());
    }
  }
  if (!have_base) {
    std::string parent;
    if (tf_buffer_->_getParent(camera_frame, ros::Time(0), parent) && parent != odom_frame_) publish_tf = false;
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
      fr.motion_information, MotionCovariance::diagonal(unobserved_std_m_, unobserved_std_rad_), &fallback);
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
  if (first) {  // the twist is unknown on the first frame
    odom.twist.covariance[0] = -1.0;
  }
  have_previous_pose_ = true;
  previous_child_pose_ = odom_T_child;
  previous_child_frame_ = child;
  previous_stamp_s_ = header.stamp.toSec();
  if (pub_odom_.getNumSubscribers() > 0) pub_odom_.publish(odom);

  geometry_msgs::PoseStamped ps;
  ps.header = header;
  ps.pose = odom.pose.pose;
  path_.push_back(ps);
  while (static_cast<int>(path_.size()) > path_max_poses_) path_.pop_front();
  if (pub_path_.getNumSubscribers() > 0) {
    nav_msgs::Path path;
    path.header = header;
    path.poses.assign(path_.begin(), path_.end());
    pub_path_.publish(path);
  }
}

void DemNodelet::publishLayers(const DemLayers& d, const std_msgs::Header& header, ros::Publisher& grid_pub,
                               ros::Publisher& occupancy_pub, ros::Publisher* mesh_pub) {
  if (grid_pub.getNumSubscribers() > 0) grid_pub.publish(HeightGridConverter::toMessage(d.grid, d.layers, header));
  if (occupancy_pub.getNumSubscribers() > 0) {
    occupancy_pub.publish(cost_table_.toOccupancyGrid(d.grid, *d.find("traversability"), *d.find("observations"),
                                                      occupancy_unknown_below_, header, *d.find("obstacle")));
  }
  if (mesh_pub && mesh_pub->getNumSubscribers() > 0) {
    mesh_pub->publish(HeightMeshBuilder::build(d.grid, *d.find("elevation"), header, mesh_options_));
  }
}

void DemNodelet::publishMapsLocked(const FrameResult& fr, const std_msgs::Header& header) {
  const ElevationMap& map = estimator_->map();
  if (pub_dem_.getNumSubscribers() + pub_occupancy_.getNumSubscribers() + pub_mesh_.getNumSubscribers() > 0) {
    // the local window: axis-aligned square ahead of the camera
    Eigen::Vector2d forward = fr.ground_T_camera.linear().col(2).head<2>();
    forward = forward.norm() > 1e-6 ? forward.normalized() : Eigen::Vector2d::UnitX();
    const Eigen::Vector2d c = fr.ground_T_camera.translation().head<2>() + local_map_forward_m_ * forward;
    const GroundGrid w = MapWindowSampler::window(map.options().resolution_m, c.x(), c.y(), local_map_size_m_,
                                                  local_map_size_m_);
    publishLayers(sampler_.sample(map, w, global_map_max_cells_), header, pub_dem_, pub_occupancy_, &pub_mesh_);
  }
  const ros::WallTime now = ros::WallTime::now();
  if (global_map_rate_hz_ > 0.0 && (now - last_global_publish_).toSec() >= 1.0 / global_map_rate_hz_ &&
      pub_dem_global_.getNumSubscribers() + pub_occupancy_global_.getNumSubscribers() > 0) {
    const GroundGrid known = map.knownBounds();
    if (known.rows > 1 && known.cols > 1) {
      last_global_publish_ = now;
      publishLayers(sampler_.sample(map, known, global_map_max_cells_), header, pub_dem_global_,
                    pub_occupancy_global_, nullptr);
    }
  }
  const GroundGrid known = map.knownBounds();
  std::ostringstream extent;
  extent.precision(1);
  extent << std::fixed << "x " << known.x0() << " .. " << known.xOfCol(known.cols - 1) << ", y " << known.y0()
         << " .. " << known.yOfRow(known.rows - 1) << " m (" << known.cols << " x " << known.rows << ")";
  std::lock_guard<std::mutex> slock(stats_mutex_);
  stats_.map_extent = extent.str();
}

void DemNodelet::reconfigureCb(DemParametersConfig& config, uint32_t level) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  PipelineOptions candidate = options_;
  const std::vector<std::string> missing = PipelineParameters::fromConfig(config, &candidate);
  if (!missing.empty()) NODELET_ERROR("dynamic_reconfigure: unknown parameters %s", joined(missing).c_str());
  // names that differ from the running options
  PipelineOptions old_copy = options_, new_copy = candidate;
  const ParameterTable old_table(&old_copy), new_table(&new_copy);
  std::vector<std::string> changed;
  for (const auto& e : old_table.entries())
    if (old_table.get(e) != new_table.get(*new_table.find(e.name))) changed.push_back(e.name);
  if (first_reconfigure_) {
    // The parameters were read and validated in onInit; the server only clamps them to the .cfg ranges.
    first_reconfigure_ = false;
    if (!changed.empty()) {
      NODELET_WARN("dynamic_reconfigure's ranges (cfg/DemParameters.cfg) do not hold %s; the node keeps the values "
                   "it was started with",
                   joined(changed).c_str());
    }
    PipelineParameters::toConfig(options_, &config);
    return;
  }
  if (changed.empty()) return;
  std::string why;
  if (!candidate.isValid(&why)) {
    NODELET_ERROR("dynamic_reconfigure: rejected (%s): %s", joined(changed).c_str(), why.c_str());
    PipelineParameters::toConfig(options_, &config);
    return;
  }
  if (level & 2u) sampler_.setTraversability(candidate.traversability);
  options_ = candidate;
  if (level & 1u) {
    if (!estimator_ || !estimator_->initialized()) {
      if (estimator_) estimator_ = std::make_unique<IncrementalEstimator>(rig_, options_.estimator);
      NODELET_INFO("dynamic_reconfigure: %s applied", joined(changed).c_str());
    } else {
      estimator_options_pending_ = true;
      NODELET_WARN("dynamic_reconfigure: %s take effect at the next ~reset (the running estimator cannot change "
                   "its options)",
                   joined(changed).c_str());
    }
  } else {
    NODELET_INFO("dynamic_reconfigure: %s applied", joined(changed).c_str());
  }
}

bool DemNodelet::resetSrv(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  const bool pending = estimator_options_pending_;
  resetLocked("~reset service");
  res.success = true;
  res.message = pending ? "map reset; pending parameter changes applied" : "map reset";
  return true;
}

bool DemNodelet::saveSrv(SaveMap::Request& req, SaveMap::Response& res) {
  const std::string dir = req.directory.empty() ? save_directory_ : req.directory;
  DemExport dem;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    if (!estimator_ || !estimator_->initialized()) {
      res.success = false;
      res.message = "nothing to save: no stereo frame has been processed yet";
      return true;
    }
    const ElevationMap& map = estimator_->map();
    const DemLayers d = sampler_.sample(map, map.knownBounds());
    dem.grid = d.grid;
    dem.elevation = d.find("elevation")->clone();
    dem.variance = d.find("variance")->clone();
    dem.traversability = d.find("traversability")->clone();
    if (const cv::Mat* o = d.find("obstacle")) dem.obstacles = o->clone();
    if (const cv::Mat* o = d.find("obstacle_height")) dem.obstacle_height = o->clone();
    dem.ground_T_camera0 = estimator_->groundTCamera0();
    dem.trajectory_xy = trajectory_xy_;
    dem.extra = {{"mode", "ROS node " + getName()}, {"frame_id", odom_frame_}};
  }
  try {
    const std::vector<std::string> names = DemExporter::write(dir, dem, req.pictures);
    char cwd[4096];
    const std::string base =
        dir.empty() || dir[0] == '/' ? dir : std::string(getcwd(cwd, sizeof(cwd)) ? cwd : ".") + "/" + dir;
    for (const std::string& n : names) res.files.push_back(n.empty() || n[0] == '/' ? n : base + "/" + n);
    res.success = true;
    res.message = "wrote " + std::to_string(res.files.size()) + " files to " + base;
  } catch (const std::exception& e) {
    res.success = false;
    res.message = e.what();
  }
  return true;
}

bool DemNodelet::submapSrv(GetSubmap::Request& req, GetSubmap::Response& res) {
  if (!std::isfinite(req.center_x) || !std::isfinite(req.center_y) || !(req.length_x > 0.0) ||
      !(req.length_y > 0.0) || !std::isfinite(req.length_x) || !std::isfinite(req.length_y)) {
    res.success = false;
    res.message = "center must be finite and length_x, length_y > 0";
    return true;
  }
  std::lock_guard<std::mutex> lock(state_mutex_);
  if (!estimator_ || !estimator_->initialized()) {
    res.success = false;
    res.message = "the map is empty: no stereo frame has been processed yet";
    return true;
  }
  const ElevationMap& map = estimator_->map();
  const GroundGrid w =
      MapWindowSampler::window(map.options().resolution_m, req.center_x, req.center_y, req.length_x, req.length_y);
  DemLayers d = sampler_.sample(map, w, global_map_max_cells_);
  if (!req.layers.empty()) {
    std::vector<GridLayer> chosen;
    std::vector<std::string> unknown;
    for (const std::string& name : req.layers) {
      const cv::Mat* m = d.find(name);
      if (m) chosen.push_back({name, *m});
      else unknown.push_back(name);
    }
    if (!unknown.empty()) {
      std::vector<std::string> names;
      for (const GridLayer& l : d.layers) names.push_back(l.name);
      res.success = false;
      res.message = "unknown layers " + joined(unknown) + " (available: " + joined(names) + ")";
      return true;
    }
    d.layers = chosen;
  }
  std_msgs::Header header;
  header.stamp = last_header_stamp_;
  header.frame_id = odom_frame_;
  res.map = HeightGridConverter::toMessage(d.grid, d.layers, header);
  res.success = true;
  std::ostringstream os;
  os << d.grid.cols << " x " << d.grid.rows << " cells of " << d.grid.resolution_m << " m, " << d.knownCount()
     << " known";
  res.message = os.str();
  return true;
}

void DemNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
  bool subscribed;
  {
    std::lock_guard<std::mutex> lock(connect_mutex_);
    subscribed = subscribed_;
  }
  std::lock_guard<std::mutex> lock(stats_mutex_);
  const ros::WallTime now = ros::WallTime::now();
  const double dt = (now - stats_.last_report_time).toSec();
  const double rate = dt > 0.0 ? (stats_.synchronized - stats_.synchronized_at_last_report) / dt : 0.0;
  stats_.synchronized_at_last_report = stats_.synchronized;
  stats_.last_report_time = now;
  const double problem_age = stats_.last_problem.empty() ? -1.0 : (now - stats_.last_problem_time).toSec();
  if (!subscribed) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "idle: no subscriber to any output (~lazy)");
  } else if (stats_.consecutive_bad >= 3) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR, stats_.last_problem);
  } else if (problem_age >= 0.0 && problem_age < 5.0) {
    stat.summary(stats_.last_problem_error ? diagnostic_msgs::DiagnosticStatus::ERROR
                                           : diagnostic_msgs::DiagnosticStatus::WARN,
                 stats_.last_problem);
  } else if (stats_.processed == 0) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "waiting for the first synchronized stereo frame");
  } else {
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "mapping");
  }
  stat.add("subscribed to the cameras", subscribed);
  stat.add("input rate [Hz]", rate);
  stat.add("synchronized frames", stats_.synchronized);
  stat.add("processed frames", stats_.processed);
  stat.add("initialized", stats_.initialized);
  stat.add("tracked", stats_.tracked);
  stat.add("recovered", stats_.recovered);
  stat.add("failed (pose predicted, map unchanged)", stats_.failed);
  stat.add("rejected by the estimator", stats_.rejected);
  stat.add("skipped (invalid input)", stats_.skipped);
  stat.add("last status", stats_.status);
  stat.add("processing last [ms]", stats_.last_ms);
  stat.add("processing mean [ms]", stats_.processed > 0 ? stats_.sum_ms / stats_.processed : 0.0);
  stat.add("processing max [ms]", stats_.max_ms);
  stat.add("latency stamp to publish [ms]", stats_.last_latency_ms);
  stat.add("map tiles", stats_.map_tiles);
  stat.add("map memory [MB]", stats_.map_memory_mb);
  stat.add("map known extent", stats_.map_extent);
  stat.add("last problem", stats_.last_problem);
  stat.add("last problem age [s]", problem_age);
}

}  // namespace stereo_ground_dem

PLUGINLIB_EXPORT_CLASS(stereo_ground_dem::DemNodelet, nodelet::Nodelet)
