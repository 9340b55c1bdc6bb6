#pragma once
/// \file StartHoldPolicy.hpp
/// Which frames make the worker's slot hold the frame that follows them (LatestFrameSlot::holdNext)
/// instead of keeping the newest. A frame processed without a velocity (the initializing one, the
/// first tracked one, one after a failure) always does: the motion search that follows finds steps
/// of up to ~4 m. The first `frames_with_velocity` frames after it do too: their velocity comes from
/// one short step, they are slow (no usual pre-alignment cost is known yet for their gaps, so every
/// start is aligned: 0.4-0.5 s each at full KITTI resolution), and the newest frame after one of
/// them lies 1 s or more later. Measured offline with the frames the node kept at 10 Hz on KITTI raw
/// 0013: frames 0, 1, 3, 14, then every ~2nd: 2.92 % drift (the 11-frame step alone: 1.2 deg of yaw,
/// 0.65 m); frames 0, 1, 3, 9, 13, then every 2nd (the gaps holding two more frames gives): 1.21 %
/// (every frame: 1.22 %). No ROS dependency.

namespace stereo_ground_dem {

class StartHoldPolicy {
 public:
  explicit StartHoldPolicy(int frames_with_velocity = 2) : frames_with_velocity_(frames_with_velocity) {}

  /// Called before a frame is processed, with the estimator's state then; true: hold the next frame.
  bool holdNext(bool initialized, bool velocity_known) {
    if (!initialized || !velocity_known) {
      since_velocity_ = 0;
      return true;
    }
    return since_velocity_++ < frames_with_velocity_;
  }

 private:
  int frames_with_velocity_;
  int since_velocity_ = 0;  ///< frames processed with a velocity since the last one without
};

}  // namespace stereo_ground_dem
