#pragma once
/// \file StampSequenceChecker.hpp
/// Judges the stamp of each valid synchronized stereo frame against the previous accepted one,
/// before the frame reaches the core (whose constant-velocity prediction is scaled by the stamp
/// difference, so stamps must be real capture times):
///  - 0 or not finite: skipped ("the frame has no time stamp");
///  - equal to the previous frame's: skipped (a duplicate: re-sent or a driver bug);
///  - older by at most `restart_after_s`: skipped (out of order);
///  - older by more: accepted as the start of a new map (a bag looped or restarted, a clock jump);
///  - newer by more than `max_gap_s`: accepted as the start of a new map (the motion over the gap
///    is unknown: a constant-velocity prediction over seconds is a guess, and a frame fused at a
///    guessed pose would spoil the map); shorter gaps are bridged by the core's prediction.
/// No ROS dependency.

#include <string>

namespace stereo_ground_dem {

class StampSequenceChecker {
 public:
  enum class Verdict { kAccept, kSkip, kRestart };
  struct Result {
    Verdict verdict = Verdict::kAccept;
    std::string message;  ///< why (skip, restart), "" when accepted plainly
  };

  StampSequenceChecker(double restart_after_s = 0.05, double max_gap_s = 2.0)
      : restart_after_s_(restart_after_s), max_gap_s_(max_gap_s) {}

  /// Judges `stamp_s`; a frame accepted (or restarting) becomes the reference of the next one.
  Result check(double stamp_s);
  /// Forgets the previous stamp (after a reset).
  void reset() { have_last_ = false; }

 private:
  double restart_after_s_, max_gap_s_;
  bool have_last_ = false;
  double last_s_ = 0.0;
};

}  // namespace stereo_ground_dem
