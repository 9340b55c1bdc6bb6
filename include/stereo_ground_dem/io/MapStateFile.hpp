#pragma once
/// \file MapStateFile.hpp
/// A map saved to be continued: the ElevationMap's tiles, the ortho-texture and residual layers,
/// and the estimator's state (EstimatorState.hpp), in one directory:
///
///     state.yaml                        poses, velocity, stamps, levels, rectification, counters
///     previous_left.tif, previous_right.tif, last_left.tif   float images (exact)
///     previous_obstacles_<level>.png    the previous frame's obstacle pixels
///     previous_moving_<level>.png       ... its moving texture (none when nothing moved)
///     carried_moving_<level>.png        ... the part of it flagged in the frame before too
///     map/tile_<row>_<col>.bin          the ElevationMap tiles (its archive format)
///     ortho.bin, residual.bin           the layers' tiles (when they were given)
///
/// `dem_offline` writes one as `OUT/state` after every sequence run and continues one with
/// `--resume OUT`; the node's `~save_map` writes one as `DIR/state` and `~load_map` reads it.
/// The records are binary in the host's byte order, for the same build to continue its own maps
/// (not an exchange format: dem.tif is).

#include <Eigen/Core>
#include <string>
#include <vector>

#include "stereo_ground_dem/ElevationMap.hpp"
#include "stereo_ground_dem/EstimatorState.hpp"
#include "stereo_ground_dem/OrthoTexture.hpp"
#include "stereo_ground_dem/PhotometricResidualMap.hpp"

namespace stereo_ground_dem {

struct SavedMapState {
  EstimatorState estimator;
  std::vector<Eigen::Vector2d> trajectory_xy;  ///< camera positions in G so far (pictures) [m]
  std::string sequence;                        ///< offline: the sequence directory (informative)
  int next_sequence_frame = -1;                ///< offline: the frame after the last one processed (-1: unknown)
  int image_width_px = 0;                      ///< the calibration's image size when saved
  int image_height_px = 0;
};

class MapStateFile {
 public:
  /// Writes `state` and the layers to `directory` (created if missing; a previous save there is
  /// replaced). Throws std::runtime_error naming the file that could not be written.
  static void write(const std::string& directory, const SavedMapState& state, const ElevationMap& map,
                    const OrthoTexture* ortho = nullptr, const PhotometricResidualMap* residual = nullptr);

  /// Reads a directory write() wrote: returns the state and replaces the contents of `map` (and of
  /// `ortho`, `residual` when given and saved). Throws std::runtime_error with a one-line reason
  /// when the directory is missing, incomplete, or saved with another grid layout.
  static SavedMapState read(const std::string& directory, ElevationMap* map, OrthoTexture* ortho = nullptr,
                            PhotometricResidualMap* residual = nullptr);

  /// True when `directory` holds a state.yaml.
  static bool exists(const std::string& directory);
};

}  // namespace stereo_ground_dem
