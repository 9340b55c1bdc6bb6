#include "stereo_ground_dem/io/DemExporter.hpp"

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <sys/stat.h>

#include <opencv2/core.hpp>

#include "stereo_ground_dem/io/DemMetadata.hpp"
#include "stereo_ground_dem/io/DemPicture.hpp"
#include "stereo_ground_dem/io/GeoTiff.hpp"
#include "stereo_ground_dem/io/PlyWriter.hpp"

namespace stereo_ground_dem {

void DemExporter::makeDirectories(const std::string& directory) {
  std::string path;
  size_t pos = 0;
  while (pos != std::string::npos) {
    pos = directory.find('/', pos + 1);
    path = directory.substr(0, pos);
    if (path.empty()) continue;
    if (mkdir(path.c_str(), 0755) != 0 && errno != EEXIST) {
      throw std::runtime_error("cannot create directory '" + path + "': " + std::strerror(errno));
    }
  }
  struct stat st {};
  if (stat(directory.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    throw std::runtime_error("'" + directory + "' is not a directory");
  }
}

std::vector<std::string> DemExporter::write(const std::string& dir, const DemExport& dem, bool pictures) {
  makeDirectories(dir);
  std::vector<std::string> written;
  std::vector<std::string> layers{"elevation"};
  GeoTiff::write(dir + "/dem.tif", dem.elevation, dem.grid, "elevation");
  written.push_back("dem.tif");
  // Companion rasters on the DEM's grid, each written when given and named in dem.yaml as
  // <stem>_file: (file, layer, band name).
  struct Companion {
    const char* file;
    const cv::Mat* layer;
    const char* band;
  };
  const Companion companions[] = {{"variance.tif", &dem.variance, "variance"},
                                  {"traversability.tif", &dem.traversability, "traversability"},
                                  {"traversability_confidence.tif", &dem.traversability_confidence,
                                   "traversability_confidence"},
                                  {"obstacles.tif", &dem.obstacles, "obstacle"},
                                  {"obstacle_height.tif", &dem.obstacle_height, "obstacle_height"},
                                  {"intensity.tif", &dem.intensity, "intensity"},
                                  {"residual.tif", &dem.residual, "residual"},
                                  {"residual_outlier_rate.tif", &dem.residual_outlier_rate, "residual_outlier_rate"}};
  for (const Companion& c : companions) {
    if (c.layer->empty()) continue;
    GeoTiff::write(dir + "/" + c.file, *c.layer, dem.grid, c.band);
    written.push_back(c.file);
  }
  if (!dem.ortho.empty()) {
    GeoTiff::write(dir + "/ortho.tif", dem.ortho, dem.ortho_grid, "intensity");
    written.push_back("ortho.tif");
  }
  DemMetadata meta = DemMetadata::fromGrid(dem.grid, dem.ground_T_camera0, layers);
  for (const auto& kv : dem.extra) meta.extra_strings[kv.first] = kv.second;
  for (const Companion& c : companions) {
    if (c.layer->empty()) continue;
    const std::string f = c.file;
    meta.extra_strings[f.substr(0, f.find('.')) + "_file"] = f;
  }
  if (!dem.ortho.empty()) {
    meta.extra_strings["ortho_file"] = "ortho.tif";
    meta.extra_numbers["ortho_resolution"] = dem.ortho_grid.resolution_m;
  }
  meta.write(dir + "/dem.yaml");
  written.push_back("dem.yaml");
  if (!pictures) return written;
  DemPictureOptions po;
  po.title = "DEM heights [m]";
  DemPicture::save(dir + "/dem_height.png", DemPicture::heightPicture(dem.elevation, dem.grid, po, dem.trajectory_xy));
  written.push_back("dem_height.png");
  if (!dem.traversability.empty()) {
    DemPictureOptions to;
    to.title = "Traversability (0 lethal .. 1 free)";
    DemPicture::save(dir + "/traversability.png",
                     DemPicture::traversabilityPicture(dem.traversability, dem.grid, to, dem.trajectory_xy));
    written.push_back("traversability.png");
  }
  if (!dem.ortho.empty()) {
    DemPicture::save(dir + "/ortho.png", orthoPicture(dem.ortho));
    written.push_back("ortho.png");
  }
  PlyWriter::writeMesh(dir + "/mesh.ply", dem.grid, dem.elevation);
  written.push_back("mesh.ply");
  return written;
}

cv::Mat DemExporter::orthoPicture(const cv::Mat& ortho) {
  // Raster (r, c) = (y, x); the picture's pixel (col, row) = (rows-1-r, cols-1-c): +x up, +y left.
  cv::Mat t;
  cv::transpose(ortho, t);
  cv::flip(t, t, -1);
  cv::Mat out(t.size(), CV_8UC4, cv::Scalar(0, 0, 0, 0));
  for (int r = 0; r < t.rows; ++r) {
    const float* in = t.ptr<float>(r);
    cv::Vec4b* o = out.ptr<cv::Vec4b>(r);
    for (int c = 0; c < t.cols; ++c) {
      if (!std::isfinite(in[c])) continue;
      const auto g = static_cast<uchar>(std::clamp(std::lround(in[c]), 0L, 255L));
      o[c] = cv::Vec4b(g, g, g, 255);
    }
  }
  return out;
}

}  // namespace stereo_ground_dem
