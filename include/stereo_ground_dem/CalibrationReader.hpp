#pragma once
/// \file CalibrationReader.hpp
/// Readers for KITTI calibration files. Every failure throws std::runtime_error with the file name
/// and the reason, in one line.

#include <string>

#include "stereo_ground_dem/StereoRig.hpp"

namespace stereo_ground_dem {

class CalibrationReader {
 public:
  /// Which rectified pair of a KITTI raw recording to read.
  enum class RawPair { kGray /* P_rect_00 / P_rect_01 */, kColor /* P_rect_02 / P_rect_03 */ };

  /// KITTI odometry `calib.txt`: lines `P0: <12 numbers>` and `P1: <12 numbers>` (other keys are
  /// ignored), or, without keys, the first two lines of 12 numbers each (left, right).
  /// `P2:`/`P3:` are used when `P0:`/`P1:` are absent (colour pair).
  static StereoRig readKittiOdometry(const std::string& path);

  /// KITTI raw `calib_cam_to_cam.txt`: `P_rect_0X` for the chosen pair; the image size comes from
  /// `S_rect_0X` when present.
  static StereoRig readKittiRaw(const std::string& path, RawPair pair = RawPair::kColor);

  /// Detects the format from the content (a `P_rect_` key means KITTI raw, colour pair).
  static StereoRig read(const std::string& path);
};

}  // namespace stereo_ground_dem
