#pragma once
/// \file HeightMeshBuilder.hpp
/// The DEM as an rviz mesh: a visualization_msgs/Marker TRIANGLE_LIST in the grid's frame, with
/// the GroundGrid triangulation (GroundGrid.hpp), one colour per vertex from its height.
///  - Only triangles whose three vertices are known are emitted: no NaN ever reaches rviz.
///  - The size is bounded: when the grid has more than max_triangles triangles it is decimated by
///    the smallest integer stride s (every s-th vertex along rows and columns) that fits.
///  - Colours: a perceptually ordered map (dark blue, low .. yellow, high) over [color_min_m,
///    color_max_m]; NaN bounds mean "automatic": the 2nd and 98th percentiles of the known heights.
///    With colors kIntensity and an intensity layer (the ortho-texture's grey per cell), the mesh
///    is drawn in the ground's own grey instead (height colours where the intensity is unknown).
///    With kResidual and the photometric-residual layer (grey levels per cell), the mesh
///    shows where the surface model does not explain the images: green at 0, yellow at half of
///    residual_max_grey, red at and above it; mid-grey where the residual is unknown.

#include <std_msgs/ColorRGBA.h>
#include <std_msgs/Header.h>
#include <visualization_msgs/Marker.h>

#include <limits>
#include <opencv2/core.hpp>
#include <string>

#include "stereo_ground_dem/GroundGrid.hpp"

namespace stereo_ground_dem {

/// What the mesh's vertex colours show (~mesh_colors: height, intensity, residual).
enum class MeshColors { kHeight, kIntensity, kResidual };

struct HeightMeshOptions {
  int max_triangles = 60000;  ///< upper bound on the triangles of one marker
  double color_min_m = std::numeric_limits<double>::quiet_NaN();  ///< height shown darkest [m]; NaN: auto
  double color_max_m = std::numeric_limits<double>::quiet_NaN();  ///< height shown brightest [m]; NaN: auto
  float alpha = 1.0f;         ///< opacity [0..1]
  MeshColors colors = MeshColors::kHeight;
  double residual_max_grey = 20.0;  ///< residual shown fully red [grey levels]
  std::string ns = "dem";     ///< marker namespace
  int id = 0;
};

class HeightMeshBuilder {
 public:
  /// `elevation`: CV_32F grid.rows x grid.cols [m], NaN unknown. With no known triangle the marker
  /// is a DELETE of (ns, id), so that rviz drops the previous mesh.
  /// `intensity` (optional, same size, grey 0..255, NaN unknown) is used with kIntensity,
  /// `residual` (optional, same size, grey levels, NaN unknown) with kResidual.
  static visualization_msgs::Marker build(const GroundGrid& grid, const cv::Mat& elevation,
                                          const std_msgs::Header& header, const HeightMeshOptions& options,
                                          const cv::Mat* intensity = nullptr, const cv::Mat* residual = nullptr);
  /// The smallest stride s >= 1 whose decimated grid has at most max_triangles triangles.
  static int stride(int rows, int cols, int max_triangles);
  /// The colour of a normalized height u in [0, 1] (clamped).
  static std_msgs::ColorRGBA color(double u, float alpha = 1.0f);
};

}  // namespace stereo_ground_dem
