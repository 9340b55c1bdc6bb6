#pragma once
/// \file DemDiagnostics.hpp
/// Counters, the last problem and /diagnostics of stereo_ground_dem/DemNodelet (docs/ros.md,
/// "Input validation and diagnostics"). Every method is thread-safe: the image callback, the
/// processing thread (DemWorker) and the timers call it concurrently; the diagnostic and
/// input-check timers run on the nodelet's multi-threaded queue, so diagnostics keep coming while
/// a frame is processed. Problems are logged (ERROR or WARN) when they differ from the last logged
/// one or every 5 s: one line each, throttled.

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/ros.h>

#include <array>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <string>

#include "stereo_ground_dem/GroundAttitudeEstimator.hpp"
#include "stereo_ground_dem/IncrementalEstimator.hpp"
#include "stereo_ground_dem/ros/InputMonitor.hpp"

namespace stereo_ground_dem {

class DemDiagnostics {
 public:
  /// What the processing thread reports for one processed frame.
  struct FrameRecord {
    FrameStatus status = FrameStatus::kTracked;
    double processing_ms = 0.0;  ///< the core's time for the frame
    double latency_ms = std::numeric_limits<double>::quiet_NaN();  ///< image stamp -> outputs published
    double wait_ms = 0.0;        ///< callback -> start of processing (time in the slot)
    double stamp_gap_s = std::numeric_limits<double>::quiet_NaN();  ///< to the previous processed frame
    size_t map_tiles = 0;
    double map_memory_mb = 0.0;
    std::string map_extent;
    GroundAttitudeEstimate attitude;  ///< the camera above the local ground (mapped frames)
    /// How far the motion-only pre-alignment moved from the constant-velocity prediction [m]
    /// (FrameResult::prealign_shift_m; NaN without one) and whether that was beyond the
    /// acceleration bound, so that the prediction was kept (FrameResult::prealign_rejected).
    double prealign_shift_m = std::numeric_limits<double>::quiet_NaN();
    bool prealign_rejected = false;
    /// other starts whose pre-alignment ended beyond that bound (FrameResult::prealign_discarded)
    int prealign_discarded = 0;
    int carried_moving_pixels = 0;  ///< texture moving with the vehicle, skipped from the start (test level)
    int hidden_pixels = 0;          ///< ground the previous camera did not see (TemporalVisibility; temporal level)
    int far_pixels = 0;             ///< ground seen past the surface (far_depth_ratio; obstacle test level)
    int far_seeded_vertices = 0;    ///< vertices started from its points or rays (FarGroundSeeds)
    int rising_seeded_vertices = 0; ///< vertices started on ground rising out of the surface (RisingGroundSeeds)
    bool repeat_from_prediction = false;  ///< the second temporal pass started from the prediction (FrameResult)
  };

  /// `logger`: name for the log lines; `topics`: resolved input names (InputMonitor order).
  /// `attitude`: the mount check's tolerances and window (GroundAttitudeOptions).
  DemDiagnostics(const std::string& logger, const std::array<std::string, 4>& topics, bool approximate_sync,
                 double slop_s, const GroundAttitudeOptions& attitude = GroundAttitudeOptions());

  /// Starts /diagnostics (every diagnostic_period_s) and the input check (every input_check_period_s)
  /// on `timer_nh` (use the multi-threaded private node handle).
  void start(ros::NodeHandle& nh, ros::NodeHandle& pnh, ros::NodeHandle& timer_nh, const std::string& task_name,
             const std::string& hardware_id, double diagnostic_period_s, double input_check_period_s);
  /// Stops the timers (before the nodelet goes away).
  void stop();

  void setSubscribed(bool subscribed);
  void countInput(InputMonitor::Topic topic, const ros::Time& stamp);
  void countSynchronized();
  /// Records the stamp of a valid frame; a gap (InputMonitor::frameGap) is reported as a warning
  /// unless report_gap is false (the frame restarts the map, which is reported instead).
  void checkGap(const ros::Time& stamp, bool report_gap = true);

  /// A frame that never reaches the core (invalid input): counted as skipped, ERROR.
  void skipped(const std::string& problem);
  /// A frame the core rejected (black, saturated, no contrast, frozen): counted as rejected and
  /// skipped, ERROR.
  void rejected(const std::string& problem);
  /// A valid frame replaced in the slot by a newer one before it was processed.
  void dropped();
  /// The map was restarted (reset service, stamps jumping, calibration change).
  void restarted(const std::string& why, bool warning);
  /// A processed frame.
  void processed(const FrameRecord& record);
  /// Any other problem: WARN (error = false) or ERROR.
  void problem(const std::string& text, bool error);
  /// Where the estimator's start-up guess of the camera's mount came from, and its values.
  void setMount(const std::string& text);

  /// Counters for tests and the realtime check (same numbers as /diagnostics).
  struct Counts {
    long synchronized = 0, processed = 0, initialized = 0, tracked = 0, recovered = 0, failed = 0, rejected = 0,
         skipped = 0, dropped = 0, restarts = 0;
    long prealign_rejected = 0;  ///< frames whose pre-alignment was beyond the acceleration bound
    long prealign_discarded = 0;  ///< frames with other starts' pre-alignments beyond it (not candidates)
    long carried_moving = 0;     ///< frames that skipped moving texture carried from the last two
    long repeat_from_prediction = 0;  ///< frames whose second temporal pass started from the prediction
  };
  Counts counts() const;

  /// Fills one DiagnosticStatus (the updater's task).
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);

 private:
  void report(const std::string& problem, bool error);  // with mutex_ held
  void checkInputs(const ros::WallTimerEvent& event);

  std::string logger_;
  mutable std::mutex mutex_;
  InputMonitor monitor_;
  Counts counts_;
  bool subscribed_ = false;
  ros::WallTime subscribed_since_;
  int consecutive_bad_ = 0;
  double last_ms_ = 0.0, sum_ms_ = 0.0, max_ms_ = 0.0;
  double last_latency_ms_ = std::numeric_limits<double>::quiet_NaN(), max_latency_ms_ = 0.0;
  double last_wait_ms_ = 0.0;
  double last_gap_s_ = std::numeric_limits<double>::quiet_NaN(), max_gap_s_ = 0.0;
  double last_prealign_shift_m_ = std::numeric_limits<double>::quiet_NaN();
  int last_carried_moving_pixels_ = 0;
  int last_hidden_pixels_ = 0;
  int last_far_pixels_ = 0;
  int last_far_seeded_vertices_ = 0;
  int last_rising_seeded_vertices_ = 0;
  std::string status_;
  std::string last_problem_;
  bool last_problem_error_ = false;
  ros::WallTime last_problem_time_;
  std::string last_logged_problem_;
  ros::WallTime last_logged_time_;
  long synchronized_at_last_report_ = 0;
  ros::WallTime last_report_time_;
  size_t map_tiles_ = 0;
  double map_memory_mb_ = 0.0;
  std::string map_extent_;
  GroundAttitudeEstimator attitude_check_;
  std::deque<GroundAttitudeEstimate> recent_attitudes_;  ///< the last mount_window_frames mapped frames
  GroundAttitudeEstimate first_attitude_;                ///< typical of the map's first full window
  GroundAttitudeEstimate last_attitude_;
  std::string mount_;                                    ///< setMount
  std::string mount_warning_;                            ///< "" while the camera sits as at the start

  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diagnostic_timer_, input_timer_;
};

}  // namespace stereo_ground_dem
