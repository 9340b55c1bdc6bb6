#include "stereo_ground_dem/ros/StereoInputValidator.hpp"

#include <sensor_msgs/image_encodings.h>

#include <Eigen/Core>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace stereo_ground_dem {

namespace enc = sensor_msgs::image_encodings;

namespace {

std::string sizeText(unsigned w, unsigned h) {
  std::ostringstream os;
  os << w << "x" << h;
  return os.str();
}

Eigen::Matrix<double, 3, 4> projection(const sensor_msgs::CameraInfo& info) {
  Eigen::Matrix<double, 3, 4> p;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) p(r, c) = info.P[static_cast<size_t>(r * 4 + c)];
  return p;
}

void checkOneInfo(const sensor_msgs::CameraInfo& info, const std::string& side) {
  if (info.width == 0 || info.height == 0) {
    throw std::invalid_argument(side + " camera_info has no image size (width x height = " +
                                sizeText(info.width, info.height) + ")");
  }
  if (info.binning_x > 1 || info.binning_y > 1) {
    std::ostringstream os;
    os << side << " camera_info has binning " << info.binning_x << "x" << info.binning_y
       << "; publish full-resolution rectified images (binning 0 or 1)";
    throw std::invalid_argument(os.str());
  }
  const auto& roi = info.roi;
  const bool full_roi = (roi.width == 0 && roi.height == 0) ||
                        (roi.x_offset == 0 && roi.y_offset == 0 && roi.width == info.width && roi.height == info.height);
  if (!full_roi) {
    std::ostringstream os;
    os << side << " camera_info has a region of interest (" << roi.width << "x" << roi.height << " at "
       << roi.x_offset << "," << roi.y_offset << "); publish full rectified images";
    throw std::invalid_argument(os.str());
  }
  for (size_t i = 0; i < info.P.size(); ++i) {
    if (!std::isfinite(info.P[i])) {
      std::ostringstream os;
      os << side << " camera_info P[" << i << "] is " << info.P[i]
         << ": the calibration is broken (NaN or infinite projection matrix)";
      throw std::invalid_argument(os.str());
    }
  }
  bool all_zero = true;
  for (double v : info.P) all_zero = all_zero && v == 0.0;
  if (all_zero) {
    throw std::invalid_argument(side + " camera_info has no projection matrix P (all zeros): the camera is not "
                                "calibrated, or this is not the rectified camera_info");
  }
}

}  // namespace

std::string StereoInputValidator::checkEncoding(const std::string& encoding) {
  if (encoding == enc::MONO8 || encoding == enc::MONO16 || encoding == enc::BGR8 || encoding == enc::RGB8) return "";
  if (enc::isBayer(encoding)) {
    return "encoding '" + encoding +
           "' is a raw Bayer image: debayer and rectify it first (image_proc / stereo_image_proc) and subscribe "
           "to image_rect";
  }
  if (encoding.empty()) return "the image has no encoding";
  if (encoding == enc::TYPE_8UC1 || encoding == enc::TYPE_16UC1) {
    return "encoding '" + encoding +
           "' is a generic (depth-image) encoding, not a grey image: publish mono8 or mono16 (or remap the "
           "camera's image_rect, not a depth image)";
  }
  return "encoding '" + encoding + "' is not supported (use mono8, mono16, bgr8 or rgb8)";
}

ImagePyramid::ColorOrder StereoInputValidator::colorOrder(const std::string& encoding) {
  return encoding == enc::RGB8 ? ImagePyramid::ColorOrder::kRgb : ImagePyramid::ColorOrder::kBgr;
}

