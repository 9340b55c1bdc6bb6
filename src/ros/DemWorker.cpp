#include "stereo_ground_dem/ros/DemWorker.hpp"

#include <ros/ros.h>

#include <cmath>
#include <cstdio>
#include <sstream>

#include "stereo_ground_dem/io/AllocatorTuning.hpp"
#include "stereo_ground_dem/io/MapStateFile.hpp"

namespace stereo_ground_dem {

namespace {
bool sameRig(const StereoRig& a, const StereoRig& b) {
  return a.fx == b.fx && a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.baseline_m == b.baseline_m &&
         a.width == b.width && a.height == b.height;
}
}  // namespace

DemWorker::DemWorker(DemPublisher& publisher, DemDiagnostics& diagnostics, const IncrementalEstimatorOptions& options,
                     const std::string& logger, const OrthoTextureOptions& ortho,
                     const PhotometricResidualOptions& residual, const GroundAttitudeOptions& attitude)
    : publisher_(publisher),
      diagnostics_(diagnostics),
      logger_(logger),
      options_(options),
      snapshot_(std::make_shared<MapSnapshot>()),
      ortho_options_(ortho),
      residual_options_(residual),
      attitude_(attitude) {}

void DemWorker::restartLayers(const IncrementalEstimatorOptions& options, double resolution_m) {
  // evicted with the map (map_keep_radius_m may have changed)
  ortho_.reset();
  if (ortho_options_.enabled) {
    OrthoTextureOptions o = ortho_options_;
    o.keep_radius_m = options.map.keep_radius_m;
    ortho_ = std::make_unique<OrthoTexture>(o);
  }
  residual_.reset();
  if (residual_options_.enabled) {
    PhotometricResidualOptions o = residual_options_;
    o.keep_radius_m = options.map.keep_radius_m;
    residual_ = std::make_unique<PhotometricResidualMap>(resolution_m, o);
  }
}

DemWorker::~DemWorker() { stop(); }

void DemWorker::start() {
  if (!thread_.joinable()) thread_ = std::thread(&DemWorker::run, this);
}

void DemWorker::stop() {
  slot_.close();
  if (thread_.joinable()) thread_.join();
  std::lock_guard<std::mutex> lock(control_mutex_);
  if (load_request_) load_request_->done.set_value({false, "the node is shutting down"});
  load_request_.reset();
}

bool DemWorker::hasCalibration() const {
  std::lock_guard<std::mutex> lock(control_mutex_);
  return has_calibration_;
}

bool DemWorker::submit(StereoFrame frame) { return slot_.put(std::move(frame)).has_value(); }

void DemWorker::requestReset(const std::string& why, bool warning) {
  {
    std::lock_guard<std::mutex> lock(control_mutex_);
    ++reset_requested_;
    reset_reason_ = why;
    snapshot_ = std::make_shared<MapSnapshot>();
    if (load_request_) load_request_->done.set_value({false, "cancelled by a reset (" + why + ")"});
    load_request_.reset();
  }
  diagnostics_.restarted(why, warning);
  slot_.wake();
}

bool DemWorker::setEstimatorOptions(const IncrementalEstimatorOptions& options) {
  std::lock_guard<std::mutex> lock(control_mutex_);
  options_ = options;
  options_changed_ = true;
  if (!initialized_) slot_.wake();  // recreated before the next frame
  return !initialized_;
}

bool DemWorker::optionsPending() const {
  std::lock_guard<std::mutex> lock(control_mutex_);
  return options_changed_ && initialized_;
}

std::future<std::pair<bool, std::string>> DemWorker::requestLoad(const std::string& directory) {
  auto r = std::make_unique<LoadRequest>();
  r->directory = directory;
  auto done = r->done.get_future();
  {
    std::lock_guard<std::mutex> lock(control_mutex_);
    if (load_request_) load_request_->done.set_value({false, "superseded by another ~load_map request"});
    load_request_ = std::move(r);
  }
  slot_.wake();
  return done;
}

void DemWorker::applyLoad() {
  std::unique_ptr<LoadRequest> r;
  long generation = 0;
  {
    std::lock_guard<std::mutex> lock(control_mutex_);
    if (!load_request_ || !estimator_) return;  // without a calibration: with the first frame
    r = std::move(load_request_);
    generation = reset_requested_;
  }
  try {
    const std::string dir =
        MapStateFile::exists(r->directory + "/state") ? r->directory + "/state" : r->directory;
    ElevationMap map(estimator_->map().options());
    std::unique_ptr<OrthoTexture> ortho = ortho_ ? std::make_unique<OrthoTexture>(ortho_->options()) : nullptr;
    std::unique_ptr<PhotometricResidualMap> residual =
        residual_ ? std::make_unique<PhotometricResidualMap>(map.options().resolution_m, residual_->options()) : nullptr;
    SavedMapState saved = MapStateFile::read(dir, &map, ortho.get(), residual.get());
    const StereoRig& rig = estimator_->rig();
    if (saved.image_width_px != rig.width || saved.image_height_px != rig.height) {
      std::ostringstream os;
      os << "cannot resume from '" << dir << "': saved for " << saved.image_width_px << "x" << saved.image_height_px
         << " images, the camera has " << rig.width << "x" << rig.height;
      throw std::runtime_error(os.str());
    }
    if (!saved.estimator.initialized) throw std::runtime_error("cannot resume from '" + dir + "': nothing was mapped");
    auto est = std::make_unique<IncrementalEstimator>(rig, estimator_->options());
    est->map() = std::move(map);
    est->restore(saved.estimator);  // validates before anything changes here
    estimator_ = std::move(est);
    ortho_ = std::move(ortho);
    residual_ = std::move(residual);
    loaded_state_ = std::make_unique<EstimatorState>(saved.estimator);
    publisher_.reset();
    trajectory_xy_ = saved.trajectory_xy;
    fused_frames_ = 0;
    last_processed_stamp_s_ = -1.0;
    {
      std::lock_guard<std::mutex> lock(control_mutex_);
      initialized_ = true;
    }
    publishSnapshot(ros::Time(0), generation);
    const Eigen::Vector3d t = saved.estimator.ground_T_camera.translation();
    std::ostringstream os;
    os << "loaded " << estimator_->map().tileCount() << " map tiles from '" << dir << "'; the camera continues from (x "
       << t.x() << ", y " << t.y() << ", z " << t.z() << ") m";
    diagnostics_.restarted(os.str(), false);
    r->done.set_value({true, os.str()});
  } catch (const std::exception& e) {
    diagnostics_.problem(std::string("~load_map: ") + e.what(), true);
    r->done.set_value({false, e.what()});
  }
}

void DemWorker::publishSnapshot(const ros::Time& stamp, long generation) {
  auto snap = std::make_shared<MapSnapshot>();
  const ElevationMap& map = estimator_->map();
  snap->map = std::make_shared<const ElevationMap>(map);
  if (ortho_) snap->ortho = std::make_shared<const OrthoTexture>(*ortho_);
  if (residual_) snap->residual = std::make_shared<const PhotometricResidualMap>(*residual_);
  snap->ground_T_camera0 = estimator_->groundTCamera0();
  snap->trajectory_xy = trajectory_xy_;
  snap->stamp = stamp;
  snap->frame_count = fused_frames_;
  snap->estimator = std::make_shared<const EstimatorState>(estimator_->state());
  snap->image_width_px = estimator_->rig().width;
  snap->image_height_px = estimator_->rig().height;
  std::lock_guard<std::mutex> lock(control_mutex_);
  if (reset_requested_ == generation) snapshot_ = snap;
}

std::shared_ptr<const MapSnapshot> DemWorker::snapshot() const {
  std::lock_guard<std::mutex> lock(control_mutex_);
  return snapshot_;
}

void DemWorker::run() {
  StereoFrame frame;
  for (;;) {
    const LatestFrameSlot<StereoFrame>::Taken t = slot_.take(&frame);
    if (t == LatestFrameSlot<StereoFrame>::Taken::kClosed) break;
    applyReset();
    applyLoad();
    if (t == LatestFrameSlot<StereoFrame>::Taken::kItem) {
      process(frame);
      frame = StereoFrame();  // release the image messages
      if (release_every_frames_ > 0 && ++processed_since_release_ >= release_every_frames_) {
        processed_since_release_ = 0;
        const ros::WallTime t0 = ros::WallTime::now();
        AllocatorTuning::releaseFreeMemory();
        ROS_DEBUG_NAMED(logger_, "free memory returned to the kernel in %.1f ms", (ros::WallTime::now() - t0).toSec() * 1e3);
      }
    }
  }
}

void DemWorker::applyReset() {
  IncrementalEstimatorOptions options;
  bool reset = false, recreate = false;
  {
    std::lock_guard<std::mutex> lock(control_mutex_);
    reset = reset_requested_ != reset_applied_;
    reset_applied_ = reset_requested_;
    // new options apply when the estimator is recreated: at a reset, or while nothing is mapped
    recreate = estimator_ && options_changed_ && (reset || !initialized_);
    if (recreate) {
      options = options_;
      options_changed_ = false;
    }
    if (reset) initialized_ = false;
  }
  if (recreate) {
    estimator_ = std::make_unique<IncrementalEstimator>(estimator_->rig(), mounted(options));
    restartLayers(options, estimator_->map().options().resolution_m);
  } else if (reset && estimator_) {
    estimator_->reset();
  }
  if (reset) {
    publisher_.reset();
    loaded_state_.reset();
    if (ortho_) ortho_->clear();
    if (residual_) residual_->clear();
    trajectory_xy_.clear();
    fused_frames_ = 0;
    last_processed_stamp_s_ = -1.0;
  }
}

IncrementalEstimatorOptions DemWorker::mounted(IncrementalEstimatorOptions options) const {
  if (!have_mount_) return options;
  IncrementalEstimatorOptions o = options;
  if (have_mount_height_) o.stereo.nominal_height_m = mount_.height_m;
  o.stereo.nominal_pitch_down_rad = mount_.pitch_down_rad;
  o.stereo.nominal_roll_rad = mount_.roll_rad;
  std::string why;
  return o.isValid(&why) ? o : options;  // readMount checked it with the same parameters
}

void DemWorker::readMount(const std::string& camera_frame, const IncrementalEstimatorOptions& parameters) {
  constexpr double kDeg = 180.0 / M_PI;
  const StereoEstimatorOptions& p = parameters.stereo;
  char said[160];
  std::snprintf(said, sizeof(said), "height %.2f m, pitch down %.1f deg, roll %.1f deg", p.nominal_height_m,
                p.nominal_pitch_down_rad * kDeg + 0.0, p.nominal_roll_rad * kDeg + 0.0);
  NominalMount m;
  bool with_height = false;
  std::string source;
  have_mount_ = false;
  if (!mount_from_tf_) {
    diagnostics_.setMount(std::string("from the parameters (~mount_from_tf false or no ~base_frame): ") + said);
    return;
  }
  if (!publisher_.cameraMount(camera_frame, &m, &with_height, &source)) {
    diagnostics_.setMount(std::string("from the parameters (tf has no mount of '") + camera_frame + "'): " + said);
    return;
  }
  if (!with_height) m.height_m = p.nominal_height_m;
  IncrementalEstimatorOptions o = parameters;
  o.stereo.nominal_height_m = m.height_m;
  o.stereo.nominal_pitch_down_rad = m.pitch_down_rad;
  o.stereo.nominal_roll_rad = m.roll_rad;
  char read[160];
  std::snprintf(read, sizeof(read), "height %.2f m%s, pitch down %.1f deg, roll %.1f deg", m.height_m,
                with_height ? "" : " (~nominal_height_m)", m.pitch_down_rad * kDeg + 0.0, m.roll_rad * kDeg + 0.0);
  std::string why;
  if (!o.isValid(&why)) {
    const std::string text = "the camera mount from tf " + source + " (" + read + ") is not usable: " + why +
                             "; using the parameters: " + said + ". Check the transform or set ~mount_from_tf: false";
    diagnostics_.problem(text, false);
    diagnostics_.setMount(std::string("from the parameters (tf's is not usable): ") + said);
    return;
  }
  have_mount_ = true;
  have_mount_height_ = with_height;
  mount_ = m;
  diagnostics_.setMount("from tf " + source + ": " + read);
  const bool differs = (with_height && std::abs(m.height_m - p.nominal_height_m) > 0.1) ||
                       std::abs(m.pitch_down_rad - p.nominal_pitch_down_rad) > 3.0 / kDeg ||
                       std::abs(m.roll_rad - p.nominal_roll_rad) > 3.0 / kDeg;
  if (differs) {
    ROS_WARN_NAMED(logger_,
                   "camera mount from tf %s: %s, where the parameters say %s; tf's is used (~mount_from_tf: false "
                   "keeps the parameters)",
                   source.c_str(), read, said);
  } else {
    ROS_INFO_NAMED(logger_, "camera mount from tf %s: %s", source.c_str(), read);
  }
}

void DemWorker::process(StereoFrame& f) {
  const ros::WallTime start = ros::WallTime::now();
  long generation = 0;
  {
    std::lock_guard<std::mutex> lock(control_mutex_);
    generation = reset_requested_;
  }
  if (!estimator_ || !sameRig(estimator_->rig(), f.rig)) {
    if (estimator_) {
      diagnostics_.restarted("the camera calibration changed (camera_info P or size): starting a new map", true);
      publisher_.reset();
      trajectory_xy_.clear();
      fused_frames_ = 0;
      last_processed_stamp_s_ = -1.0;
    }
    IncrementalEstimatorOptions options;
    {
      std::lock_guard<std::mutex> lock(control_mutex_);
      options = options_;
      options_changed_ = false;
      initialized_ = false;
      snapshot_ = std::make_shared<MapSnapshot>();
    }
    readMount(f.camera_frame, options);
    try {
      estimator_ = std::make_unique<IncrementalEstimator>(f.rig, mounted(options));
      restartLayers(options, estimator_->map().options().resolution_m);
      std::lock_guard<std::mutex> lock(control_mutex_);
      has_calibration_ = true;
    } catch (const std::exception& e) {
      estimator_.reset();
      diagnostics_.skipped(std::string("cannot start the estimator: ") + e.what());
      return;
    }
    const StereoRig& r = f.rig;
    ROS_INFO_NAMED(logger_, "stereo rig from camera_info: %dx%d, fx %.2f fy %.2f cx %.2f cy %.2f px, baseline %.4f m",
                   r.width, r.height, r.fx, r.fy, r.cx, r.cy, r.baseline_m);
    loaded_state_.reset();
    applyLoad();  // a ~load_map that waited for the calibration
  }
  const double stamp_s = f.stamp.toSec();
  if (loaded_state_) {
    // A loaded map continues in this run's time: the saved velocity and stamp belong to the old
    // one, so the motion is searched from the saved pose as after a failure.
    EstimatorState s = *loaded_state_;
    loaded_state_.reset();
    s.rebaseClock(stamp_s, estimator_->options().nominal_frame_period_s);
    try {
      estimator_->restore(s);
    } catch (const std::exception& e) {  // validated at the load; never expected
      diagnostics_.problem(std::string("~load_map: ") + e.what(), true);
    }
  }
  // No velocity is known yet (this frame initializes the map, or is the first tracked one, or
  // follows a failure): the next frame processed must follow this one closely, so the slot holds
  // the first frame that arrives meanwhile instead of the newest. With the newest, the first steps
  // spanned 0.5-1 s (an initialization and a motion search take that long) and the motion search,
  // or the prediction from one short step scaled tenfold, missed them (KITTI 06 at 10 Hz: 52-65 %
  // drift). So do the first start_hold_frames frames with a velocity (StartHoldPolicy.hpp).
  if (start_hold_.holdNext(estimator_->initialized(), estimator_->velocityKnown())) slot_.holdNext();
  FrameResult fr;
  try {
    fr = estimator_->processFrame(f.left, f.right, stamp_s, f.order);
  } catch (const std::exception& e) {
    diagnostics_.skipped(std::string("estimator: ") + e.what() + " (frame skipped)");
    return;
  }
  {
    std::lock_guard<std::mutex> lock(control_mutex_);
    initialized_ = estimator_->initialized();
    if (reset_requested_ != generation) return;  // a reset came meanwhile: this frame belongs to the old map
  }
  if (fr.status == FrameStatus::kRejectedInput) {
    diagnostics_.rejected("images rejected by the estimator: " + fr.message + " (frame skipped)");
    return;
  }
  if (fr.status == FrameStatus::kFailed) {
    diagnostics_.problem("tracking failed: " + fr.message + " (pose predicted, map unchanged)", false);
  }
  DemDiagnostics::FrameRecord record;
  record.status = fr.status;
  record.processing_ms = fr.time_ms;
  record.prealign_shift_m = fr.prealign_shift_m;
  record.prealign_rejected = fr.prealign_rejected;
  record.prealign_discarded = fr.prealign_discarded;
  record.carried_moving_pixels = fr.carried_moving_pixels;
  record.hidden_pixels = fr.hidden_pixels;
  record.far_pixels = fr.far_pixels;
  record.far_seeded_vertices = fr.far_seeded_vertices;
  record.rising_seeded_vertices = fr.rising_seeded_vertices;
  record.repeat_from_prediction = fr.repeat_from_prediction;
  record.wait_ms = (start - f.received).toSec() * 1e3;
  if (last_processed_stamp_s_ >= 0.0) record.stamp_gap_s = stamp_s - last_processed_stamp_s_;
  last_processed_stamp_s_ = stamp_s;
  const ElevationMap& map = estimator_->map();
  if (estimator_->initialized()) {
    trajectory_xy_.push_back(fr.ground_T_camera.translation().head<2>());
    if (ortho_ && fr.status != FrameStatus::kFailed) {  // the left image draped on the map just fused
      try {
        ortho_->update(map, fr.window, estimator_->lastLeftImage(), estimator_->rig(), fr.ground_T_camera,
                       fr.photometric[1]);
        ortho_->evictFarFrom(fr.ground_T_camera.translation().x(), fr.ground_T_camera.translation().y());
      } catch (const std::exception& e) {  // never expected; never fatal either
        diagnostics_.problem(std::string("ortho-texture: ") + e.what(), false);
      }
    }
    if (residual_ && fr.status != FrameStatus::kFailed) {  // where the surface does not explain the images
      try {
        residual_->update(map, fr.window, estimator_->lastLeftImage(), estimator_->lastRightImage(), estimator_->rig(),
                          fr.ground_T_camera, fr.rectification, fr.photometric[0],
                          fr.status == FrameStatus::kTracked ? &fr.photometric[1] : nullptr,
                          estimator_->lastObstacleMask(), estimator_->lastMovingMask());
        residual_->evictFarFrom(fr.ground_T_camera.translation().x(), fr.ground_T_camera.translation().y());
      } catch (const std::exception& e) {  // never expected; never fatal either
        diagnostics_.problem(std::string("photometric residual: ") + e.what(), false);
      }
    }
    record.map_extent = publisher_.publish(fr, map, f.stamp, f.camera_frame, {ortho_.get(), residual_.get()});
    if (fr.status != FrameStatus::kFailed) {  // a failed frame's pose is only the prediction
      try {
        record.attitude = attitude_.estimate(map, fr.ground_T_camera);
      } catch (const std::exception& e) {  // never expected (the window is tiny); never fatal either
        diagnostics_.problem(std::string("ground attitude: ") + e.what(), false);
      }
      publisher_.publishAttitude(record.attitude, f.stamp, f.camera_frame);
    }
    if (fr.status != FrameStatus::kFailed) ++fused_frames_;
    publishSnapshot(f.stamp, generation);
  }
  record.latency_ms = (ros::Time::now() - f.stamp).toSec() * 1e3;
  record.map_tiles = map.tileCount();
  record.map_memory_mb =
      (map.memoryBytes() + (ortho_ ? ortho_->memoryBytes() : 0) + (residual_ ? residual_->memoryBytes() : 0)) / 1048576.0;
  diagnostics_.processed(record);
  ROS_DEBUG_NAMED(logger_, "frame %.3f: %s in %.1f ms, waited %.1f ms, %.1f ms in all", stamp_s, toString(fr.status),
                  fr.time_ms, record.wait_ms, (ros::WallTime::now() - start).toSec() * 1e3);
}

}  // namespace stereo_ground_dem
