#include "stereo_ground_dem/ros/DemDiagnostics.hpp"

#include <algorithm>
#include <cmath>

namespace stereo_ground_dem {

DemDiagnostics::DemDiagnostics(const std::string& logger, const std::array<std::string, 4>& topics,
                               bool approximate_sync, double slop_s, const GroundAttitudeOptions& attitude)
    : logger_(logger), monitor_(topics, approximate_sync, slop_s), attitude_check_(attitude) {
  last_report_time_ = ros::WallTime::now();
}

void DemDiagnostics::start(ros::NodeHandle& nh, ros::NodeHandle& pnh, ros::NodeHandle& timer_nh,
                           const std::string& task_name, const std::string& hardware_id, double diagnostic_period_s,
                           double input_check_period_s) {
  updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
  updater_->setHardwareID(hardware_id);
  updater_->add(task_name, this, &DemDiagnostics::diagnose);
  diagnostic_timer_ = timer_nh.createWallTimer(ros::WallDuration(std::max(0.05, diagnostic_period_s)),
                                               [this](const ros::WallTimerEvent&) { updater_->force_update(); });
  input_timer_ = timer_nh.createWallTimer(ros::WallDuration(std::max(0.05, input_check_period_s)),
                                          &DemDiagnostics::checkInputs, this);
}

void DemDiagnostics::stop() {
  diagnostic_timer_.stop();
  input_timer_.stop();
  updater_.reset();  // its /diagnostics publisher
}

void DemDiagnostics::setSubscribed(bool subscribed) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (subscribed && !subscribed_) {
    subscribed_since_ = ros::WallTime::now();
    monitor_.check();  // restart the counts
  }
  subscribed_ = subscribed;
}

void DemDiagnostics::countInput(InputMonitor::Topic topic, const ros::Time& stamp) {
  std::lock_guard<std::mutex> lock(mutex_);
  monitor_.count(topic, stamp.toSec());
}

void DemDiagnostics::countSynchronized() {
  std::lock_guard<std::mutex> lock(mutex_);
  monitor_.countSynchronized();
  ++counts_.synchronized;
}

void DemDiagnostics::checkGap(const ros::Time& stamp, bool report_gap) {
  std::lock_guard<std::mutex> lock(mutex_);
  const std::string gap = monitor_.frameGap(stamp.toSec());
  if (!gap.empty() && report_gap) report(gap, false);
}

void DemDiagnostics::skipped(const std::string& problem) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++counts_.skipped;
  ++consecutive_bad_;
  report(problem, true);
}

void DemDiagnostics::rejected(const std::string& problem) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++counts_.rejected;
  ++counts_.skipped;
  ++consecutive_bad_;
  report(problem, true);
}

void DemDiagnostics::dropped() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++counts_.dropped;
}

void DemDiagnostics::restarted(const std::string& why, bool warning) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++counts_.restarts;
  recent_attitudes_.clear();
  first_attitude_ = GroundAttitudeEstimate();
  last_attitude_ = GroundAttitudeEstimate();
  mount_warning_.clear();
  if (warning) {
    report("map reset: " + why, false);
  } else {
    ROS_INFO_STREAM_NAMED(logger_, "map reset: " << why);
  }
}

