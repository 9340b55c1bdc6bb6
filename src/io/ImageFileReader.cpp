#include "stereo_ground_dem/io/ImageFileReader.hpp"

#include <array>
#include <cstdint>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <sys/stat.h>
#include <vector>

namespace stereo_ground_dem {

namespace {

const std::array<std::uint32_t, 256>& crcTable() {
  static const std::array<std::uint32_t, 256> table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t n = 0; n < 256; ++n) {
      std::uint32_t c = n;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xedb88320u ^ (c >> 1) : c >> 1;
      t[n] = c;
    }
    return t;
  }();
  return table;
}

std::uint32_t crc32(const unsigned char* p, size_t n) {
  std::uint32_t c = 0xffffffffu;
  const auto& t = crcTable();
  for (size_t i = 0; i < n; ++i) c = t[(c ^ p[i]) & 0xffu] ^ (c >> 8);
  return c ^ 0xffffffffu;
}

std::uint32_t bigEndian32(const unsigned char* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | p[3];
}

std::string checkPng(const unsigned char* data, size_t size) {
  size_t pos = 8;
  bool first = true;
  while (true) {
    if (pos + 12 > size) return "truncated PNG (ends inside a chunk header at byte " + std::to_string(pos) + ")";
    const std::uint32_t length = bigEndian32(data + pos);
    const std::string type(reinterpret_cast<const char*>(data + pos + 4), 4);
    if (length > 0x7fffffffu || pos + 12 + length > size) {
      return "truncated PNG (chunk at byte " + std::to_string(pos) + " runs past the end of the file)";
    }
    for (char c : type) {
      if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z'))) {
        return "corrupt PNG (invalid chunk type at byte " + std::to_string(pos) + ")";
      }
    }
    if (first && type != "IHDR") return "corrupt PNG (first chunk is not IHDR)";
    first = false;
    if (crc32(data + pos + 4, 4 + length) != bigEndian32(data + pos + 8 + length)) {
      return "corrupt PNG (CRC mismatch in the " + type + " chunk at byte " + std::to_string(pos) + ")";
    }
    pos += 12 + length;
    if (type == "IEND") return {};
  }
}

}  // namespace

std::string ImageFileReader::checkContainer(const std::string& bytes) {
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const size_t size = bytes.size();
  static const unsigned char kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (size >= 8 && std::equal(kPng, kPng + 8, data)) return checkPng(data, size);
  if (size >= 3 && data[0] == 0xff && data[1] == 0xd8 && data[2] == 0xff) {
    // trailing padding after the end-of-image marker is allowed
    size_t end = size;
    while (end > 2 && data[end - 1] == 0x00) --end;
    if (end < 4 || data[end - 2] != 0xff || data[end - 1] != 0xd9) return "truncated JPEG (no end-of-image marker)";
  }
  return {};
}

cv::Mat ImageFileReader::read(const std::string& path, std::string* why) {
  auto failed = [&](const std::string& reason) {
    if (why) *why = "cannot read image '" + path + "' (" + reason + ")";
    return cv::Mat();
  };
  struct stat st {};
  if (stat(path.c_str(), &st) != 0) return failed("no such file");
  if (!S_ISREG(st.st_mode)) return failed("not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) return failed("cannot be opened");
  std::ostringstream os;
  os << in.rdbuf();
  const std::string bytes = os.str();
  if (bytes.empty()) return failed("empty file");
  const std::string container = checkContainer(bytes);
  if (!container.empty()) return failed(container);
  const std::vector<unsigned char> buffer(bytes.begin(), bytes.end());
  cv::Mat image;
  try {
    image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception&) {
    return failed("the decoder failed");
  }
  if (image.empty()) return failed("not an image OpenCV can decode");
  if (why) why->clear();
  return image;
}

}  // namespace stereo_ground_dem
