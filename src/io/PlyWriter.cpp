#include "stereo_ground_dem/io/PlyWriter.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "stereo_ground_dem/io/DemPicture.hpp"
#include "stereo_ground_dem/io/NumberText.hpp"

namespace stereo_ground_dem {

namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw std::runtime_error("PlyWriter: " + path + ": " + what);
}

void putLe32(std::string* out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out->push_back(static_cast<char>((v >> (8 * i)) & 0xffu));
}

void putFloat(std::string* out, float f) {
  std::uint32_t bits = 0;
  std::memcpy(&bits, &f, sizeof(bits));
  putLe32(out, bits);
}

}  // namespace

PlyMeshStats PlyWriter::writeMesh(const std::string& path, const GroundGrid& grid, const cv::Mat& heights,
                                  bool colour_by_height, PlyFormat format) {
  if (heights.type() != CV_32FC1 || heights.rows != grid.rows || heights.cols != grid.cols) {
    fail(path, "heights are not CV_32F of grid.rows x grid.cols");
  }
  // Known vertices get consecutive PLY indices.
  std::vector<int> ply_index(static_cast<size_t>(grid.vertexCount()), -1);
  PlyMeshStats stats;
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      if (std::isfinite(heights.at<float>(r, c)))
        ply_index[static_cast<size_t>(grid.index(r, c))] = stats.vertices++;
    }
  }
  std::vector<std::array<int, 3>> faces;
  for (int t = 0; t < grid.triangleCount(); ++t) {
    const std::array<int, 3> tri = grid.triangle(t);
    std::array<int, 3> f{};
    bool known = true;
    for (int k = 0; k < 3; ++k) {
      f[static_cast<size_t>(k)] = ply_index[static_cast<size_t>(tri[static_cast<size_t>(k)])];
      known = known && f[static_cast<size_t>(k)] >= 0;
    }
    if (known) faces.push_back(f);
  }
  stats.faces = static_cast<int>(faces.size());

  double lo = 0.0, hi = 1.0;
  const bool coloured = colour_by_height && DemPicture::robustRange(heights, 2.0, 98.0, &lo, &hi);
  const cv::Mat lut = DemPicture::colourLut(DemPictureOptions().height_colormap);

  const bool binary = format == PlyFormat::kBinaryLittleEndian;
  std::ostringstream header;
  header << "ply\n"
         << "format " << (binary ? "binary_little_endian" : "ascii") << " 1.0\n"
         << "comment stereo_ground_dem ground mesh: ground frame x forward, y left, z up [m]\n"
         << "comment grid resolution " << NumberText::shortest(grid.resolution_m) << " origin "
         << NumberText::shortest(grid.x0()) << " " << NumberText::shortest(grid.y0()) << " rows " << grid.rows
         << " cols " << grid.cols << "\n"
         << "element vertex " << stats.vertices << "\n"
         << "property float x\nproperty float y\nproperty float z\n"
         << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
         << "element face " << stats.faces << "\n"
         << "property list uchar int vertex_indices\n"
         << "end_header\n";
  std::string body = header.str();
  std::ostringstream ascii;
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      const float z = heights.at<float>(r, c);
      if (!std::isfinite(z)) continue;
      cv::Vec3b bgr(200, 200, 200);
      if (coloured) {
        const double u = std::min(1.0, std::max(0.0, (z - lo) / (hi - lo)));
        bgr = lut.at<cv::Vec3b>(0, static_cast<int>(std::lround(u * 255.0)));
      }
      const auto x = static_cast<float>(grid.xOfCol(c));
      const auto y = static_cast<float>(grid.yOfRow(r));
      if (binary) {
        putFloat(&body, x);
        putFloat(&body, y);
        putFloat(&body, z);
        for (int k = 2; k >= 0; --k) body.push_back(static_cast<char>(bgr[k]));
      } else {
        ascii << NumberText::shortestFloat(x) << " " << NumberText::shortestFloat(y) << " "
              << NumberText::shortestFloat(z) << " " << int(bgr[2]) << " " << int(bgr[1]) << " "
              << int(bgr[0]) << "\n";
      }
    }
  }
  for (const auto& f : faces) {
    if (binary) {
      body.push_back(static_cast<char>(3));
      for (int v : f) putLe32(&body, static_cast<std::uint32_t>(v));
    } else {
      ascii << "3 " << f[0] << " " << f[1] << " " << f[2] << "\n";
    }
  }
  if (!binary) body += ascii.str();

  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) fail(path, "cannot open for writing");
  out.write(body.data(), static_cast<std::streamsize>(body.size()));
  out.flush();
  if (!out) fail(path, "write error");
  return stats;
}

}  // namespace stereo_ground_dem
