#pragma once
/// \file DemPicture.hpp
/// Pictures of the DEM for people (PNG-ready BGR images).
///
/// Map pictures are drawn as a map seen from above with the vehicle driving up the page: ground
/// +x (forward) points UP and ground +y (left) points LEFT, so grid column c grows upwards and grid
/// row r grows to the left. Each vertex is drawn as a square of pixels_per_cell x pixels_per_cell
/// pixels centred on it. Every map carries a title, a colour-bar legend, a scale bar and an axes
/// sign; unknown cells are a neutral dark grey.
///
///        +x (forward)
///         ^
///         |
///   +y <--+        picture
///
/// overlayOnImage() draws a per-pixel value over a camera image, with a legend strip below it.

#include <Eigen/Core>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"

namespace stereo_ground_dem {

struct DemPictureOptions {
  /// Picture pixels per grid cell (fractional allowed); <= 0: automatic, so that the map's long
  /// side is about auto_map_size_px (integer pixels per cell whenever it is >= 1).
  double pixels_per_cell = 0.0;
  int auto_map_size_px = 900;  ///< target long side of the map for automatic scaling [px]
  /// Colour range [layer units, m for heights]; NaN: the low/high percentiles of the known values.
  double min_value = std::numeric_limits<double>::quiet_NaN();
  double max_value = std::numeric_limits<double>::quiet_NaN();
  double low_percentile = 2.0;                 ///< [%] for the automatic range
  double high_percentile = 98.0;               ///< [%]
  int height_colormap = cv::COLORMAP_VIRIDIS;  ///< perceptually uniform
  bool hillshade = true;                       ///< shade heights by slope (light from light_azimuth_deg)
  double hillshade_strength = 0.6;             ///< 0: flat colours .. 1: full Lambert shading
  double hillshade_z_factor = 1.0;             ///< vertical exaggeration of the shading only
  /// Compass direction the light comes from, clockwise from picture-up (= +x): 315 = north-west,
  /// i.e. from the upper left of the picture (forward-left of the vehicle).
  double light_azimuth_deg = 315.0;
  double light_elevation_deg = 45.0;              ///< above the horizon [deg]
  cv::Vec3b unknown_bgr = cv::Vec3b(64, 64, 64);  ///< colour of unknown cells
  std::string title;            ///< empty: a default title naming the picture and the resolution
  double overlay_alpha = 0.55;  ///< opacity of overlayOnImage()'s colours, 0..1
  int overlay_colormap = cv::COLORMAP_TURBO;  ///< colour map of overlayOnImage()
  /// Significant bits of 16-bit camera images given to overlayOnImage() [bit]: 0 detect from the
  /// image (GreyConverter::detectBitDepth), else 8..16.
  int image_bit_depth = 0;

  bool isValid(std::string* why = nullptr) const;
};

/// Where the map landed in a picture, to draw more on it.
struct DemPictureLayout {
  cv::Rect map_rect;           ///< the map's pixels in the picture
  double pixels_per_cell = 0;  ///< scale used
  GroundGrid grid;             ///< grid drawn
  /// Picture pixel (sub-pixel, OpenCV coordinates: x right, y down) of ground point (x, y) [m].
  cv::Point2d pixelOf(double x_m, double y_m) const;
};

class DemPicture {
 public:
  /// Heights (CV_32F grid.rows x grid.cols, NaN unknown) coloured with options.height_colormap over
  /// [min_value, max_value] (or the robust percentile range), hill-shaded, with a legend in metres.
  /// `trajectory_xy_m` (ground x, y [m]) is drawn on top, its first point marked "start".
  static cv::Mat heightPicture(const cv::Mat& heights, const GroundGrid& grid,
                               const DemPictureOptions& options = DemPictureOptions(),
                               const std::vector<Eigen::Vector2d>& trajectory_xy_m = {},
                               DemPictureLayout* layout = nullptr);

  /// A 0..1 traversability layer: red (0, blocked) -> yellow -> green (1, free), unknown grey.
  static cv::Mat traversabilityPicture(const cv::Mat& traversability, const GroundGrid& grid,
                                       const DemPictureOptions& options = DemPictureOptions(),
                                       const std::vector<Eigen::Vector2d>& trajectory_xy_m = {},
                                       DemPictureLayout* layout = nullptr);

  /// The camera image (any type GreyConverter accepts: 8/16-bit grey, BGR or BGRA, float grey;
  /// 16-bit scaled by options.image_bit_depth) with `values` (CV_32F, same size; NaN or 0 = none)
  /// blended over it in options.overlay_colormap over [min_value, max_value] (NaN: robust range
  /// of the shown values), and a legend strip below titled `legend_title`.
  static cv::Mat overlayOnImage(const cv::Mat& image, const cv::Mat& values, double min_value,
                                double max_value, const std::string& legend_title,
                                const DemPictureOptions& options = DemPictureOptions());

  /// The [low_pct, high_pct] percentiles of the finite values of a CV_32F layer (ignoring zeros
  /// if zero_is_none); a degenerate range is widened to +-0.05. False if there is no such value.
  static bool robustRange(const cv::Mat& layer, double low_pct, double high_pct, double* lo, double* hi,
                          bool zero_is_none = false);
  /// The 256 colours of an OpenCV colour map as a 1 x 256 CV_8UC3 (BGR) row, low to high.
  static cv::Mat colourLut(int colormap);
  /// The red -> yellow -> green traversability colours as a 1 x 256 CV_8UC3 row.
  static cv::Mat traversabilityLut();
  /// cv::imwrite that throws std::runtime_error (path + reason) on failure.
  static void save(const std::string& path, const cv::Mat& picture);
};

}  // namespace stereo_ground_dem
