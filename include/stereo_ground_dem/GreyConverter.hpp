#pragma once
/// \file GreyConverter.hpp
/// The one conversion of camera images into what the estimators work on: single-channel CV_32F
/// grey in 8-bit grey levels (0..255) whatever the input type. Every photometric threshold of the
/// estimator (robust scale, dark and saturated levels, the input checks) is in 8-bit grey levels,
/// so 16-bit images are scaled by their REAL bit depth: 12-bit data stored in 16-bit samples
/// (0..4095) maps 4095 -> 255, not 65535 -> 255.
///
/// Accepted: CV_8UC1/3/4, CV_16UC1/3/4 (colour order BGR(A) or RGB(A)) and CV_32FC1 (already in
/// grey levels, every pixel finite). Samples may be big-endian (ROS `is_bigendian`): they are
/// swapped to the host order first. Anything else, and images outside the size limits, throw
/// std::invalid_argument with one line naming the type or the size and the limit.
///
/// The bit depth of 16-bit images is `image_bit_depth` when set, else detected ONCE from the
/// maximum of the first 16-bit image converted (the smallest of 8, 10, 12, 14 and 16 bits that
/// holds it) and kept for every later image, so that the scale never changes within a run.
/// A very dark first image of 12-bit data may be detected as 10 bits: set `image_bit_depth` then.
/// Samples above the bit depth's maximum come out above 255 grey (and count as saturated).

#include <opencv2/core.hpp>
#include <string>

namespace stereo_ground_dem {

struct GreyConverterOptions {
  int image_bit_depth = 0;       ///< significant bits of 16-bit samples [bit]: 0 detect, else 8..16
  int min_side_px = 32;          ///< narrower or lower images are refused [px]
  int max_side_px = 8192;        ///< wider or higher images are refused [px]
  double max_megapixels = 32.0;  ///< images with more pixels are refused [Mpx]

  bool isValid(std::string* why) const;
};

class GreyConverter {
 public:
  enum class ColorOrder { kBgr, kRgb };
  /// Byte order of 16-bit and float samples in memory.
  enum class ByteOrder { kLittleEndian, kBigEndian };
  static constexpr ByteOrder kHostByteOrder =
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
      ByteOrder::kBigEndian;
#else
      ByteOrder::kLittleEndian;
#endif

  /// Throws std::invalid_argument if the options are not valid.
  explicit GreyConverter(const GreyConverterOptions& options = GreyConverterOptions());

  /// Converts one image (see the file comment); fixes the bit depth at the first 16-bit image when
  /// detecting it. Throws std::invalid_argument (one line) for a refused image.
  cv::Mat convert(const cv::Mat& image, ColorOrder order = ColorOrder::kBgr,
                  ByteOrder bytes = kHostByteOrder);

  /// The bit depth used for 16-bit images: image_bit_depth, the detected one, or 0 while unknown.
  int bitDepth() const { return bit_depth_; }
  const GreyConverterOptions& options() const { return options_; }

  /// The stateless conversion: 16-bit samples hold `bit_depth` significant bits (8..16); size
  /// limits from `limits` (its image_bit_depth is ignored).
  static cv::Mat toGrey(const cv::Mat& image, int bit_depth = 16, ColorOrder order = ColorOrder::kBgr,
                        ByteOrder bytes = kHostByteOrder,
                        const GreyConverterOptions& limits = GreyConverterOptions());

  /// "" when toGrey() accepts the image's type and size, else the one-line reason.
  static std::string check(const cv::Mat& image, const GreyConverterOptions& limits = GreyConverterOptions());

  /// The smallest of 8, 10, 12, 14, 16 bits that holds the largest sample of a CV_16U image.
  static int detectBitDepth(const cv::Mat& image16);

  /// A copy with the bytes of every 16-bit or 32-bit sample swapped when `bytes` is not the host's
  /// order (8-bit images are returned as they are).
  static cv::Mat toHostByteOrder(const cv::Mat& image, ByteOrder bytes);

  /// A picture-ready CV_8UC3 (BGR) of any accepted image: colour kept, 16-bit scaled by
  /// `bit_depth` (0: detected from this image), float grey clamped to 0..255.
  static cv::Mat toBgr8(const cv::Mat& image, int bit_depth = 0, ColorOrder order = ColorOrder::kBgr);

  /// OpenCV's name of a type, e.g. "CV_16UC3", for error messages.
  static std::string typeName(int type);

 private:
  GreyConverterOptions options_;
  int bit_depth_ = 0;
};

}  // namespace stereo_ground_dem
