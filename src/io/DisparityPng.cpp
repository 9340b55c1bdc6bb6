#include "stereo_ground_dem/io/DisparityPng.hpp"

#include <cmath>
#include <cstdint>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

namespace stereo_ground_dem {

namespace {
[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw std::runtime_error("DisparityPng: " + path + ": " + what);
}
}  // namespace

cv::Mat DisparityPng::encode(const cv::Mat& disparity_px) {
  if (disparity_px.type() != CV_32FC1) {
    throw std::runtime_error("DisparityPng::encode: disparity is not CV_32F single-channel");
  }
  cv::Mat out(disparity_px.size(), CV_16UC1);
  for (int r = 0; r < disparity_px.rows; ++r) {
    const float* in = disparity_px.ptr<float>(r);
    std::uint16_t* o = out.ptr<std::uint16_t>(r);
    for (int c = 0; c < disparity_px.cols; ++c) {
      const double d = in[c];
      if (!std::isfinite(d) || d <= 0.0) {
        o[c] = 0;
      } else {
        const double q = std::round(d * 256.0);
        o[c] = static_cast<std::uint16_t>(q >= 65535.0 ? 65535.0 : (q < 1.0 ? 1.0 : q));
      }
    }
  }
  return out;
}

void DisparityPng::write(const std::string& path, const cv::Mat& disparity_px) {
  if (disparity_px.type() != CV_32FC1 || disparity_px.empty()) {
    fail(path, "disparity is empty or not CV_32F single-channel");
  }
  const cv::Mat png = encode(disparity_px);
  bool ok = false;
  try {
    ok = cv::imwrite(path, png, {cv::IMWRITE_PNG_COMPRESSION, 3});
  } catch (const cv::Exception& e) {
    fail(path, "cannot write PNG: " + e.err);
  }
  if (!ok) fail(path, "cannot write PNG (directory missing or not writable, or not a .png name?)");
}

cv::Mat DisparityPng::read(const std::string& path, float none_value) {
  if (!std::ifstream(path).good()) fail(path, "no such file or not readable");
  cv::Mat png;
  try {
    png = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    fail(path, "cannot read: " + e.err);
  }
  if (png.empty()) fail(path, "missing or not an image");
  if (png.type() != CV_16UC1) fail(path, "not a 16-bit single-channel PNG (KITTI disparity format)");
  cv::Mat out(png.size(), CV_32FC1);
  for (int r = 0; r < png.rows; ++r) {
    const std::uint16_t* in = png.ptr<std::uint16_t>(r);
    float* o = out.ptr<float>(r);
    for (int c = 0; c < png.cols; ++c) o[c] = in[c] == 0 ? none_value : static_cast<float>(in[c]) / 256.0f;
  }
  return out;
}

}  // namespace stereo_ground_dem
