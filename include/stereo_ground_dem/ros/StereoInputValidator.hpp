#pragma once
/// \file StereoInputValidator.hpp
/// Checks one synchronized stereo frame (two images, two camera_info) before it reaches the core,
/// and turns the camera_info pair into a StereoRig. Every problem comes back as one sentence that
/// names it (which side, which field, the values), for the node's throttled error and diagnostics.
///
/// The camera_info pair is validated once per change: as long as the P matrices, sizes, binning
/// and ROI stay the same, the cached verdict (rig or reason) is reused.
///
/// Accepted image encodings: mono8, mono16, bgr8, rgb8 (what ImagePyramid accepts and ROS cameras
/// publish); bayer_* is refused with a hint to debayer and rectify first (image_proc), anything
/// else with the list of accepted encodings. Both images must have the same encoding and size,
/// equal to their camera_info's width x height.

#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include <string>

#include "stereo_ground_dem/ImagePyramid.hpp"
#include "stereo_ground_dem/StereoRig.hpp"

namespace stereo_ground_dem {

/// The verdict on one frame.
struct StereoInputCheck {
  bool ok = false;
  std::string problem;                   ///< why not ok (one sentence)
  StereoRig rig;                         ///< valid when ok
  ImagePyramid::ColorOrder order = ImagePyramid::ColorOrder::kBgr;
  bool calibration_changed = false;      ///< ok, and the rig differs from the previous valid one
};

class StereoInputValidator {
 public:
  StereoInputCheck check(const sensor_msgs::Image& left, const sensor_msgs::CameraInfo& left_info,
                         const sensor_msgs::Image& right, const sensor_msgs::CameraInfo& right_info);

  /// "" if `encoding` is accepted, else the reason.
  static std::string checkEncoding(const std::string& encoding);
  /// Encoding, size > 0 and a data buffer that holds height * step bytes with step >= width * pixel size.
  static std::string checkImage(const sensor_msgs::Image& image, const std::string& side);
  /// The rig of a rectified pair; throws std::invalid_argument naming the problem (sizes, binning,
  /// ROI, a missing or non-rectified P, different intrinsics, the baseline).
  static StereoRig rigFromCameraInfo(const sensor_msgs::CameraInfo& left, const sensor_msgs::CameraInfo& right);
  static ImagePyramid::ColorOrder colorOrder(const std::string& encoding);

  /// How many times the camera_info pair was actually validated (not taken from the cache).
  int calibrationChecks() const { return calibration_checks_; }

 private:
  static bool sameCalibration(const sensor_msgs::CameraInfo& a, const sensor_msgs::CameraInfo& b);

  bool have_cached_ = false;
  sensor_msgs::CameraInfo cached_left_, cached_right_;
  std::string cached_problem_;  ///< "" when the cached pair is valid
  StereoRig cached_rig_;
  bool have_valid_rig_ = false;
  StereoRig last_valid_rig_;    ///< rig of the last frame that passed
  int calibration_checks_ = 0;
};

}  // namespace stereo_ground_dem
