#pragma once
/// \file PhotometricResidualMap.hpp
/// Where the surface model does not explain the images: per DEM cell, the photometric residual of
/// the last observations and how often it was an outlier (moving objects, vegetation, reflections,
/// ground hidden behind an obstacle).
///
/// Per mapped frame (update()), every cell of the frame's window is sampled on an n x n sub-grid of
/// points on the fused surface (GroundGrid's piecewise-linear mesh). Each point is projected into the
/// current left image and into
///  - the current right image (the stereo pair) with the estimator's own stereo geometry (the
///    rectification's modelled vertical misalignment: the right camera's y offset and the row shift,
///    VerticalMisalignment): r_s = L_k(u) - (g_s R_k(u_r) + b_s),
///  - the previous mapped left image at its pose (the temporal pair): r_t = L_k(u) - (g_t L_{k-1}(u_p) + b_t),
/// with the estimator's gain/bias of each pair (PhotometricParams: reference = gain * other + bias);
/// the temporal pair only for frames whose motion was estimated against that previous frame
/// (tracked frames; a re-initialized frame has no estimated temporal gain). Points where a sampled
/// value is dark or saturated are not used (as in the aligner).
/// The cell's residual this frame is the median over its points of max(|r_s|, |r_t|) [grey], each
/// clamped at `max_residual_grey`; a cell is an outlier this frame when that exceeds
/// max(outlier_sigmas * sigma, min_outlier_grey), sigma = 1.4826 * the median of the frame's cell
/// residuals (the frame's own noise level). Both are fused as exponential moving averages with the
/// weight `update_weight` of the newest frame: `residual` [grey] and `outlier_rate` [0..1].
///
/// Pixels the estimator explained otherwise do not count against the surface (update()'s masks):
/// a point seen through an obstacle pixel is not used (the ground is hidden this frame: a car
/// standing on it), and texture that moved (a moving shadow, a vehicle) leaves only the stereo
/// term. What remains is the surface itself not explaining the images: ground hidden behind a
/// guardrail that the mesh draped, a wrong height. contradicted() names the cells whose outlier
/// rate reached `max_published_outlier_rate`; the products publish their heights as unknown
/// (the estimator's map keeps them).
///
/// Cells live on the ElevationMap's lattice (same resolution), in tiles evicted like the map's;
/// copies share tiles (LatticeTiles).

#include <Eigen/Geometry>
#include <istream>
#include <opencv2/core.hpp>
#include <ostream>
#include <string>
#include <vector>

#include "stereo_ground_dem/ElevationMap.hpp"
#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/LatticeTiles.hpp"
#include "stereo_ground_dem/PhotometricParams.hpp"
#include "stereo_ground_dem/StereoRig.hpp"
#include "stereo_ground_dem/VerticalMisalignment.hpp"

namespace stereo_ground_dem {

struct PhotometricResidualOptions {
  bool enabled = true;             ///< false: update() does nothing
  int samples_per_cell = 4;        ///< n: n x n points per cell
  double max_range_m = 30.0;       ///< points farther from the camera (along its axis) are not used [m]
  double min_range_m = 1.0;        ///< ... nor nearer ones [m]
  double update_weight = 0.5;      ///< weight of the newest frame in the moving averages (0..1]
  double outlier_sigmas = 3.0;     ///< outlier: residual above this many robust sigmas of the frame ...
  double min_outlier_grey = 6.0;   ///< ... and above this [grey]
  double max_residual_grey = 60.0; ///< each point's |residual| is clamped here [grey]
  int min_points = 4;              ///< cells with fewer points in view are not updated this frame
  double keep_radius_m = 200.0;    ///< tiles whose centre is farther from the vehicle are evicted [m]
  int tile_size = 64;              ///< cells per tile side
  int image_margin_px = 2;         ///< points projecting this close to an image border are not used [px]
  double dark_level_grey = 1.5;        ///< sampled values at or below: the point is not used
  double saturated_level_grey = 253.5; ///< ... at or above
  /// Cells whose outlier rate is at or above this are contradicted(): their heights are published as
  /// unknown (> 1: none). With update_weight 0.5, 0.5 means: the cell's last observation was an
  /// outlier (or every one before it was); 0.75: the last two were.
  double max_published_outlier_rate = 0.5;

