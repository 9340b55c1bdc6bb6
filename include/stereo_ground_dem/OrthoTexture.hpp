#pragma once
/// \file OrthoTexture.hpp
/// The ortho-texture: the left camera's image draped onto the fused surface and seen from above, on
/// a lattice finer than the DEM's (0.1 m by default), so that lane markings, tracks and puddles can
/// be recognised in the map.
///
/// Lattice: texel (i, j) is centred on ground point (x, y) = (j, i) * resolution_m, the same
/// conventions as GroundGrid (row i along +y, column j along +x), stored in square tiles like the
/// ElevationMap and evicted with the same radius.
///
/// Per frame (update()): every texel of the frame's window whose map square has four known heights
/// and no obstacle mark is placed on the surface (piecewise-linear, the mesh's triangles), projected
/// into the left image and sampled bilinearly. Grey levels are brought to the first frame's
/// exposure by chaining the estimated gain/bias between consecutive left images, so the mosaic has
/// no seams where the camera's exposure changed (after a re-initialized frame the link is taken as
/// identity, so a seam can appear there). A texel keeps the best-resolved view: a view that covers
/// more image pixels per texel (closer, less grazing) by `better_view_ratio` replaces the stored
/// value; views of about the same resolution are averaged (a running mean whose count is capped at
/// `max_average_views`, so newer views keep some weight); worse views and back-facing triangles are
/// ignored. Terrain hidden behind nearer terrain is not detected (obstacle cells are left out). For a vehicle driving forward every texel is therefore taken from the
/// last frames that saw it, near the bottom of the image.
///
/// Copies share their tiles (copy on write, LatticeTiles): a copy made after every frame for readers
/// on other threads (the ROS node's services) costs only the tiles the next update() touches.

#include <Eigen/Geometry>
#include <cstdint>
#include <istream>
#include <memory>
#include <opencv2/core.hpp>
#include <ostream>
#include <string>
#include <unordered_map>
#include <vector>

#include "stereo_ground_dem/ElevationMap.hpp"
#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/LatticeTiles.hpp"
#include "stereo_ground_dem/PhotometricParams.hpp"
#include "stereo_ground_dem/StereoRig.hpp"

namespace stereo_ground_dem {

struct OrthoTextureOptions {
  bool enabled = true;               ///< false: update() does nothing (no memory, no time)
  double resolution_m = 0.1;         ///< texel size [m]
  int tile_size = 256;               ///< texels per tile side
  double keep_radius_m = 200.0;      ///< tiles whose centre is farther from the vehicle are evicted [m]
  double min_range_m = 1.0;          ///< texels nearer to the camera (depth along its optical axis) are not taken [m]
  double max_range_m = 30.0;         ///< ... nor deeper ones [m]
  double min_pixels_per_texel = 0.3; ///< views coarser than this (image px per texel side) are not taken
  double better_view_ratio = 1.25;   ///< a view this much better resolved replaces the stored one (> 1)
  int max_average_views = 8;         ///< views of a similar resolution averaged (a running mean of at most this many)
  int image_margin_px = 2;           ///< texels projecting this close to the image border are not taken [px]

  bool isValid(std::string* why) const;
};

class OrthoTexture {
 public:
  explicit OrthoTexture(const OrthoTextureOptions& options = OrthoTextureOptions());

  /// Textures the window of one mapped frame from its left image (CV_32F grey, 8-bit units, full
  /// resolution of `rig`) at the camera pose `ground_T_camera`, with the surface of `map` (which
  /// must already hold this frame's fused heights). `left_vs_previous` is the estimated gain/bias
  /// between this left image and the previous mapped one (L_k = gain * L_{k-1} + bias; identity for
  /// the first frame or when unknown); it is chained to keep the first frame's exposure. Returns the
  /// number of texels written.
  int update(const ElevationMap& map, const GroundGrid& window, const cv::Mat& left, const StereoRig& rig,
             const Eigen::Isometry3d& ground_T_camera, const PhotometricParams& left_vs_previous);

  /// Grey level [first frame's exposure, 0..255] at the vertices of `grid` (CV_32F rows x cols,
  /// NaN unknown): the mean of the known texels within half a cell of each vertex (the texel itself
  /// at the texel resolution; through cells wider than 5 texels, 5 x 5 of them evenly spaced).
  cv::Mat sample(const GroundGrid& grid) const;

  /// The bounding grid of every known texel on the lattice of factor * resolution_m (empty grid if
  /// none). Throws std::length_error beyond GroundGrid's limits.
  GroundGrid knownBounds(int factor = 1) const;
  /// The whole known texture (sample() of knownBounds(f)), at the texel resolution, or coarsened by
  /// the smallest integer f that keeps it within max_texels (16 M: 64 MB of floats); `grid`
  /// receives the raster's grid.
  cv::Mat raster(GroundGrid* grid, long long max_texels = 16LL << 20) const;

  /// Removes the tiles whose centre is farther than keep_radius_m from (x, y); returns how many.
  int evictFarFrom(double x, double y);
  void clear();

  /// The texture (tiles and exposure reference) as a binary record, for a map continued in a
  /// later run; read() replaces this texture with one (std::runtime_error when it does not fit
  /// this texture's resolution and tile size, or is truncated).
  void write(std::ostream& out) const;
  void read(std::istream& in);

  /// The affine map from the current left image's grey levels to the first frame's.
  const PhotometricParams& toReference() const { return to_reference_; }
  size_t tileCount() const { return tiles_.size(); }
  size_t memoryBytes() const;
  const OrthoTextureOptions& options() const { return options_; }

 private:
  struct Tile {
    explicit Tile(size_t n);
    std::vector<float> value;    ///< grey [reference exposure], NaN unknown
    std::vector<float> quality;  ///< image pixels per texel side of the stored view
    std::vector<uint8_t> views;  ///< views averaged into value (0: unknown)
    template <class Self, class F>
    static void forEachBuffer(Self& t, F f) {
      f(t.value);
      f(t.quality);
      f(t.views);
    }
  };
  bool knownExtent(long long* i0, long long* i1, long long* j0, long long* j1) const;

  OrthoTextureOptions options_;
  LatticeTiles<Tile> tiles_;
  PhotometricParams to_reference_;
  bool has_reference_ = false;
};

}  // namespace stereo_ground_dem
