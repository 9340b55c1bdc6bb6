// stereo_ground_dem/DemNodelet: synchronized rectified stereo in; DEM (HeightGrid), traversability
// (OccupancyGrid), mesh (Marker), Odometry, Path and tf out. Topics, parameters and frames:
// docs/ros.md.
//
// This class only wires things up and hands frames over: onInit reads the parameters, builds the
// synchronizer (lazy subscription), and the image callback converts and validates a frame and puts
// it into the worker's one-element slot. The rest is in one class per file:
//   DemWorker      the processing thread (owns the core's IncrementalEstimator)
//   DemPublisher   topics and tf
//   DemServices    ~reset, ~save_map, ~get_submap (on the map snapshot the worker publishes)
//   DemDiagnostics counters, throttled problem reports, /diagnostics
// Every callback runs on PersistentCallbackQueues (not the nodelet's own queues), and the destructor
// unregisters every ROS entity before it waits for the processing thread: see docs/ros.md,
// "Shutdown", for the use-after-free at exit that this avoids.
#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <image_transport/image_transport.h>
#include <image_transport/subscriber_filter.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/sync_policies/exact_time.h>
#include <message_filters/synchronizer.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include <pluginlib/class_list_macros.hpp>

#include <memory>
#include <mutex>

#include "stereo_ground_dem/DemParametersConfig.h"
#include "stereo_ground_dem/ParameterTable.hpp"
#include "stereo_ground_dem/io/AllocatorTuning.hpp"
#include "stereo_ground_dem/ros/DemDiagnostics.hpp"
#include "stereo_ground_dem/ros/DemPublisher.hpp"
#include "stereo_ground_dem/ros/DemServices.hpp"
#include "stereo_ground_dem/ros/DemWorker.hpp"
#include "stereo_ground_dem/ros/ImageMessageConverter.hpp"
#include "stereo_ground_dem/ros/PersistentCallbackQueues.hpp"
#include "stereo_ground_dem/ros/PipelineParameters.hpp"
#include "stereo_ground_dem/ros/RosNodeOptions.hpp"
#include "stereo_ground_dem/ros/StampSequenceChecker.hpp"
#include "stereo_ground_dem/ros/StereoInputValidator.hpp"

namespace stereo_ground_dem {

namespace {
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

  void onInit() override;
  void readParameters();
  void connectCb();
  void frameCb(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::CameraInfoConstPtr& left_info,
               const sensor_msgs::ImageConstPtr& right, const sensor_msgs::CameraInfoConstPtr& right_info);
  void reconfigureCb(DemParametersConfig& config, uint32_t level);

  RosNodeOptions options_;
  PipelineOptions pipeline_;  ///< as last accepted (reconfigure callback only after onInit)
  bool first_reconfigure_ = true;

  std::unique_ptr<PersistentCallbackQueues> queues_;
  ros::NodeHandle nh_, pnh_, mt_nh_, mt_pnh_;  ///< the nodelet's handles on queues_

  // Destroyed in reverse order: the worker (its thread joined in the destructor) before the
  // publisher and diagnostics it uses.
  std::unique_ptr<DemDiagnostics> diagnostics_;
  std::unique_ptr<DemPublisher> publisher_;
  std::unique_ptr<DemWorker> worker_;
  std::unique_ptr<DemServices> services_;

  std::shared_ptr<image_transport::ImageTransport> it_;
  image_transport::SubscriberFilter sub_left_image_, sub_right_image_;
  message_filters::Subscriber<Info> sub_left_info_, sub_right_info_;
  std::shared_ptr<message_filters::Synchronizer<ExactPolicy>> exact_sync_;
  std::shared_ptr<message_filters::Synchronizer<ApproxPolicy>> approx_sync_;
  boost::recursive_mutex reconfigure_mutex_;
  std::shared_ptr<ReconfigureServer> reconfigure_server_;

  std::mutex connect_mutex_;  ///< subscription state
  bool subscribed_ = false;

