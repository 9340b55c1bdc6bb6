#include "stereo_ground_dem/ros/InputMonitor.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <vector>

namespace stereo_ground_dem {

InputMonitor::InputMonitor(const std::array<std::string, 4>& topics, bool approximate_sync, double slop_s)
    : topics_(topics), approximate_(approximate_sync), slop_s_(slop_s) {}

void InputMonitor::count(Topic topic, double stamp_s) {
  ++counts_[topic];
  last_stamp_[topic] = stamp_s;
}

std::string InputMonitor::check() {
  std::ostringstream os;
  std::vector<std::string> silent, alive;
  for (int t = 0; t < 4; ++t) (counts_[t] == 0 ? silent : alive).push_back(topics_[t]);
  auto list = [](const std::vector<std::string>& v) {
    std::string s;
    for (size_t i = 0; i < v.size(); ++i) s += (i ? (i + 1 == v.size() ? " and " : ", ") : "") + v[i];
    return s;
  };
  if (synchronized_ > 0) {
    // fine
  } else if (alive.empty()) {
    os << "no input: nothing received on " << list(silent)
       << " (check the remapping and that the camera driver or bag is running)";
  } else if (!silent.empty()) {
    os << "no synchronized stereo frame: " << list(alive) << (alive.size() == 1 ? " arrives" : " arrive")
       << " but nothing on " << list(silent);
  } else {
    double lo = last_stamp_[0], hi = last_stamp_[0];
    for (double s : last_stamp_) lo = std::min(lo, s), hi = std::max(hi, s);
    os << "no synchronized stereo frame although all four topics arrive: the latest stamps differ by up to "
       << std::lround((hi - lo) * 1e3) << " ms";
    if (approximate_) os << " (approximate sync, slop " << slop_s_ << " s: raise ~slop_s)";
    else os << " (exact sync: set ~approximate_sync true if the cameras are not hardware-synchronized)";
  }
  counts_.fill(0);
  synchronized_ = 0;
  return os.str();
}

std::string InputMonitor::frameGap(double stamp_s, double gap_factor) {
  std::string out;
  if (last_valid_stamp_ < 0.0 || stamp_s < last_valid_stamp_) {
    periods_.clear();
  } else {
    const double dt = stamp_s - last_valid_stamp_;
    if (periods_.size() >= 2) {
      std::vector<double> sorted = periods_;
      std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
      const double usual = sorted[sorted.size() / 2];
      if (usual > 0.0 && dt > gap_factor * usual) {
        std::ostringstream os;
        os.precision(3);
        os << "gap in the input: " << dt << " s between two valid stereo frames, about "
           << std::lround(dt / usual) - 1 << " frames dropped or invalid (usual period " << usual << " s)";
        out = os.str();
      }
    }
    if (out.empty()) {  // gaps do not enter the statistics
      periods_.push_back(dt);
      if (periods_.size() > 15) periods_.erase(periods_.begin());
    }
  }
  last_valid_stamp_ = stamp_s;
  return out;
}

}  // namespace stereo_ground_dem