  bool isValid(std::string* why) const;
};

class PhotometricResidualMap {
 public:
  enum class Layer { kResidual, kOutlierRate, kObservations };

  /// `resolution_m`: the ElevationMap's (cells are its vertices).
  PhotometricResidualMap(double resolution_m, const PhotometricResidualOptions& options = PhotometricResidualOptions());

  /// One mapped frame: `left`, `right` (CV_32F grey, full resolution of `rig`) at `ground_T_camera`,
  /// the map already holding this frame's heights, the rectification modelled (FrameResult::
  /// rectification), the stereo pair's gain/bias (L = g R + b) and the temporal pair's
  /// (L_k = g L_{k-1} + b against the previous frame given to update(); null: no temporal pair this
  /// frame, e.g. a re-initialized one). Keeps a copy of the left image and the pose for the next
  /// frame's temporal pair. `obstacles` and `moving` (CV_8U, non-zero set; over the left image at
  /// any pyramid level, i.e. its size halved k times; empty: none): points seen through an
  /// obstacle pixel are not used, points on moving texture only in the stereo pair
  /// (IncrementalEstimator::lastObstacleMask, lastMovingMask). Returns the cells updated.
  int update(const ElevationMap& map, const GroundGrid& window, const cv::Mat& left, const cv::Mat& right,
             const StereoRig& rig, const Eigen::Isometry3d& ground_T_camera, const VerticalMisalignment& rectification,
             const PhotometricParams& stereo, const PhotometricParams* temporal, const cv::Mat& obstacles = cv::Mat(),
             const cv::Mat& moving = cv::Mat());

  /// Over `grid` (same resolution), CV_8U: 255 where the outlier rate is at or above
  /// max_published_outlier_rate (the images contradict the height there), 0 elsewhere.
  cv::Mat contradicted(const GroundGrid& grid) const;
  /// Sets the cells contradicted() names to NaN in each of `layers` (CV_32F over `grid`); returns
  /// how many cells.
  int unpublishContradicted(const GroundGrid& grid, const std::vector<cv::Mat*>& layers) const;

  /// A layer over `grid` (on the cells' lattice: same resolution), CV_32F, NaN where never observed.
  cv::Mat layer(Layer which, const GroundGrid& grid) const;

  /// Removes the tiles whose centre is farther than keep_radius_m from (x, y); returns how many.
  int evictFarFrom(double x, double y) { return tiles_.evictFarFrom(x, y, options_.keep_radius_m); }
  /// Forgets everything, the previous frame included.
  void clear();

  /// The cells, the previous frame (image and pose) and the last median as a binary record, for a
  /// map continued in a later run; read() replaces this map's with one (std::runtime_error when it
  /// does not fit the resolution and tile size, or is truncated).
  void write(std::ostream& out) const;
  void read(std::istream& in);
  size_t tileCount() const { return tiles_.size(); }
  size_t memoryBytes() const {
    return tiles_.size() * static_cast<size_t>(options_.tile_size) * static_cast<size_t>(options_.tile_size) *
               (2 * sizeof(float) + sizeof(uint16_t)) +
           previous_left_.total() * previous_left_.elemSize();
  }
  /// The median cell residual of the last frame [grey] (NaN before the first).
  double lastMedianResidual() const { return last_median_; }
  const PhotometricResidualOptions& options() const { return options_; }

 private:
  struct Tile {
    explicit Tile(size_t n);
    std::vector<float> residual;      ///< [grey], NaN unknown
    std::vector<float> outlier_rate;  ///< [0..1]
    std::vector<uint16_t> observations;
    template <class Self, class F>
    static void forEachBuffer(Self& t, F f) {
      f(t.residual);
      f(t.outlier_rate);
      f(t.observations);
    }
  };

  PhotometricResidualOptions options_;
  double resolution_m_;
  LatticeTiles<Tile> tiles_;
  cv::Mat previous_left_;
  Eigen::Isometry3d previous_camera_T_ground_ = Eigen::Isometry3d::Identity();
  double last_median_;
};

}  // namespace stereo_ground_dem
