#include "stereo_ground_dem/io/GeoTiff.hpp"

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <stdexcept>

namespace stereo_ground_dem {

namespace {

const char* const kCrsName = "stereo_ground_dem ground frame (x forward, y left, z up)";

void registerDrivers() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

/// Silences GDAL's printing to stderr for its lifetime (the last error is still recorded and
/// reported in our exceptions). GDAL's handler stack is per thread.
class QuietGdal {
 public:
  QuietGdal() {
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
  }
  ~QuietGdal() { CPLPopErrorHandler(); }
  QuietGdal(const QuietGdal&) = delete;
  QuietGdal& operator=(const QuietGdal&) = delete;
};

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  std::string msg = "GeoTiff: " + path + ": " + what;
  const char* gdal = CPLGetLastErrorMsg();
  if (gdal != nullptr && gdal[0] != '\0') msg += " (GDAL: " + std::string(gdal) + ")";
  for (char& ch : msg) {
    if (ch == '\n' || ch == '\r') ch = ' ';
  }
  throw std::runtime_error(msg);
}

struct DatasetCloser {
  void operator()(GDALDataset* ds) const { GDALClose(GDALDataset::ToHandle(ds)); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

bool nearInteger(double v, double* rounded) {
  *rounded = std::round(v);
  return std::abs(v - *rounded) <= 1e-6;
}

GroundGrid gridFromGeoTransform(const std::string& path, const double gt[6], int rows, int cols) {
  const double res = gt[1];
  if (!(res > 0.0) || !std::isfinite(res)) fail(path, "geotransform has a non-positive pixel width");
  if (gt[2] != 0.0 || gt[4] != 0.0) fail(path, "geotransform is rotated, not a ground grid");
  if (std::abs(gt[5] - res) > 1e-9 * res) {
    fail(path, gt[5] < 0.0 ? "raster is north-up (negative pixel height), expected the south-up "
                             "layout of stereo_ground_dem (row index along +y)"
                           : "cells are not square");
  }
  double col0 = 0.0, row0 = 0.0;
  if (!nearInteger(gt[0] / res + 0.5, &col0) || !nearInteger(gt[3] / res + 0.5, &row0)) {
    fail(path,
         "raster origin is not on the lattice of its resolution (vertex-centred cells "
         "expected: origin = (col0 - 1/2, row0 - 1/2) * resolution)");
  }
  if (std::abs(col0) > std::numeric_limits<int>::max() / 2 ||
      std::abs(row0) > std::numeric_limits<int>::max() / 2) {
    fail(path, "raster origin is out of range");
  }
  GroundGrid g;
  g.resolution_m = res;
  g.col0 = static_cast<int>(col0);
  g.row0 = static_cast<int>(row0);
  g.rows = rows;
  g.cols = cols;
  return g;
}

}  // namespace

void GeoTiff::write(const std::string& path, const cv::Mat& layer, const GroundGrid& grid,
                    const std::string& name) {
  writeLayers(path, {name}, {layer}, grid);
}

void GeoTiff::writeLayers(const std::string& path, const std::vector<std::string>& names,
                          const std::vector<cv::Mat>& layers, const GroundGrid& grid) {
  registerDrivers();
  QuietGdal quiet;
  if (layers.empty()) fail(path, "no layer to write");
  if (names.size() != layers.size()) fail(path, "number of names differs from number of layers");
  if (grid.rows <= 0 || grid.cols <= 0 || !(grid.resolution_m > 0.0)) fail(path, "empty or invalid grid");
  for (size_t i = 0; i < layers.size(); ++i) {
    const cv::Mat& l = layers[i];
    if (l.type() != CV_32FC1 || l.rows != grid.rows || l.cols != grid.cols) {
      fail(path, "layer '" + names[i] + "' is not CV_32F of " + std::to_string(grid.rows) + " x " +
                     std::to_string(grid.cols) + " (grid rows x cols)");
    }
  }
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (driver == nullptr) fail(path, "GDAL has no GTiff driver");

  CPLStringList options;
  options.SetNameValue("COMPRESS", "DEFLATE");
  options.SetNameValue("PREDICTOR", "3");  // floating-point predictor
  options.SetNameValue("BIGTIFF", "IF_SAFER");
  options.SetNameValue("INTERLEAVE", "BAND");
  // Create() on an existing file first deletes that dataset with every file GDAL counts as its
  // sidecar, and GDAL's satellite metadata readers count a plain summary.txt in the same folder
  // (ALOS). dem_offline writes one there, so a run into a used folder lost it: remove only the
  // file itself.
  VSIStatBufL st;
  if (VSIStatL(path.c_str(), &st) == 0 && VSIUnlink(path.c_str()) != 0) fail(path, "cannot replace the existing file");
  DatasetPtr ds(driver->Create(path.c_str(), grid.cols, grid.rows, static_cast<int>(layers.size()),
                               GDT_Float32, options.List()));
  if (!ds) fail(path, "cannot create the file");

  bool ok = true;
  const double res = grid.resolution_m;
  double gt[6] = {grid.x0() - 0.5 * res, res, 0.0, grid.y0() - 0.5 * res, 0.0, res};
  ok = ok && ds->SetGeoTransform(gt) == CE_None;
  OGRSpatialReference srs;
  srs.SetLocalCS(kCrsName);
  srs.SetLinearUnits(SRS_UL_METER, 1.0);
  ok = ok && ds->SetSpatialRef(&srs) == CE_None;
  ds->SetMetadataItem("TIFFTAG_SOFTWARE", "stereo_ground_dem");
  ds->SetMetadataItem("SGD_CONVENTIONS",
                      "vertex (r,c) at x = x0 + c*resolution, y = y0 + r*resolution; raster row = "
                      "grid row (south-up); cells centred on vertices; ground frame x forward, y "
                      "left, z up; metres; NaN unknown");
  for (size_t i = 0; ok && i < layers.size(); ++i) {
    GDALRasterBand* band = ds->GetRasterBand(static_cast<int>(i) + 1);
    band->SetDescription(names[i].c_str());
    ok = ok && band->SetNoDataValue(std::numeric_limits<double>::quiet_NaN()) == CE_None;
    cv::Mat& l = const_cast<cv::Mat&>(layers[i]);  // RasterIO takes void*; GF_Write only reads it
    ok = ok && band->RasterIO(GF_Write, 0, 0, grid.cols, grid.rows, l.data, grid.cols, grid.rows, GDT_Float32,
                              0, static_cast<GSpacing>(l.step[0]), nullptr) == CE_None;
  }
  if (ok) {
    CPLErrorReset();
    ds.reset();  // flushes and compresses: errors surface here
    ok = CPLGetLastErrorType() < CE_Failure;
  }
  if (!ok) {
    ds.reset();
    const std::string reason = CPLGetLastErrorMsg();
    VSIUnlink(path.c_str());
    throw std::runtime_error("GeoTiff: " + path + ": writing failed (GDAL: " + reason + ")");
  }
}

cv::Mat GeoTiff::read(const std::string& path, GroundGrid* grid) {
  std::vector<cv::Mat> layers = readLayers(path, grid, nullptr);
  return layers.front();
}

std::vector<cv::Mat> GeoTiff::readLayers(const std::string& path, GroundGrid* grid,
                                         std::vector<std::string>* names) {
  registerDrivers();
  QuietGdal quiet;
  VSIStatBufL st;
  if (VSIStatL(path.c_str(), &st) != 0) fail(path, "no such file");
  const char* const allowed[] = {"GTiff", nullptr};
  DatasetPtr ds(GDALDataset::FromHandle(
      GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, allowed, nullptr, nullptr)));
  if (!ds) fail(path, "not a readable GeoTIFF");
  const int rows = ds->GetRasterYSize();
  const int cols = ds->GetRasterXSize();
  const int bands = ds->GetRasterCount();
  if (rows <= 0 || cols <= 0 || bands <= 0) fail(path, "raster is empty");
  if (grid != nullptr) {
    double gt[6];
    if (ds->GetGeoTransform(gt) != CE_None) fail(path, "raster has no geotransform");
    *grid = gridFromGeoTransform(path, gt, rows, cols);
  }
  std::vector<cv::Mat> layers;
  if (names != nullptr) names->clear();
  for (int b = 1; b <= bands; ++b) {
    GDALRasterBand* band = ds->GetRasterBand(b);
    cv::Mat layer(rows, cols, CV_32FC1);
    if (band->RasterIO(GF_Read, 0, 0, cols, rows, layer.data, cols, rows, GDT_Float32, 0,
                       static_cast<GSpacing>(layer.step[0]), nullptr) != CE_None) {
      fail(path, "cannot read band " + std::to_string(b));
    }
    int has_nodata = 0;
    const double nodata = band->GetNoDataValue(&has_nodata);
    if (has_nodata != 0 && !std::isnan(nodata)) {
      const float nd = static_cast<float>(nodata);
      const float nan = std::numeric_limits<float>::quiet_NaN();
      layer.forEach<float>([nd, nan](float& v, const int*) {
        if (v == nd) v = nan;
      });
    }
    layers.push_back(layer);
    if (names != nullptr) names->emplace_back(band->GetDescription());
  }
  return layers;
}

}  // namespace stereo_ground_dem