void DemDiagnostics::processed(const FrameRecord& r) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++counts_.processed;
  status_ = toString(r.status);
  last_ms_ = r.processing_ms;
  sum_ms_ += r.processing_ms;
  max_ms_ = std::max(max_ms_, r.processing_ms);
  last_latency_ms_ = r.latency_ms;
  if (std::isfinite(r.latency_ms)) max_latency_ms_ = std::max(max_latency_ms_, r.latency_ms);
  last_wait_ms_ = r.wait_ms;
  last_gap_s_ = r.stamp_gap_s;
  if (std::isfinite(r.stamp_gap_s)) max_gap_s_ = std::max(max_gap_s_, r.stamp_gap_s);
  last_prealign_shift_m_ = r.prealign_shift_m;
  last_carried_moving_pixels_ = r.carried_moving_pixels;
  last_hidden_pixels_ = r.hidden_pixels;
  last_far_pixels_ = r.far_pixels;
  last_far_seeded_vertices_ = r.far_seeded_vertices;
  last_rising_seeded_vertices_ = r.rising_seeded_vertices;
  if (r.prealign_rejected) ++counts_.prealign_rejected;
  if (r.prealign_discarded > 0) ++counts_.prealign_discarded;
  if (r.carried_moving_pixels > 0) ++counts_.carried_moving;
  if (r.repeat_from_prediction) ++counts_.repeat_from_prediction;
  switch (r.status) {
    case FrameStatus::kInitialized: ++counts_.initialized; consecutive_bad_ = 0; break;
    case FrameStatus::kTracked: ++counts_.tracked; consecutive_bad_ = 0; break;
    case FrameStatus::kRecovered: ++counts_.recovered; consecutive_bad_ = 0; break;
    case FrameStatus::kFailed: ++counts_.failed; ++consecutive_bad_; break;
    case FrameStatus::kRejectedInput: break;
  }
  map_tiles_ = r.map_tiles;
  map_memory_mb_ = r.map_memory_mb;
  if (r.status != FrameStatus::kFailed) {
    last_attitude_ = r.attitude;
    recent_attitudes_.push_back(r.attitude);
    const size_t window = static_cast<size_t>(attitude_check_.options().mount_window_frames);
    if (recent_attitudes_.size() > window) recent_attitudes_.pop_front();
    const std::vector<GroundAttitudeEstimate> recent(recent_attitudes_.begin(), recent_attitudes_.end());
    if (!first_attitude_.valid && recent.size() == window) first_attitude_ = attitude_check_.typical(recent);
    const std::string w = attitude_check_.mountWarning(recent, first_attitude_);
    if (!w.empty() && w != mount_warning_) ROS_WARN_STREAM_NAMED(logger_, w);  // once per change, not per frame
    mount_warning_ = w;
  }
  if (!r.map_extent.empty()) map_extent_ = r.map_extent;
}

void DemDiagnostics::setMount(const std::string& text) {
  std::lock_guard<std::mutex> lock(mutex_);
  mount_ = text;
}

void DemDiagnostics::problem(const std::string& text, bool error) {
  std::lock_guard<std::mutex> lock(mutex_);
  report(text, error);
}

DemDiagnostics::Counts DemDiagnostics::counts() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counts_;
}

void DemDiagnostics::report(const std::string& problem, bool error) {
  const ros::WallTime now = ros::WallTime::now();
  last_problem_ = problem;
  last_problem_error_ = error;
  last_problem_time_ = now;
  if (problem != last_logged_problem_ || (now - last_logged_time_).toSec() > 5.0) {
    if (error) ROS_ERROR_STREAM_NAMED(logger_, problem);
    else ROS_WARN_STREAM_NAMED(logger_, problem);
    last_logged_problem_ = problem;
    last_logged_time_ = now;
  }
}

void DemDiagnostics::checkInputs(const ros::WallTimerEvent& event) {
  std::lock_guard<std::mutex> lock(mutex_);
  // give a fresh subscription one full period before judging it
  if (!subscribed_ ||
      (event.current_real - subscribed_since_).toSec() < 0.9 * (event.current_real - event.last_real).toSec()) {
    return;
  }
  const std::string p = monitor_.check();
  if (!p.empty()) report(p, false);
}

