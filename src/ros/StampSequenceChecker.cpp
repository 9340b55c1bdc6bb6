#include "stereo_ground_dem/ros/StampSequenceChecker.hpp"

#include <cmath>
#include <cstdio>

namespace stereo_ground_dem {

namespace {
std::string seconds(double s) {
  char b[64];
  std::snprintf(b, sizeof(b), "%.3f s", s);
  return b;
}
}  // namespace

StampSequenceChecker::Result StampSequenceChecker::check(double stamp_s) {
  Result r;
  if (!std::isfinite(stamp_s) || stamp_s <= 0.0) {
    r.verdict = Verdict::kSkip;
    r.message = "the images have no time stamp (header.stamp is 0): the estimator needs capture times";
    return r;
  }
  if (have_last_) {
    const double dt = stamp_s - last_s_;
    if (dt == 0.0) {
      r.verdict = Verdict::kSkip;
      r.message = "duplicate time stamp: the frame has the same stamp as the previous one";
      return r;
    }
    if (dt < 0.0 && -dt <= restart_after_s_) {
      r.verdict = Verdict::kSkip;
      r.message = "time stamp goes backwards by " + seconds(-dt) + " (frames out of order)";
      return r;
    }
    if (dt < 0.0) {
      r.verdict = Verdict::kRestart;
      r.message = "time jumped back by " + seconds(-dt) + " (bag restarted or looped?): starting a new map";
    } else if (dt > max_gap_s_) {
      r.verdict = Verdict::kRestart;
      r.message = "time jumped forward by " + seconds(dt) + " (more than ~max_stamp_gap_s " + seconds(max_gap_s_) +
                  "; the motion over the gap is unknown): starting a new map";
    }
  }
  have_last_ = true;
  last_s_ = stamp_s;
  return r;
}

}  // namespace stereo_ground_dem