std::string StereoInputValidator::checkImage(const sensor_msgs::Image& image, const std::string& side) {
  const std::string e = checkEncoding(image.encoding);
  if (!e.empty()) return side + " image: " + e;
  if (image.width == 0 || image.height == 0) return side + " image is empty (" + sizeText(image.width, image.height) + ")";
  const size_t pixel = static_cast<size_t>(enc::numChannels(image.encoding)) *
                       static_cast<size_t>(enc::bitDepth(image.encoding) / 8);
  if (static_cast<size_t>(image.step) < image.width * pixel) {
    std::ostringstream os;
    os << side << " image: step " << image.step << " bytes is less than width " << image.width << " x " << pixel
       << " bytes per pixel";
    return os.str();
  }
  if (image.data.size() < static_cast<size_t>(image.step) * image.height) {
    std::ostringstream os;
    os << side << " image: " << image.data.size() << " data bytes, expected height " << image.height << " x step "
       << image.step << " = " << static_cast<size_t>(image.step) * image.height;
    return os.str();
  }
  return "";
}

StereoRig StereoInputValidator::rigFromCameraInfo(const sensor_msgs::CameraInfo& left,
                                                  const sensor_msgs::CameraInfo& right) {
  checkOneInfo(left, "left");
  checkOneInfo(right, "right");
  if (left.width != right.width || left.height != right.height) {
    throw std::invalid_argument("left camera_info is " + sizeText(left.width, left.height) +
                                " but right camera_info is " + sizeText(right.width, right.height) +
                                "; a rectified pair has one image size");
  }
  return StereoRig::fromProjectionMatrices(projection(left), projection(right), static_cast<int>(left.width),
                                           static_cast<int>(left.height));
}

bool StereoInputValidator::sameCalibration(const sensor_msgs::CameraInfo& a, const sensor_msgs::CameraInfo& b) {
  return a.P == b.P && a.width == b.width && a.height == b.height && a.binning_x == b.binning_x &&
         a.binning_y == b.binning_y && a.roi.x_offset == b.roi.x_offset && a.roi.y_offset == b.roi.y_offset &&
         a.roi.width == b.roi.width && a.roi.height == b.roi.height;
}

StereoInputCheck StereoInputValidator::check(const sensor_msgs::Image& left, const sensor_msgs::CameraInfo& left_info,
                                             const sensor_msgs::Image& right,
                                             const sensor_msgs::CameraInfo& right_info) {
  StereoInputCheck out;
  // 1. calibration, validated once per change
  if (!have_cached_ || !sameCalibration(left_info, cached_left_) || !sameCalibration(right_info, cached_right_)) {
    ++calibration_checks_;
    cached_left_ = left_info;
    cached_right_ = right_info;
    have_cached_ = true;
    try {
      cached_rig_ = rigFromCameraInfo(left_info, right_info);
      cached_problem_.clear();
    } catch (const std::invalid_argument& e) {
      cached_problem_ = std::string("camera_info: ") + e.what();
    }
  }
  if (!cached_problem_.empty()) {
    out.problem = cached_problem_;
    return out;
  }
  // 2. the images
  for (const auto* p : {&left, &right}) {
    const std::string side = p == &left ? "left" : "right";
    const std::string why = checkImage(*p, side);
    if (!why.empty()) {
      out.problem = why;
      return out;
    }
  }
  if (left.encoding != right.encoding) {
    out.problem = "left image is " + left.encoding + " but right image is " + right.encoding +
                  "; both cameras must publish the same encoding";
    return out;
  }
  if (left.width != right.width || left.height != right.height) {
    out.problem = "left image is " + sizeText(left.width, left.height) + " but right image is " +
                  sizeText(right.width, right.height);
    return out;
  }
  if (left.width != left_info.width || left.height != left_info.height) {
    out.problem = "images are " + sizeText(left.width, left.height) + " but camera_info says " +
                  sizeText(left_info.width, left_info.height) + " (images and camera_info from different sources?)";
    return out;
  }
  out.ok = true;
  out.rig = cached_rig_;
  out.order = colorOrder(left.encoding);
  const StereoRig& a = last_valid_rig_;
  const StereoRig& b = cached_rig_;
  out.calibration_changed = have_valid_rig_ && (a.fx != b.fx || a.fy != b.fy || a.cx != b.cx || a.cy != b.cy ||
                                                 a.baseline_m != b.baseline_m || a.width != b.width ||
                                                 a.height != b.height);
  last_valid_rig_ = cached_rig_;
  have_valid_rig_ = true;
  return out;
}

}  // namespace stereo_ground_dem
