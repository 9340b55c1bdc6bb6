#pragma once
/// \file DemWorker.hpp
/// The processing thread of stereo_ground_dem/DemNodelet. The image callback hands validated
/// frames over through a one-element LatestFrameSlot (a frame not yet taken is replaced by the
/// newer one and counted as dropped: never queued); this thread takes the latest, runs the core's
/// IncrementalEstimator (which it alone owns), publishes through DemPublisher and then publishes a
/// MapSnapshot (a copy of the map) for the services. No lock is held while a frame is processed:
/// services, diagnostics and dynamic_reconfigure answer meanwhile.
///
/// Resets (service, stamps jumping, calibration change) are requests: requestReset() empties the
/// snapshot at once (the services see an empty map from then on), wakes the thread and returns; the
/// thread resets the estimator before it takes the next frame, and a frame that was being processed
/// when the request came is not published.

#include <atomic>
#include <future>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "stereo_ground_dem/GroundAttitudeEstimator.hpp"
#include "stereo_ground_dem/IncrementalEstimator.hpp"
#include "stereo_ground_dem/ros/DemDiagnostics.hpp"
#include "stereo_ground_dem/ros/DemPublisher.hpp"
#include "stereo_ground_dem/ros/LatestFrameSlot.hpp"
#include "stereo_ground_dem/ros/MapSnapshot.hpp"
#include "stereo_ground_dem/ros/StartHoldPolicy.hpp"
#include "stereo_ground_dem/ros/StereoFrame.hpp"

namespace stereo_ground_dem {

class DemWorker {
 public:
  /// `ortho`, `residual`: the options of the layers kept beside the map (their keep radius is taken
  /// from the map's).
  DemWorker(DemPublisher& publisher, DemDiagnostics& diagnostics, const IncrementalEstimatorOptions& options,
            const std::string& logger, const OrthoTextureOptions& ortho = OrthoTextureOptions(),
            const PhotometricResidualOptions& residual = PhotometricResidualOptions(),
            const GroundAttitudeOptions& attitude = GroundAttitudeOptions());
  ~DemWorker();  ///< stop()

  /// Every `every_frames` processed frames (0: never), hand the allocator's free memory back to
  /// the kernel (AllocatorTuning::releaseFreeMemory). Call before start().
  void setMemoryRelease(int every_frames) { release_every_frames_ = every_frames; }
  /// Frames processed with a velocity that still hold the frame after them, once tracking starts
  /// (StartHoldPolicy). Call before start().
  void setStartHold(int frames_with_velocity) { start_hold_ = StartHoldPolicy(frames_with_velocity); }
  /// Take the start-up guess of the camera's mount from tf (DemPublisher::cameraMount) when the
  /// estimator is created for a camera; the parameters where tf has nothing. Call before start().
  void setMountFromTf(bool on) { mount_from_tf_ = on; }

  void start();
  /// Closes the slot and joins the thread (a frame being processed is finished first).
  void stop();

  /// Hands a frame over; returns true when it replaced a frame that was not processed yet.
  bool submit(StereoFrame frame);
  /// Asks for a new map before the next frame; returns at once (see the file comment).
  void requestReset(const std::string& why, bool warning);
  /// New estimator options: used when the estimator is (re)created, i.e. now if no frame has been
  /// mapped yet, else at the next reset. Returns true when they apply without a reset.
  bool setEstimatorOptions(const IncrementalEstimatorOptions& options);
  /// Estimator options waiting for a reset.
  bool optionsPending() const;
  /// Asks for a saved map (MapStateFile) to replace the current one before the next frame; the
  /// future receives (true, what was loaded) or (false, why not). Before the first frame (no
  /// calibration yet) the request waits for it. The next frame's stamp restarts the motion
  /// prediction (velocity unknown, search from the saved pose).
  std::future<std::pair<bool, std::string>> requestLoad(const std::string& directory);
  /// A camera_info has been received (the estimator exists).
  bool hasCalibration() const;

  /// The map as of the last published frame (map == nullptr: nothing mapped).
  std::shared_ptr<const MapSnapshot> snapshot() const;

 private:
  void run();
  void applyReset();
  void applyLoad();
  void process(StereoFrame& frame);
  void publishSnapshot(const ros::Time& stamp, long generation);

  DemPublisher& publisher_;
  DemDiagnostics& diagnostics_;
  const std::string logger_;
  LatestFrameSlot<StereoFrame> slot_;
  std::thread thread_;

  mutable std::mutex control_mutex_;  ///< guards the fields below (never held while processing)
  IncrementalEstimatorOptions options_;
  bool options_changed_ = false;      ///< options_ differ from the running estimator's
  bool initialized_ = false;          ///< mirror of estimator_->initialized()
  long reset_requested_ = 0;          ///< generation counters
  long reset_applied_ = 0;
  std::string reset_reason_;
  std::shared_ptr<const MapSnapshot> snapshot_;
  struct LoadRequest {
    std::string directory;
    std::promise<std::pair<bool, std::string>> done;
  };
  std::unique_ptr<LoadRequest> load_request_;  ///< answered by applyLoad, a reset, a newer request or stop()
  bool has_calibration_ = false;

  // processing thread only
  /// A loaded state, restored again with the next frame's stamp (MotionPredictor's time base).
  std::unique_ptr<EstimatorState> loaded_state_;
  std::unique_ptr<IncrementalEstimator> estimator_;
  std::vector<Eigen::Vector2d> trajectory_xy_;
  const OrthoTextureOptions ortho_options_;
  const PhotometricResidualOptions residual_options_;
  std::unique_ptr<OrthoTexture> ortho_;              ///< null when disabled; renewed with the map
  std::unique_ptr<PhotometricResidualMap> residual_; ///< null when disabled; renewed with the map
  /// New, empty layers beside the map (at every new map: the keep radius and the resolution follow
  /// the estimator's options).
  void restartLayers(const IncrementalEstimatorOptions& options, double resolution_m);
  /// `options` with the mount read from tf (mount_) in place of the nominal parameters.
  IncrementalEstimatorOptions mounted(IncrementalEstimatorOptions options) const;
  /// Reads the mount of `camera_frame` from tf into mount_ if mount_from_tf_ (and says where the
  /// start-up guess comes from: log, diagnostics).
  void readMount(const std::string& camera_frame, const IncrementalEstimatorOptions& parameters);
  bool mount_from_tf_ = false;
  bool have_mount_ = false;         ///< mount_ holds the pitch and roll from tf
  bool have_mount_height_ = false;  ///< ... and the height
  NominalMount mount_;
  GroundAttitudeEstimator attitude_;
  long fused_frames_ = 0;
  int release_every_frames_ = 0;
  long processed_since_release_ = 0;
  StartHoldPolicy start_hold_;
  double last_processed_stamp_s_ = -1.0;
};

}  // namespace stereo_ground_dem
