#include "stereo_ground_dem/ros/ImageMessageConverter.hpp"

#include <sensor_msgs/image_encodings.h>

#include <cstdint>
#include <cstring>
#include <stdexcept>

namespace stereo_ground_dem {

namespace enc = sensor_msgs::image_encodings;

bool ImageMessageConverter::hostIsBigEndian() {
  const uint16_t one = 1;
  uint8_t first = 0;
  std::memcpy(&first, &one, 1);
  return first == 0;
}

cv::Mat ImageMessageConverter::toMat(const sensor_msgs::Image& image) {
  int type = -1;
  if (image.encoding == enc::MONO8) type = CV_8UC1;
  else if (image.encoding == enc::MONO16) type = CV_16UC1;
  else if (image.encoding == enc::BGR8 || image.encoding == enc::RGB8) type = CV_8UC3;
  if (type < 0) throw std::invalid_argument("ImageMessageConverter: encoding '" + image.encoding + "' not accepted");
  if (image.data.size() < static_cast<size_t>(image.step) * image.height ||
      static_cast<size_t>(image.step) < image.width * static_cast<size_t>(CV_ELEM_SIZE(type))) {
    throw std::invalid_argument("ImageMessageConverter: the data buffer does not hold height x step bytes");
  }
  // the Mat does not own the buffer and the core only reads it
  const cv::Mat shared(static_cast<int>(image.height), static_cast<int>(image.width), type,
                       const_cast<uint8_t*>(image.data.data()), image.step);
  if (CV_ELEM_SIZE1(type) == 1 || (image.is_bigendian != 0) == hostIsBigEndian()) return shared;
  cv::Mat swapped(shared.rows, shared.cols, type);
  for (int r = 0; r < shared.rows; ++r) {
    const uint16_t* src = shared.ptr<uint16_t>(r);
    uint16_t* dst = swapped.ptr<uint16_t>(r);
    for (int c = 0; c < shared.cols; ++c) dst[c] = static_cast<uint16_t>((src[c] >> 8) | (src[c] << 8));
  }
  return swapped;
}

}  // namespace stereo_ground_dem
