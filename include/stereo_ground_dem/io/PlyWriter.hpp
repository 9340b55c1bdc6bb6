#pragma once
/// \file PlyWriter.hpp
/// The DEM as a triangle mesh in PLY (MeshLab, CloudCompare, Blender, Open3D): one vertex per known
/// grid vertex at its ground (x, y, z) [m] with an RGB colour, one face per triangle of
/// GroundGrid::triangle() whose three vertices are known, wound counter-clockwise seen from +z
/// (normals point up).

#include <opencv2/core.hpp>
#include <string>

#include "stereo_ground_dem/GroundGrid.hpp"

namespace stereo_ground_dem {

enum class PlyFormat { kAscii, kBinaryLittleEndian };

struct PlyMeshStats {
  int vertices = 0;  ///< vertices written (the known ones)
  int faces = 0;     ///< triangles written (all three vertices known)
};

class PlyWriter {
 public:
  /// Writes the mesh of `heights` (CV_32F grid.rows x grid.cols, NaN unknown). With
  /// colour_by_height the vertices are coloured with the viridis map over the 2-98 percentile
  /// height range, else light grey. Throws std::runtime_error (path + reason).
  static PlyMeshStats writeMesh(const std::string& path, const GroundGrid& grid, const cv::Mat& heights,
                                bool colour_by_height = true,
                                PlyFormat format = PlyFormat::kBinaryLittleEndian);
};

}  // namespace stereo_ground_dem