  // image callback only (the nodelet's single-threaded queue)
  StereoInputValidator validator_;
  StampSequenceChecker stamps_;
};

DemNodelet::~DemNodelet() {
  // 1. no callback of this nodelet runs from here on (waits for a running one);
  // 2. every subscription, service, timer and publisher unregistered, quickly, before
  // 3. the wait for the processing thread (up to one frame).
  if (queues_) queues_->stop();
  if (diagnostics_) diagnostics_->stop();
  {
    std::lock_guard<std::mutex> lock(connect_mutex_);
    sub_left_image_.unsubscribe();
    sub_right_image_.unsubscribe();
    sub_left_info_.unsubscribe();
    sub_right_info_.unsubscribe();
  }
  reconfigure_server_.reset();
  if (services_) services_->shutdown();
  if (publisher_) publisher_->shutdown();
  if (worker_) worker_->stop();
}

void DemNodelet::readParameters() {
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  try {
    pipeline_ = PipelineParameters::load([&pnh](const std::string& name, XmlRpc::XmlRpcValue* v) {
      return pnh.getParam(name, *v);
    });
    options_ = RosNodeOptions::load(pnh);
  } catch (const std::invalid_argument& e) {
    NODELET_FATAL("refusing to start: %s", e.what());
    throw std::runtime_error(std::string("stereo_ground_dem/DemNodelet: ") + e.what());
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
  const std::vector<std::string> unknown = PipelineParameters::unknown(mine, RosNodeOptions::names());
  if (!unknown.empty()) {
    NODELET_WARN("ignoring unknown private parameters (typos?): %s. Known names: docs/ros.md and docs/parameters.md",
                 joined(unknown).c_str());
  }
}

void DemNodelet::onInit() {
  readParameters();
  if (options_.tune_allocator && !AllocatorTuning::apply()) {
    NODELET_WARN("~tune_allocator: the C library refused the allocator settings (not glibc?); frames will be slower");
  }
  queues_ = std::make_unique<PersistentCallbackQueues>(2);
  nh_ = queues_->singleThreaded(getNodeHandle());
  pnh_ = queues_->singleThreaded(getPrivateNodeHandle());
  mt_nh_ = queues_->multiThreaded(getNodeHandle());
  mt_pnh_ = queues_->multiThreaded(getPrivateNodeHandle());
  ros::NodeHandle& nh = nh_;
  ros::NodeHandle& pnh = pnh_;
  ros::NodeHandle& mt_pnh = mt_pnh_;
  stamps_ = StampSequenceChecker(options_.restart_back_s, options_.max_stamp_gap_s);
  const std::string logger = getName();

  const std::array<std::string, 4> topics{nh.resolveName("left/image_rect"), nh.resolveName("left/camera_info"),
                                          nh.resolveName("right/image_rect"), nh.resolveName("right/camera_info")};
  diagnostics_ = std::make_unique<DemDiagnostics>(logger, topics, options_.approximate_sync, options_.slop_s,
                                                  pipeline_.attitude);
  publisher_ = std::make_unique<DemPublisher>(options_, pipeline_.traversability, logger);
  worker_ = std::make_unique<DemWorker>(*publisher_, *diagnostics_, pipeline_.estimator, logger, pipeline_.ortho,
                                       pipeline_.residual, pipeline_.attitude);
  worker_->setMemoryRelease(options_.release_memory_every_frames);
  worker_->setStartHold(options_.start_hold_frames);
  worker_->setMountFromTf(options_.mount_from_tf && !options_.base_frame.empty());
  services_ = std::make_unique<DemServices>(*worker_, options_, pipeline_.traversability, getName());

  it_ = std::make_shared<image_transport::ImageTransport>(nh);
  const uint32_t q = static_cast<uint32_t>(options_.queue_size);
  auto cb = boost::bind(&DemNodelet::frameCb, this, boost::placeholders::_1, boost::placeholders::_2,
                        boost::placeholders::_3, boost::placeholders::_4);
  if (options_.approximate_sync) {
    approx_sync_ = std::make_shared<message_filters::Synchronizer<ApproxPolicy>>(
        ApproxPolicy(q), sub_left_image_, sub_left_info_, sub_right_image_, sub_right_info_);
    approx_sync_->setMaxIntervalDuration(ros::Duration(options_.slop_s));
    approx_sync_->registerCallback(cb);
  } else {
    exact_sync_ = std::make_shared<message_filters::Synchronizer<ExactPolicy>>(
        ExactPolicy(q), sub_left_image_, sub_left_info_, sub_right_image_, sub_right_info_);
    exact_sync_->registerCallback(cb);
  }
  DemDiagnostics* d = diagnostics_.get();
  sub_left_image_.registerCallback(boost::function<void(const sensor_msgs::ImageConstPtr&)>(
      [d](const sensor_msgs::ImageConstPtr& m) { d->countInput(InputMonitor::kLeftImage, m->header.stamp); }));
  sub_right_image_.registerCallback(boost::function<void(const sensor_msgs::ImageConstPtr&)>(
      [d](const sensor_msgs::ImageConstPtr& m) { d->countInput(InputMonitor::kRightImage, m->header.stamp); }));
  sub_left_info_.registerCallback(boost::function<void(const sensor_msgs::CameraInfoConstPtr&)>(
      [d](const sensor_msgs::CameraInfoConstPtr& m) { d->countInput(InputMonitor::kLeftInfo, m->header.stamp); }));
  sub_right_info_.registerCallback(boost::function<void(const sensor_msgs::CameraInfoConstPtr&)>(
      [d](const sensor_msgs::CameraInfoConstPtr& m) { d->countInput(InputMonitor::kRightInfo, m->header.stamp); }));

  diagnostics_->start(nh, pnh, mt_pnh, "stereo_ground_dem " + getName(),
                      "stereo camera " + topics[0] + " / " + topics[2], options_.diagnostic_period_s,
                      options_.input_check_period_s);
  services_->advertise(mt_pnh);
  worker_->start();

  reconfigure_server_ = std::make_shared<ReconfigureServer>(reconfigure_mutex_, pnh);
  reconfigure_server_->setCallback(
      boost::bind(&DemNodelet::reconfigureCb, this, boost::placeholders::_1, boost::placeholders::_2));

  // Outputs last, with the connect callback (lazy subscription), as image_pipeline does.
  {
    std::lock_guard<std::mutex> lock(connect_mutex_);
    publisher_->advertise(mt_nh_, pnh, boost::bind(&DemNodelet::connectCb, this));
  }
  queues_->start();
  connectCb();
  NODELET_INFO("ready: %s sync (queue %d%s) of %s, %s, %s, %s; %s", options_.approximate_sync ? "approximate" : "exact",
               options_.queue_size,
               options_.approximate_sync ? (", slop " + std::to_string(options_.slop_s) + " s").c_str() : "",
               topics[0].c_str(), topics[1].c_str(), topics[2].c_str(), topics[3].c_str(),
               options_.lazy ? "lazy: subscribes while an output has a subscriber" : "always subscribed");
}

void DemNodelet::connectCb() {
  std::lock_guard<std::mutex> lock(connect_mutex_);
  const bool wanted = !options_.lazy || publisher_->anySubscriber();
  if (!wanted && subscribed_) {
    sub_left_image_.unsubscribe();
    sub_left_info_.unsubscribe();
    sub_right_image_.unsubscribe();
    sub_right_info_.unsubscribe();
    subscribed_ = false;
    diagnostics_->setSubscribed(false);
    NODELET_INFO("no subscriber left: stopped listening to the cameras");
  } else if (wanted && !subscribed_) {
    ros::NodeHandle& nh = nh_;
    const image_transport::TransportHints hints(options_.image_transport, ros::TransportHints(), pnh_);
    const uint32_t q = static_cast<uint32_t>(options_.queue_size);
    sub_left_image_.subscribe(*it_, "left/image_rect", q, hints);
    sub_left_info_.subscribe(nh, "left/camera_info", q);
    sub_right_image_.subscribe(*it_, "right/image_rect", q, hints);
    sub_right_info_.subscribe(nh, "right/camera_info", q);
    subscribed_ = true;
    diagnostics_->setSubscribed(true);
    NODELET_INFO("listening to the cameras");
  }
}

void DemNodelet::frameCb(const sensor_msgs::ImageConstPtr& left, const sensor_msgs::CameraInfoConstPtr& left_info,
                         const sensor_msgs::ImageConstPtr& right,
                         const sensor_msgs::CameraInfoConstPtr& right_info) {
  StereoFrame frame;
  frame.received = ros::WallTime::now();
  diagnostics_->countSynchronized();
  const StereoInputCheck check = validator_.check(*left, *left_info, *right, *right_info);
  if (!check.ok) {
    diagnostics_->skipped(check.problem + " (frame skipped)");
    return;
  }
  const StampSequenceChecker::Result stamp = stamps_.check(left->header.stamp.toSec());
  if (stamp.verdict == StampSequenceChecker::Verdict::kSkip) {
    diagnostics_->skipped(stamp.message + " (frame skipped)");
    return;
  }
  const bool restart = stamp.verdict == StampSequenceChecker::Verdict::kRestart;
  if (restart) worker_->requestReset(stamp.message, true);
  diagnostics_->checkGap(left->header.stamp, !restart);
  try {
    frame.left = ImageMessageConverter::toMat(*left);
    frame.right = ImageMessageConverter::toMat(*right);
  } catch (const std::exception& e) {
    diagnostics_->skipped(std::string("cannot convert the images: ") + e.what() + " (frame skipped)");
    return;
  }
  frame.left_msg = left;
  frame.right_msg = right;
  frame.order = check.order;
  frame.rig = check.rig;
  frame.stamp = left->header.stamp;
  frame.camera_frame = options_.camera_frame.empty() ? left->header.frame_id : options_.camera_frame;
  if (frame.camera_frame.empty()) frame.camera_frame = "camera";
  if (worker_->submit(std::move(frame))) diagnostics_->dropped();
}

void DemNodelet::reconfigureCb(DemParametersConfig& config, uint32_t level) {
  PipelineOptions candidate = pipeline_;
  const std::vector<std::string> missing = PipelineParameters::fromConfig(config, &candidate);
  if (!missing.empty()) NODELET_ERROR("dynamic_reconfigure: unknown parameters %s", joined(missing).c_str());
  // names that differ from the running options
  PipelineOptions old_copy = pipeline_, new_copy = candidate;
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
    PipelineParameters::toConfig(pipeline_, &config);
    return;
  }
  if (changed.empty()) return;
  std::string why;
  if (!candidate.isValid(&why)) {
    NODELET_ERROR("dynamic_reconfigure: rejected (%s): %s", joined(changed).c_str(), why.c_str());
    PipelineParameters::toConfig(pipeline_, &config);
    return;
  }
  pipeline_ = candidate;
  if (level & 2u) {
    publisher_->setTraversability(pipeline_.traversability);
    services_->setTraversability(pipeline_.traversability);
  }
  if ((level & 1u) && !worker_->setEstimatorOptions(pipeline_.estimator)) {
    NODELET_WARN("dynamic_reconfigure: %s take effect at the next ~reset (the running estimator cannot change "
                 "its options)",
                 joined(changed).c_str());
  } else {
    NODELET_INFO("dynamic_reconfigure: %s applied", joined(changed).c_str());
  }
}

}  // namespace stereo_ground_dem

PLUGINLIB_EXPORT_CLASS(stereo_ground_dem::DemNodelet, nodelet::Nodelet)