void DemDiagnostics::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
  std::lock_guard<std::mutex> lock(mutex_);
  const ros::WallTime now = ros::WallTime::now();
  const double dt = (now - last_report_time_).toSec();
  const double rate = dt > 0.0 ? (counts_.synchronized - synchronized_at_last_report_) / dt : 0.0;
  synchronized_at_last_report_ = counts_.synchronized;
  last_report_time_ = now;
  const double problem_age = last_problem_.empty() ? -1.0 : (now - last_problem_time_).toSec();
  if (!subscribed_) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "idle: no subscriber to any output (~lazy)");
  } else if (consecutive_bad_ >= 3) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR, last_problem_);
  } else if (problem_age >= 0.0 && problem_age < 5.0) {
    stat.summary(last_problem_error_ ? diagnostic_msgs::DiagnosticStatus::ERROR
                                     : diagnostic_msgs::DiagnosticStatus::WARN,
                 last_problem_);
  } else if (counts_.processed == 0) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "waiting for the first synchronized stereo frame");
  } else if (!mount_warning_.empty()) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, mount_warning_);
  } else {
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "mapping");
  }
  stat.add("subscribed to the cameras", subscribed_);
  stat.add("input rate [Hz]", rate);
  stat.add("synchronized frames", counts_.synchronized);
  stat.add("processed frames", counts_.processed);
  stat.add("initialized", counts_.initialized);
  stat.add("tracked", counts_.tracked);
  stat.add("recovered", counts_.recovered);
  stat.add("failed (pose predicted, map unchanged)", counts_.failed);
  stat.add("rejected by the estimator", counts_.rejected);
  stat.add("skipped (invalid input)", counts_.skipped);
  stat.add("dropped (busy: replaced by a newer frame)", counts_.dropped);
  stat.add("map restarts", counts_.restarts);
  stat.add("pre-alignment beyond max_acceleration_mps2 (prediction kept)", counts_.prealign_rejected);
  stat.add("frames with pre-alignment starts beyond max_acceleration_mps2 (not candidates)", counts_.prealign_discarded);
  stat.add("pre-alignment shift from the prediction last [m]", last_prealign_shift_m_);
  stat.add("frames skipping moving texture carried from the last two", counts_.carried_moving);
  stat.add("moving texture carried last [px at the test level]", last_carried_moving_pixels_);
  stat.add("frames whose second temporal pass started from the prediction (moving texture pulled the first)",
           counts_.repeat_from_prediction);
  stat.add("ground the previous camera did not see, last [px at the finest temporal level]", last_hidden_pixels_);
  stat.add("ground seen past the surface, last (excluded) [px at the obstacle test level]", last_far_pixels_);
  stat.add("vertices started from ground seen past the surface, last", last_far_seeded_vertices_);
  stat.add("vertices started on ground rising out of the surface, last", last_rising_seeded_vertices_);
  stat.add("last status", status_);
  stat.add("processing last [ms]", last_ms_);
  stat.add("processing mean [ms]", counts_.processed > 0 ? sum_ms_ / counts_.processed : 0.0);
  stat.add("processing max [ms]", max_ms_);
  stat.add("waiting for the worker last [ms]", last_wait_ms_);
  stat.add("latency stamp to publish [ms]", last_latency_ms_);
  stat.add("latency stamp to publish max [ms]", max_latency_ms_);
  stat.add("stamp gap to the previous processed frame [s]", last_gap_s_);
  stat.add("stamp gap max [s]", max_gap_s_);
  stat.add("map tiles", map_tiles_);
  stat.add("map memory [MB]", map_memory_mb_);
  stat.add("map known extent", map_extent_);
  constexpr double kDeg = 180.0 / M_PI;
  stat.add("camera above the local ground: known", last_attitude_.valid);
  stat.add("camera above the local ground: height [m]", last_attitude_.height_m);
  stat.add("camera above the local ground: pitch [deg]", last_attitude_.pitch_rad * kDeg);
  stat.add("camera above the local ground: roll [deg]", last_attitude_.roll_rad * kDeg);
  stat.add("camera mount, start-up guess", mount_.empty() ? std::string("not read yet (no frame)") : mount_);
  stat.add("camera mount", mount_warning_.empty() ? std::string("as at the start of the map (or not yet known)")
                                                   : mount_warning_);
  stat.add("last problem", last_problem_);
  stat.add("last problem age [s]", problem_age);
}

}  // namespace stereo_ground_dem
