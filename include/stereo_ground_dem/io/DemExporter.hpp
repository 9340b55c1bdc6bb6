#pragma once
/// \file DemExporter.hpp
/// Writes a DEM and its companion layers and pictures into a folder, the same way for the offline
/// runner and the ROS node's save service:
///   dem.tif (float32 heights [m], NaN unknown), dem.yaml (grid, origin, ground_T_camera0, layers),
///   variance.tif [m^2], traversability.tif [0..1], obstacles.tif (1 obstacle, 0 ground seen, NaN
///   unknown) and obstacle_height.tif [m above the ground] when given,
///   traversability_confidence.tif [0..1, the probability of being traversable] when given,
///   dem_height.png (shaded, coloured, legend, trajectory), traversability.png, mesh.ply;
///   with an ortho-texture (OrthoTexture): intensity.tif (its mean grey per DEM cell), ortho.tif (float32
///   grey on the texel lattice, the same GeoTIFF conventions at ortho_grid's resolution) and ortho.png
///   (8-bit grey + alpha, unknown transparent, drawn like the map pictures: +x up, +y left, one pixel
///   per texel); with the photometric-residual layers, residual.tif [grey] and
///   residual_outlier_rate.tif [0..1].

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"

namespace stereo_ground_dem {

struct DemExport {
  GroundGrid grid;
  cv::Mat elevation;       ///< CV_32F rows x cols [m], NaN unknown
  cv::Mat variance;        ///< optional [m^2]
  cv::Mat traversability;  ///< optional [0..1]
  cv::Mat traversability_confidence;  ///< optional: probability of being traversable [0..1]
  cv::Mat obstacles;       ///< optional: 1 obstacle (on or hidden by one), 0 ground seen, NaN unknown
  cv::Mat obstacle_height; ///< optional: obstacle top above the ground [m], NaN where none measured
  cv::Mat intensity;       ///< optional: ortho-texture grey per cell [8-bit units], NaN unknown
  cv::Mat residual;        ///< optional: photometric residual per cell [grey], NaN never observed
  cv::Mat residual_outlier_rate;  ///< optional: how often the cell was an outlier [0..1]
  cv::Mat ortho;           ///< optional: the ortho-texture on ortho_grid (CV_32F grey, NaN unknown)
  GroundGrid ortho_grid;   ///< the texel lattice window of `ortho`
  Eigen::Isometry3d ground_T_camera0 = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector2d> trajectory_xy;  ///< ground (x, y) of the camera per frame
  std::vector<std::pair<std::string, std::string>> extra;  ///< extra dem.yaml entries (strings)
};

class DemExporter {
 public:
  /// Writes the files into `directory` (created if missing); returns their names. Throws
  /// std::runtime_error (with the path) when something cannot be written.
  static std::vector<std::string> write(const std::string& directory, const DemExport& dem, bool pictures = true);
  /// mkdir -p; throws std::runtime_error on failure.
  static void makeDirectories(const std::string& directory);
  /// The ortho-texture as a picture: BGRA, +x up, +y left, one pixel per texel, unknown transparent.
  static cv::Mat orthoPicture(const cv::Mat& ortho);
};

}  // namespace stereo_ground_dem
