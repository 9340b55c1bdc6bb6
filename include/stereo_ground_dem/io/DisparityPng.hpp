#pragma once
/// \file DisparityPng.hpp
/// Disparity maps in the KITTI stereo benchmark format: a 16-bit single-channel PNG holding
/// round(d * 256) with 0 meaning "no disparity".

#include <limits>
#include <opencv2/core.hpp>
#include <string>

namespace stereo_ground_dem {

class DisparityPng {
 public:
  /// Writes a CV_32F disparity [px]. NaN, infinite and d <= 0 become 0 (none); a positive d is
  /// stored as min(65535, max(1, round(d * 256))) (a tiny positive disparity stays valid).
  /// Throws std::runtime_error (path + reason).
  static void write(const std::string& path, const cv::Mat& disparity_px);

  /// The uint16 image write() stores (exposed for tests and for in-memory encoding).
  static cv::Mat encode(const cv::Mat& disparity_px);

  /// Reads a KITTI disparity PNG as CV_32F [px]: value / 256, `none_value` where the file holds 0.
  /// Throws std::runtime_error (path + reason) if the file is missing or not 16-bit single-channel.
  static cv::Mat read(const std::string& path, float none_value = std::numeric_limits<float>::quiet_NaN());
};

}  // namespace stereo_ground_dem
