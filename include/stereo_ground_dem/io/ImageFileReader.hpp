#pragma once
/// \file ImageFileReader.hpp
/// cv::imread with a one-line reason on failure and without the decoders' own stderr messages:
/// PNG files are checked first (signature, every chunk's length and CRC, IHDR first, IEND present),
/// so a truncated or corrupted PNG is refused here instead of making libpng print "libpng error"
/// and return nothing; a JPEG file must end with its end-of-image marker (libjpeg would otherwise
/// decode a truncated file into a partly grey image with a warning).

#include <opencv2/core.hpp>
#include <string>

namespace stereo_ground_dem {

class ImageFileReader {
 public:
  /// The image unchanged (cv::IMREAD_UNCHANGED), or an empty Mat and `why` set to one line naming
  /// the file and the problem (missing, not readable, truncated, corrupt, not an image).
  static cv::Mat read(const std::string& path, std::string* why);

  /// "" when the file's container looks intact (PNG chunks, JPEG end marker; other formats are
  /// not checked), else the problem.
  static std::string checkContainer(const std::string& bytes);
};

}  // namespace stereo_ground_dem
