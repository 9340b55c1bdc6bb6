#pragma once
/// \file DemMetadata.hpp
/// `dem.yaml`: what a reader needs to interpret the DEM rasters written beside it, as plain YAML
/// (python3-yaml, ruamel, yaml-cpp; OpenCV's FileStorage wants its own "%YAML:1.0" first line,
/// which plain parsers reject, so the file has none and read() supplies it). Example:
///
///     # stereo_ground_dem DEM metadata
///     resolution: 0.5            # vertex spacing [m]
///     origin: [-2, -10.5]        # ground (x, y) of vertex (row 0, col 0) [m]
///     rows: 43                   # vertices along y
///     cols: 81                   # vertices along x
///     ground_T_camera0: [1, 0, 0, 0,
///                        0, 1, 0, 0,
///                        0, 0, 1, 1.65,
///                        0, 0, 0, 1]
///     layers: ["elevation", "variance"]
///     conventions: "vertex (r,c) at x = x0 + c*resolution, ..."
///     sequence: "kitti_06"       # extra string values (always double-quoted)
///     frames: 51                 # extra numeric values (never quoted)
///
/// ground_T_camera0 is the pose of the first left camera's optical frame (x right, y down,
/// z forward) in the ground frame, 16 numbers of the 4x4 matrix, row-major.

#include <Eigen/Geometry>
#include <map>
#include <string>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"

namespace stereo_ground_dem {

struct DemMetadata {
  static const char* const kConventions;  ///< the default `conventions` text

  double resolution_m = 0.0;  ///< vertex spacing [m]
  double origin_x_m = 0.0;    ///< ground x of vertex (0, 0) [m]
  double origin_y_m = 0.0;    ///< ground y of vertex (0, 0) [m]
  int rows = 0;               ///< vertices along y
  int cols = 0;               ///< vertices along x
  Eigen::Isometry3d ground_T_camera0 = Eigen::Isometry3d::Identity();
  std::vector<std::string> layers;  ///< layer names, in band order of the GeoTIFF
  std::string conventions = kConventions;
  /// Free extra entries written as top-level keys (letters, digits, '_', '-', '.', starting with
  /// a letter or '_'; not one of the keys above). Strings are written quoted, numbers not.
  std::map<std::string, std::string> extra_strings;
  std::map<std::string, double> extra_numbers;

  /// Metadata of `grid` (resolution, origin, size).
  static DemMetadata fromGrid(const GroundGrid& grid, const Eigen::Isometry3d& ground_T_camera0,
                              const std::vector<std::string>& layers);
  /// The grid described (row0/col0 = origin / resolution); throws std::runtime_error if the origin
  /// is not on the lattice of the resolution.
  GroundGrid grid() const;

  /// Writes the YAML file; throws std::runtime_error (path + reason) on failure or invalid keys.
  void write(const std::string& path) const;
  /// Reads a file written by write() (or by hand in the same shape); unknown top-level keys go to
  /// extra_strings (quoted or non-numeric scalars) or extra_numbers. Throws std::runtime_error
  /// (path + reason) if the file is missing, not YAML, or lacks a required key.
  static DemMetadata read(const std::string& path);
};

}  // namespace stereo_ground_dem
