#include "stereo_ground_dem/GreyConverter.hpp"

#include <cmath>
#include <cstdint>
#include <opencv2/core/check.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

namespace stereo_ground_dem {

namespace {

bool acceptedType(const cv::Mat& image) {
  const int depth = image.depth(), ch = image.channels();
  if (depth == CV_32F) return ch == 1;
  return (depth == CV_8U || depth == CV_16U) && (ch == 1 || ch == 3 || ch == 4);
}

std::string acceptedTypeError(const cv::Mat& image) {
  return "unsupported image type " + GreyConverter::typeName(image.type()) +
         " (accepted: CV_8UC1/3/4, CV_16UC1/3/4, CV_32FC1)";
}

void checkBitDepth(int bit_depth) {
  if (bit_depth < 8 || bit_depth > 16) {
    throw std::invalid_argument("bit depth of 16-bit samples must be 8..16, got " + std::to_string(bit_depth));
  }
}

double scale16(int bit_depth) { return 255.0 / (std::ldexp(1.0, bit_depth) - 1.0); }

cv::Mat greyOf(const cv::Mat& image, GreyConverter::ColorOrder order) {
  const int ch = image.channels();
  if (ch == 1) return image;
  const bool rgb = order == GreyConverter::ColorOrder::kRgb;
  const int code = ch == 3 ? (rgb ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY)
                           : (rgb ? cv::COLOR_RGBA2GRAY : cv::COLOR_BGRA2GRAY);
  cv::Mat grey;
  cv::cvtColor(image, grey, code);
  return grey;
}

}  // namespace

bool GreyConverterOptions::isValid(std::string* why) const {
  auto bad = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (image_bit_depth != 0 && (image_bit_depth < 8 || image_bit_depth > 16)) {
    return bad("image_bit_depth must be 0 (detect) or 8..16, got " + std::to_string(image_bit_depth));
  }
  if (min_side_px < 1) return bad("min_side_px must be >= 1");
  if (max_side_px < min_side_px) return bad("max_side_px must be >= min_side_px");
  if (!(max_megapixels > 0.0) || !std::isfinite(max_megapixels)) return bad("max_megapixels must be finite and > 0");
  return true;
}

GreyConverter::GreyConverter(const GreyConverterOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("GreyConverterOptions: " + why);
  bit_depth_ = options_.image_bit_depth;
}

std::string GreyConverter::typeName(int type) { return cv::typeToString(type); }

std::string GreyConverter::check(const cv::Mat& image, const GreyConverterOptions& limits) {
  if (image.empty()) return "image is empty";
  if (!acceptedType(image)) return acceptedTypeError(image);
  std::ostringstream os;
  if (image.cols > limits.max_side_px || image.rows > limits.max_side_px) {
    os << "image " << image.cols << "x" << image.rows << " exceeds the limit of " << limits.max_side_px
       << " px per side";
    return os.str();
  }
  const double mpx = static_cast<double>(image.cols) * image.rows / 1e6;
  if (mpx > limits.max_megapixels) {
    os << "image " << image.cols << "x" << image.rows << " has " << mpx << " Mpx, more than the limit of "
       << limits.max_megapixels << " Mpx";
    return os.str();
  }
  if (image.cols < limits.min_side_px || image.rows < limits.min_side_px) {
    os << "image " << image.cols << "x" << image.rows << " is smaller than " << limits.min_side_px << " px per side";
    return os.str();
  }
  return {};
}

int GreyConverter::detectBitDepth(const cv::Mat& image16) {
  if (image16.empty() || image16.depth() != CV_16U) {
    throw std::invalid_argument("detectBitDepth needs a 16-bit image, got " + typeName(image16.type()));
  }
  double lo = 0.0, hi = 0.0;
  cv::minMaxIdx(image16.reshape(1), &lo, &hi);
  for (int bits : {8, 10, 12, 14}) {
    if (hi <= std::ldexp(1.0, bits) - 1.0) return bits;
  }
  return 16;
}

cv::Mat GreyConverter::toHostByteOrder(const cv::Mat& image, ByteOrder bytes) {
  const size_t elem = image.elemSize1();
  if (bytes == kHostByteOrder || elem == 1) return image;
  cv::Mat out = image.clone();
  const int per_row = out.cols * out.channels();
  for (int r = 0; r < out.rows; ++r) {
    if (elem == 2) {
      auto* p = out.ptr<std::uint16_t>(r);
      for (int i = 0; i < per_row; ++i) p[i] = static_cast<std::uint16_t>((p[i] >> 8) | (p[i] << 8));
    } else if (elem == 4) {
      auto* p = out.ptr<std::uint32_t>(r);
      for (int i = 0; i < per_row; ++i) p[i] = __builtin_bswap32(p[i]);
    } else if (elem == 8) {
      auto* p = out.ptr<std::uint64_t>(r);
      for (int i = 0; i < per_row; ++i) p[i] = __builtin_bswap64(p[i]);
    }
  }
  return out;
}

cv::Mat GreyConverter::toGrey(const cv::Mat& image, int bit_depth, ColorOrder order, ByteOrder bytes,
                              const GreyConverterOptions& limits) {
  const std::string why = check(image, limits);
  if (!why.empty()) throw std::invalid_argument(why);
  const cv::Mat host = toHostByteOrder(image, bytes);
  double scale = 1.0;
  if (host.depth() == CV_16U) {
    checkBitDepth(bit_depth);
    scale = scale16(bit_depth);
  }
  if (host.depth() == CV_32F) {
    int bad = 0, first_u = -1, first_v = -1;
    for (int v = 0; v < host.rows; ++v) {
      const float* p = host.ptr<float>(v);
      for (int u = 0; u < host.cols; ++u) {
        if (std::isfinite(p[u])) continue;
        if (bad++ == 0) {
          first_u = u;
          first_v = v;
        }
      }
    }
    if (bad > 0) {
      std::ostringstream os;
      os << "float image has " << bad << " non-finite pixels (first at u " << first_u << ", v " << first_v << ")";
      throw std::invalid_argument(os.str());
    }
  }
  cv::Mat out;
  greyOf(host, order).convertTo(out, CV_32F, scale);
  if (out.data == image.data) out = out.clone();
  return out;
}

cv::Mat GreyConverter::convert(const cv::Mat& image, ColorOrder order, ByteOrder bytes) {
  const std::string why = check(image, options_);
  if (!why.empty()) throw std::invalid_argument(why);
  const cv::Mat host = toHostByteOrder(image, bytes);
  if (host.depth() == CV_16U && bit_depth_ == 0) bit_depth_ = detectBitDepth(host);
  return toGrey(host, host.depth() == CV_16U ? bit_depth_ : 16, order, kHostByteOrder, options_);
}

cv::Mat GreyConverter::toBgr8(const cv::Mat& image, int bit_depth, ColorOrder order) {
  if (image.empty()) throw std::invalid_argument("image is empty");
  if (!acceptedType(image)) throw std::invalid_argument(acceptedTypeError(image));
  cv::Mat eight;
  if (image.depth() == CV_16U) {
    const int bits = bit_depth > 0 ? bit_depth : detectBitDepth(image);
    checkBitDepth(bits);
    image.convertTo(eight, CV_8U, scale16(bits));
  } else if (image.depth() == CV_32F) {
    image.convertTo(eight, CV_8U);  // saturates to 0..255
  } else {
    eight = image;
  }
  const bool rgb = order == ColorOrder::kRgb;
  cv::Mat out;
  switch (eight.channels()) {
    case 1: cv::cvtColor(eight, out, cv::COLOR_GRAY2BGR); break;
    case 3:
      if (rgb) cv::cvtColor(eight, out, cv::COLOR_RGB2BGR);
      else out = eight.clone();
      break;
    default: cv::cvtColor(eight, out, rgb ? cv::COLOR_RGBA2BGR : cv::COLOR_BGRA2BGR); break;
  }
  return out;
}

}  // namespace stereo_ground_dem
