#pragma once
/// \file CalibrationReader.hpp
/// Readers for KITTI calibration files. Every failure throws std::runtime_error with the file name
/// and the reason, in one line.
///
/// Formats (detected from the content):
///  - KITTI odometry `calib.txt`: `P0:` .. `P3:` lines of 12 numbers (other keys such as `Tr:` are
///    ignored), or, without keys, two lines of 12 numbers (left, right);
///  - KITTI raw / KITTI 2015 `calib_cam_to_cam.txt`: `P_rect_00` .. `P_rect_03` (and the image
///    size `S_rect_0X`; text values such as `calib_time` are ignored).
/// Cameras 0/1 are KITTI's grey pair, 2/3 its colour pair. The colour cameras are not the rectified
/// reference camera and sit ~3 mm apart vertically: accepted under StereoRig::kMaxRelativeOffset
/// (StereoRig::rectificationWarning() names the offsets).

#include <string>

#include "stereo_ground_dem/StereoRig.hpp"

namespace stereo_ground_dem {

class CalibrationReader {
 public:
  /// Which cameras to read.
  enum class CameraPair {
    kAuto,   ///< the grey pair when present, else the colour pair, else two unkeyed lines
    kGray,   ///< P0/P1 or P_rect_00/P_rect_01 (or two unkeyed lines)
    kColor,  ///< P2/P3 or P_rect_02/P_rect_03
  };
  using RawPair = CameraPair;

  /// What a file holds (for choosing a pair before reading it).
  struct Contents {
    bool gray = false;     ///< P0/P1 or P_rect_00/01
    bool color = false;    ///< P2/P3 or P_rect_02/03
    bool unkeyed = false;  ///< at least two lines of numbers without a key
  };
  static Contents inspect(const std::string& path);

  /// Reads the chosen pair of either format; the image size comes from `S_rect_0X` when present.
  static StereoRig read(const std::string& path, CameraPair pair = CameraPair::kAuto);

  /// KITTI odometry `calib.txt`: P0/P1, else P2/P3, else the first two unkeyed lines.
  static StereoRig readKittiOdometry(const std::string& path);

  /// KITTI raw `calib_cam_to_cam.txt`: `P_rect_0X` of the chosen pair (kAuto: grey).
  static StereoRig readKittiRaw(const std::string& path, CameraPair pair = CameraPair::kColor);

  /// "0,1" or "2,3".
  static const char* name(CameraPair pair);
};

}  // namespace stereo_ground_dem
