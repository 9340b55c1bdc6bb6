#pragma once
/// \file MapWindowSampler.hpp
/// The layers the node publishes, read from the core's ElevationMap over a window of its lattice:
///   elevation [m], variance [m^2], observations [frames] (ElevationMap::layer), and
///   slope [rad], step [m], roughness [m], traversability [0..1], traversability_confidence [0..1: the
///   probability of being traversable, TraversabilityFilter::probability, 0 on obstacles], and
///   obstacle [1 obstacle, 0 ground seen last], obstacle_height [m above the ground]
///   (ElevationMap::Layer::kObstacle, kObstacleHeight), and, with an ortho-texture, intensity [grey,
///   the first frame's exposure, 8-bit units] (OrthoTexture::sample: the mean of the cell's texels),
///   and with the photometric-residual map, residual [grey] and residual_outlier_rate [0..1].
///   Traversability is 0 wherever obstacle is 1, also where the ground under the obstacle is unknown.
///   With the photometric-residual map, the heights it names contradicted() are unknown (NaN) in
///   elevation, variance and every layer derived from them (slope, step, roughness, traversability
///   and its confidence, so the OccupancyGrid's unknown); observations, obstacle and the residual
///   layers keep their values there (the cell was seen; its height is what the images refute).
/// All CV_32F, NaN where unknown. The filter runs on the window grown by its largest window
/// radius so that cells at the border see the same neighbourhood as inside the map, then is
/// cropped back. Large windows are decimated (every s-th vertex, the window aligned to s) to keep
/// messages bounded; the filter still runs at the map's resolution. No ROS dependency.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/ElevationMap.hpp"
#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/OrthoTexture.hpp"
#include "stereo_ground_dem/PhotometricResidualMap.hpp"
#include "stereo_ground_dem/TraversabilityFilter.hpp"
#include "stereo_ground_dem/ros/GridLayer.hpp"

namespace stereo_ground_dem {

/// A window and its layers (each grid.rows x grid.cols).
struct DemLayers {
  GroundGrid grid;
  std::vector<GridLayer> layers;
  /// The layer called `name`, or nullptr.
  const cv::Mat* find(const std::string& name) const;
  /// Vertices whose elevation is known.
  int knownCount() const;
};

/// The layers kept beside the ElevationMap (null: not published).
struct ExtraLayerSources {
  const OrthoTexture* ortho = nullptr;
  const PhotometricResidualMap* residual = nullptr;
};

class MapWindowSampler {
 public:
  /// Throws std::invalid_argument if `options` is invalid (TraversabilityFilter's check).
  explicit MapWindowSampler(const TraversabilityOptions& options = TraversabilityOptions());
  void setTraversability(const TraversabilityOptions& options);

  /// The layers over `window` (on the map's lattice), decimated by the smallest stride s whose
  /// window, aligned to multiples of s (so that it covers `window` on the coarser lattice), has at
  /// most max_cells vertices (max_cells <= 0: no limit; a cap below 9 may leave 2 or 3 vertices a
  /// side); `extra` adds their layers.
  DemLayers sample(const ElevationMap& map, const GroundGrid& window, int max_cells = 0,
                   const ExtraLayerSources& extra = ExtraLayerSources()) const;

  /// The lattice window of spacing resolution_m whose vertex rectangle has its centre nearest to
  /// (center_x, center_y) and spans at least size_x_m x size_y_m (at least 2 x 2 vertices).
  static GroundGrid window(double resolution_m, double center_x, double center_y, double size_x_m, double size_y_m);
  /// The smallest stride s >= 1 with ceil(rows / s) * ceil(cols / s) <= max_cells.
  static int stride(int rows, int cols, int max_cells);

 private:
  TraversabilityFilter filter_;
};

}  // namespace stereo_ground_dem
