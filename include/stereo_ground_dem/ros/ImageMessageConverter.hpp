#pragma once
/// \file ImageMessageConverter.hpp
/// sensor_msgs/Image (an encoding StereoInputValidator accepted: mono8, mono16, bgr8, rgb8) to the
/// cv::Mat the core takes, without a copy when the bytes can be used as they are: the Mat shares
/// the message's buffer (keep the message alive while the Mat is used). 16-bit images whose
/// is_bigendian differs from this machine's byte order are byte-swapped into a new Mat
/// (cv_bridge 1.16's swap returns a 2-channel 8-bit Mat for them, which the core refuses).

#include <sensor_msgs/Image.h>

#include <opencv2/core.hpp>

namespace stereo_ground_dem {

class ImageMessageConverter {
 public:
  /// Throws std::invalid_argument for an encoding other than the four accepted ones or a buffer
  /// smaller than height * step.
  static cv::Mat toMat(const sensor_msgs::Image& image);
  /// True on a big-endian machine.
  static bool hostIsBigEndian();
};

}  // namespace stereo_ground_dem
