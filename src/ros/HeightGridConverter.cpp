#include "stereo_ground_dem/ros/HeightGridConverter.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace stereo_ground_dem {

namespace {
// grid_map_ros' storage index labels (GridMapMsgHelpers.cpp: storageIndexNames).
const char* const kColumnIndex = "column_index";
const char* const kRowIndex = "row_index";

int wrap(int index, int size) {
  int r = index % size;
  return r < 0 ? r + size : r;
}
}  // namespace

HeightGrid HeightGridConverter::toMessage(const GroundGrid& grid, const std::vector<GridLayer>& layers,
                                          const std_msgs::Header& header) {
  const int nx = grid.cols;  // cells along x = grid_map's first index
  const int ny = grid.rows;  // cells along y = grid_map's second index
  const double res = grid.resolution_m;
  HeightGrid msg;
  msg.info.header = header;
  msg.info.resolution = res;
  msg.info.length_x = nx * res;
  msg.info.length_y = ny * res;
  msg.info.pose.position.x = grid.x0() + 0.5 * (nx - 1) * res;
  msg.info.pose.position.y = grid.y0() + 0.5 * (ny - 1) * res;
  msg.info.pose.position.z = 0.0;
  msg.info.pose.orientation.w = 1.0;
  msg.outer_start_index = 0;
  msg.inner_start_index = 0;
  for (const GridLayer& layer : layers) {
    if (layer.values.type() != CV_32F || layer.values.rows != ny || layer.values.cols != nx) {
      std::ostringstream os;
      os << "layer '" << layer.name << "' is " << layer.values.cols << "x" << layer.values.rows << " (type "
         << layer.values.type() << "), expected CV_32F " << nx << "x" << ny;
      throw std::invalid_argument(os.str());
    }
    if (layer.name == "elevation") msg.basic_layers.push_back(layer.name);
    msg.layers.push_back(layer.name);
    std_msgs::Float32MultiArray a;
    a.layout.dim.resize(2);
    a.layout.dim[0].label = kColumnIndex;
    a.layout.dim[0].size = static_cast<uint32_t>(ny);
    a.layout.dim[0].stride = static_cast<uint32_t>(nx * ny);
    a.layout.dim[1].label = kRowIndex;
    a.layout.dim[1].size = static_cast<uint32_t>(nx);
    a.layout.dim[1].stride = static_cast<uint32_t>(nx);
    a.layout.data_offset = 0;
    a.data.resize(static_cast<size_t>(nx) * static_cast<size_t>(ny));
    // Column j of the column-major matrix (cells along -x) is DEM row ny-1-j read backwards.
    for (int j = 0; j < ny; ++j) {
      const float* row = layer.values.ptr<float>(ny - 1 - j);
      std::reverse_copy(row, row + nx, a.data.begin() + static_cast<std::ptrdiff_t>(j) * nx);
    }
    msg.data.push_back(std::move(a));
  }
  return msg;
}

bool HeightGridConverter::fromMessage(const HeightGrid& m, GroundGrid* grid, std::vector<GridLayer>* layers,
                                      std::string* why) {
  auto fail = [why](const std::string& w) {
    if (why) *why = w;
    return false;
  };
  if (m.layers.size() != m.data.size()) return fail("different numbers of layer names and data arrays");
  const double res = m.info.resolution;
  if (!(res > 0.0)) return fail("resolution must be > 0");
  const auto& q = m.info.pose.orientation;
  if (std::abs(std::abs(q.w) - 1.0) > 1e-9) return fail("rotated grids are not supported (orientation not identity)");
  const int nx = static_cast<int>(std::lround(m.info.length_x / res));
  const int ny = static_cast<int>(std::lround(m.info.length_y / res));
  const double x0 = m.info.pose.position.x - 0.5 * m.info.length_x + 0.5 * res;
  const double y0 = m.info.pose.position.y - 0.5 * m.info.length_y + 0.5 * res;
  GroundGrid g;
  g.resolution_m = res;
  g.rows = ny;
  g.cols = nx;
  g.col0 = static_cast<int>(std::lround(x0 / res));
  g.row0 = static_cast<int>(std::lround(y0 / res));
  if (std::abs(g.col0 * res - x0) > 1e-3 * res || std::abs(g.row0 * res - y0) > 1e-3 * res) {
    return fail("grid cells are not centred on the lattice of its resolution");
  }
  std::vector<GridLayer> out;
  for (size_t k = 0; k < m.data.size(); ++k) {
    const std_msgs::Float32MultiArray& a = m.data[k];
    if (a.layout.dim.size() != 2) return fail("layer '" + m.layers[k] + "' is not two-dimensional");
    bool column_major;
    if (a.layout.dim[0].label == kColumnIndex) column_major = true;
    else if (a.layout.dim[0].label == kRowIndex) column_major = false;
    else return fail("layer '" + m.layers[k] + "' has an unknown layout label '" + a.layout.dim[0].label + "'");
    const int size_x = static_cast<int>(column_major ? a.layout.dim[1].size : a.layout.dim[0].size);
    const int size_y = static_cast<int>(column_major ? a.layout.dim[0].size : a.layout.dim[1].size);
    if (size_x != nx || size_y != ny) return fail("layer '" + m.layers[k] + "' size disagrees with length / resolution");
    if (a.data.size() < a.layout.data_offset + static_cast<size_t>(nx) * ny) {
      return fail("layer '" + m.layers[k] + "' has too few values");
    }
    cv::Mat values(ny, nx, CV_32F);
    for (int bi = 0; bi < nx; ++bi) {
      for (int bj = 0; bj < ny; ++bj) {
        const size_t at = a.layout.data_offset + (column_major ? static_cast<size_t>(bj) * nx + bi
                                                               : static_cast<size_t>(bi) * ny + bj);
        const int i = wrap(bi - m.outer_start_index, nx);  // unwrapped grid_map index
        const int j = wrap(bj - m.inner_start_index, ny);
        values.at<float>(ny - 1 - j, nx - 1 - i) = a.data[at];
      }
    }
    out.push_back({m.layers[k], values});
  }
  if (grid) *grid = g;
  if (layers) *layers = std::move(out);
  return true;
}

}  // namespace stereo_ground_dem
