#pragma once
/// \file GeoTiff.hpp
/// DEM layers as GeoTIFF (through GDAL), readable by QGIS, gdalinfo, rasterio.
///
/// File layout (see GroundGrid.hpp for the grid conventions):
///  - one float32 band per layer, DEFLATE-compressed (floating-point predictor), NaN = nodata;
///  - raster row r is grid row r and raster column c is grid column c, so raster x is ground x
///    (forward) and raster y is ground y (left), growing with the row: a "south-up" raster whose
///    geotransform has a positive pixel height;
///  - cells are centred on the vertices: the cell of vertex (r, c) is the square of side
///    `resolution_m` centred on (x0 + c * res, y0 + r * res), so the geotransform is
///    {x0 - res/2, res, 0, y0 - res/2, 0, +res} (GDAL's corner-based convention, AREA_OR_POINT=Area);
///  - a local engineering CRS in metres (LOCAL_CS "stereo_ground_dem ground frame"), band
///    descriptions = layer names.
/// Every failure throws std::runtime_error with the path and the reason in one line.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"

namespace stereo_ground_dem {

class GeoTiff {
 public:
  /// Writes one layer (CV_32F, grid.rows x grid.cols, NaN unknown) as a single-band GeoTIFF.
  static void write(const std::string& path, const cv::Mat& layer, const GroundGrid& grid,
                    const std::string& name = "elevation");

  /// Writes several layers of the same grid as the bands of one GeoTIFF, band i described as
  /// names[i]. Every layer must be CV_32F of grid.rows x grid.cols.
  static void writeLayers(const std::string& path, const std::vector<std::string>& names,
                          const std::vector<cv::Mat>& layers, const GroundGrid& grid);

  /// Reads band 1 as CV_32F (nodata values become NaN). If `grid` is given, it receives the grid
  /// recovered from the geotransform (resolution, row0/col0, rows, cols); throws if the raster is
  /// not on a lattice of this library (rotated, non-square or north-up cells, origin off the
  /// lattice).
  static cv::Mat read(const std::string& path, GroundGrid* grid = nullptr);

  /// Reads every band; `names` (optional) receives the band descriptions.
  static std::vector<cv::Mat> readLayers(const std::string& path, GroundGrid* grid = nullptr,
                                         std::vector<std::string>* names = nullptr);
};

}  // namespace stereo_ground_dem
