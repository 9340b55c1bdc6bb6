#pragma once
/// \file InputMonitor.hpp
/// Says in words why no synchronized stereo frame arrives ("nothing in rviz"): counts the messages
/// of the four input topics and the synchronized frames between two checks, and check() names what
/// is missing: no message at all (remapping? camera or bag not running?), some topics silent (e.g.
/// a missing camera_info), or all four arriving but never matching (exact sync with stamps that
/// differ: set ~approximate_sync, or raise ~slop_s). It also notices gaps: a valid frame whose stamp
/// follows the previous valid one by more than gap_factor times the usual frame period (the
/// median of the last intervals) means frames were dropped or invalid in between. No ROS
/// dependency; the node feeds it.

#include <array>
#include <string>
#include <vector>

namespace stereo_ground_dem {

class InputMonitor {
 public:
  enum Topic { kLeftImage = 0, kLeftInfo = 1, kRightImage = 2, kRightInfo = 3 };

  /// `topics`: resolved names in Topic order, for the messages.
  InputMonitor(const std::array<std::string, 4>& topics, bool approximate_sync, double slop_s);

  void count(Topic topic, double stamp_s);
  void countSynchronized() { ++synchronized_; }

  /// What is wrong since the previous check ("" if synchronized frames arrived), then restarts
  /// the counts.
  std::string check();

  int received(Topic topic) const { return counts_[topic]; }

  /// Records the stamp of a valid frame; returns "" or the description of the gap since the
  /// previous valid frame (when it is longer than gap_factor usual periods). A stamp going
  /// backwards restarts the statistics.
  std::string frameGap(double stamp_s, double gap_factor = 2.5);

 private:
  std::array<std::string, 4> topics_;
  bool approximate_;
  double slop_s_;
  std::array<int, 4> counts_{};
  std::array<double, 4> last_stamp_{};
  int synchronized_ = 0;
  double last_valid_stamp_ = -1.0;
  std::vector<double> periods_;  ///< last intervals between valid frames [s]
};

}  // namespace stereo_ground_dem
