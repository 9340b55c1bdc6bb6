// GreyConverter: every accepted input type to grey float in 8-bit units, the bit depth of 16-bit
// data (given or detected once), byte order, size limits, and one-line refusals.
#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "stereo_ground_dem/GreyConverter.hpp"
#include "stereo_ground_dem/ImagePyramid.hpp"

using stereo_ground_dem::GreyConverter;
using stereo_ground_dem::GreyConverterOptions;
using stereo_ground_dem::ImagePyramid;

namespace {

std::string refusal(const cv::Mat& image, const GreyConverterOptions& o = GreyConverterOptions()) {
  GreyConverter conv(o);
  try {
    conv.convert(image);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "<accepted>";
}

float at(const cv::Mat& m, int r = 0, int c = 0) { return m.at<float>(r, c); }

}  // namespace

TEST(GreyConverter, EightBitGreyColourAndAlpha) {
  GreyConverter conv;
  const cv::Mat g8(40, 40, CV_8UC1, cv::Scalar(200));
  const cv::Mat out = conv.convert(g8);
  EXPECT_EQ(out.type(), CV_32FC1);
  EXPECT_FLOAT_EQ(at(out), 200.0f);
  // BGR and BGRA of the same grey give that grey; pure blue weighs 0.114 (BGR) or 0.299 (RGB)
  EXPECT_FLOAT_EQ(at(conv.convert(cv::Mat(40, 40, CV_8UC3, cv::Scalar(90, 90, 90)))), 90.0f);
  EXPECT_FLOAT_EQ(at(conv.convert(cv::Mat(40, 40, CV_8UC4, cv::Scalar(90, 90, 90, 7)))), 90.0f);
  const cv::Mat blue(40, 40, CV_8UC3, cv::Scalar(255, 0, 0));
  EXPECT_FLOAT_EQ(at(conv.convert(blue, GreyConverter::ColorOrder::kBgr)), 29.0f);  // round(0.114 * 255)
  EXPECT_FLOAT_EQ(at(conv.convert(blue, GreyConverter::ColorOrder::kRgb)), 76.0f);  // round(0.299 * 255)
  EXPECT_EQ(conv.bitDepth(), 0);  // no 16-bit image seen
}

TEST(GreyConverter, SixteenBitScaledByItsRealBitDepth) {
  // 12-bit data in 16-bit samples: 4095 is white (255), 2048 is 127.5; never 65535 -> 255.
  cv::Mat g12(40, 40, CV_16UC1, cv::Scalar(2048));
  g12.at<std::uint16_t>(0, 1) = 4095;
  GreyConverter detect;
  const cv::Mat out = detect.convert(g12);
  EXPECT_EQ(detect.bitDepth(), 12);
  EXPECT_NEAR(at(out), 2048.0 * 255.0 / 4095.0, 1e-4);
  EXPECT_FLOAT_EQ(at(out, 0, 1), 255.0f);
  // the depth is fixed by the first image: a later darker one keeps the 12-bit scale
  const cv::Mat dark(40, 40, CV_16UC1, cv::Scalar(100));
  EXPECT_NEAR(at(detect.convert(dark)), 100.0 * 255.0 / 4095.0, 1e-4);
  EXPECT_EQ(detect.bitDepth(), 12);
  // full 16-bit data
  GreyConverter full;
  EXPECT_FLOAT_EQ(at(full.convert(cv::Mat(40, 40, CV_16UC1, cv::Scalar(65535)))), 255.0f);
  EXPECT_EQ(full.bitDepth(), 16);
  // a parameter overrides detection (a dark 12-bit first frame would be detected as 10 bits)
  GreyConverterOptions o;
  o.image_bit_depth = 12;
  GreyConverter given(o);
  EXPECT_NEAR(at(given.convert(dark)), 100.0 * 255.0 / 4095.0, 1e-4);
  EXPECT_EQ(given.bitDepth(), 12);
  GreyConverter guess;
  guess.convert(dark);
  EXPECT_EQ(guess.bitDepth(), 8);
  // colour and alpha 16-bit
  GreyConverter c16(o);
  EXPECT_NEAR(at(c16.convert(cv::Mat(40, 40, CV_16UC3, cv::Scalar(4095, 4095, 4095)))), 255.0, 1e-3);
  EXPECT_NEAR(at(c16.convert(cv::Mat(40, 40, CV_16UC4, cv::Scalar(2048, 2048, 2048, 0)))), 127.53, 0.01);
}

TEST(GreyConverter, DetectsStandardBitDepths) {
  for (const auto& [max, bits] : {std::pair<int, int>{0, 8}, {255, 8}, {256, 10}, {1023, 10}, {1024, 12}, {4095, 12},
                                  {4096, 14}, {16383, 14}, {16384, 16}, {65535, 16}}) {
    cv::Mat m(4, 4, CV_16UC3, cv::Scalar(0, 0, 0));
    m.at<cv::Vec3w>(3, 2)[2] = static_cast<std::uint16_t>(max);
    EXPECT_EQ(GreyConverter::detectBitDepth(m), bits) << "max " << max;
  }
  EXPECT_THROW(GreyConverter::detectBitDepth(cv::Mat(4, 4, CV_8U)), std::invalid_argument);
}

TEST(GreyConverter, BigEndianSamples) {
  // mono16 with is_bigendian: the bytes of 0x0FFF (4095) arrive as 0xFF0F on a little-endian host
  cv::Mat big(40, 40, CV_16UC1, cv::Scalar(0));
  const std::uint16_t v = 0x0ABC;  // 2748
  const std::uint16_t swapped = static_cast<std::uint16_t>((v >> 8) | (v << 8));
  const bool host_little = GreyConverter::kHostByteOrder == GreyConverter::ByteOrder::kLittleEndian;
  big.setTo(cv::Scalar(host_little ? swapped : v));
  const cv::Mat out = GreyConverter::toGrey(big, 12, GreyConverter::ColorOrder::kBgr, GreyConverter::ByteOrder::kBigEndian);
  EXPECT_NEAR(at(out), 2748.0 * 255.0 / 4095.0, 1e-4);
  // the host order leaves the samples alone
  const cv::Mat host(40, 40, CV_16UC1, cv::Scalar(v));
  EXPECT_NEAR(at(GreyConverter::toGrey(host, 12, GreyConverter::ColorOrder::kBgr, GreyConverter::kHostByteOrder)),
              2748.0 * 255.0 / 4095.0, 1e-4);
  // 32-bit float big-endian
  cv::Mat f(40, 40, CV_32FC1, cv::Scalar(100.0f));
  const cv::Mat fb = GreyConverter::toHostByteOrder(f, host_little ? GreyConverter::ByteOrder::kBigEndian
                                                                   : GreyConverter::ByteOrder::kLittleEndian);
  EXPECT_FLOAT_EQ(at(GreyConverter::toGrey(fb, 16, GreyConverter::ColorOrder::kBgr,
                                           host_little ? GreyConverter::ByteOrder::kBigEndian
                                                       : GreyConverter::ByteOrder::kLittleEndian)),
                  100.0f);
  // the stateful converter detects the depth after swapping
  GreyConverter conv;
  conv.convert(big, GreyConverter::ColorOrder::kBgr, GreyConverter::ByteOrder::kBigEndian);
  EXPECT_EQ(conv.bitDepth(), 12);
}

TEST(GreyConverter, FloatGreyIsTakenAsItIsAndMustBeFinite) {
  cv::Mat f(40, 40, CV_32FC1, cv::Scalar(123.25f));
  EXPECT_FLOAT_EQ(at(GreyConverter().convert(f)), 123.25f);
  f.at<float>(5, 7) = std::numeric_limits<float>::quiet_NaN();
  f.at<float>(6, 1) = std::numeric_limits<float>::infinity();
  EXPECT_EQ(refusal(f), "float image has 2 non-finite pixels (first at u 7, v 5)");
}

TEST(GreyConverter, RefusesOtherTypesAndSizesInOneLine) {
  EXPECT_EQ(refusal(cv::Mat()), "image is empty");
  EXPECT_EQ(refusal(cv::Mat(40, 40, CV_64FC1)), "unsupported image type CV_64FC1 (accepted: CV_8UC1/3/4, CV_16UC1/3/4, CV_32FC1)");
  EXPECT_EQ(refusal(cv::Mat(40, 40, CV_8UC2)), "unsupported image type CV_8UC2 (accepted: CV_8UC1/3/4, CV_16UC1/3/4, CV_32FC1)");
  EXPECT_EQ(refusal(cv::Mat(40, 40, CV_16SC1)), "unsupported image type CV_16SC1 (accepted: CV_8UC1/3/4, CV_16UC1/3/4, CV_32FC1)");
  EXPECT_EQ(refusal(cv::Mat(40, 40, CV_32FC3)), "unsupported image type CV_32FC3 (accepted: CV_8UC1/3/4, CV_16UC1/3/4, CV_32FC1)");
  EXPECT_EQ(refusal(cv::Mat(8193, 40, CV_8UC1)), "image 40x8193 exceeds the limit of 8192 px per side");
  EXPECT_EQ(refusal(cv::Mat(5000, 8000, CV_8UC1)), "image 8000x5000 has 40 Mpx, more than the limit of 32 Mpx");
  EXPECT_EQ(refusal(cv::Mat(31, 600, CV_8UC1)), "image 600x31 is smaller than 32 px per side");
  GreyConverterOptions bad;
  bad.image_bit_depth = 7;
  std::string why;
  EXPECT_FALSE(bad.isValid(&why));
  EXPECT_EQ(why, "image_bit_depth must be 0 (detect) or 8..16, got 7");
  EXPECT_THROW(GreyConverter c(bad), std::invalid_argument);
  EXPECT_THROW(GreyConverter::toGrey(cv::Mat(40, 40, CV_16UC1), 17), std::invalid_argument);
}

TEST(GreyConverter, PictureImagesKeepColour) {
  const cv::Mat bgra(10, 10, CV_8UC4, cv::Scalar(10, 20, 30, 40));
  cv::Mat out = GreyConverter::toBgr8(bgra);
  ASSERT_EQ(out.type(), CV_8UC3);
  EXPECT_EQ(out.at<cv::Vec3b>(0, 0), cv::Vec3b(10, 20, 30));
  const cv::Mat rgb(10, 10, CV_8UC3, cv::Scalar(10, 20, 30));
  EXPECT_EQ(GreyConverter::toBgr8(rgb, 0, GreyConverter::ColorOrder::kRgb).at<cv::Vec3b>(0, 0), cv::Vec3b(30, 20, 10));
  const cv::Mat g12(10, 10, CV_16UC1, cv::Scalar(4095));
  EXPECT_EQ(GreyConverter::toBgr8(g12).at<cv::Vec3b>(0, 0), cv::Vec3b(255, 255, 255));       // detected 12 bits
  EXPECT_EQ(GreyConverter::toBgr8(g12, 16).at<cv::Vec3b>(0, 0), cv::Vec3b(16, 16, 16));     // taken as 16 bits
  const cv::Mat f(10, 10, CV_32FC1, cv::Scalar(300.0f));
  EXPECT_EQ(GreyConverter::toBgr8(f).at<cv::Vec3b>(0, 0), cv::Vec3b(255, 255, 255));
  EXPECT_THROW(GreyConverter::toBgr8(cv::Mat(10, 10, CV_8UC2)), std::invalid_argument);
}

TEST(GreyConverter, ImagePyramidUsesTheSameConversion) {
  // the pyramid takes 16-bit data as full range and has no minimum size (4x4 stays accepted)
  EXPECT_FLOAT_EQ(ImagePyramid::toGrayFloat(cv::Mat(4, 4, CV_16UC1, cv::Scalar(65535))).at<float>(0, 0), 255.0f);
  EXPECT_FLOAT_EQ(ImagePyramid::toGrayFloat(cv::Mat(4, 4, CV_8UC4, cv::Scalar(50, 50, 50, 0))).at<float>(0, 0), 50.0f);
  try {
    ImagePyramid(cv::Mat(9000, 40, CV_8UC1), 2);
    FAIL() << "no size limit";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "image 40x9000 exceeds the limit of 8192 px per side");
  }
}
