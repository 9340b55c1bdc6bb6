#include "stereo_ground_dem/io/DemMetadata.hpp"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <opencv2/core.hpp>
#include <set>
#include <sstream>
#include <stdexcept>

#include "stereo_ground_dem/io/NumberText.hpp"

namespace stereo_ground_dem {

const char* const DemMetadata::kConventions =
    "vertex (r,c) at x = x0 + c*resolution, y = y0 + r*resolution; ground frame x forward, y left, "
    "z up; heights in metres, NaN unknown";

namespace {

const std::set<std::string>& reservedKeys() {
  static const std::set<std::string> keys = {"resolution",       "origin", "rows",       "cols",
                                             "ground_T_camera0", "layers", "conventions"};
  return keys;
}

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  std::string msg = "DemMetadata: " + path + ": " + what;
  for (char& ch : msg) {
    if (ch == '\n' || ch == '\r') ch = ' ';
  }
  throw std::runtime_error(msg);
}

bool isValidKey(const std::string& key) {
  if (key.empty()) return false;
  const auto alpha = [](char ch) { return std::isalpha(static_cast<unsigned char>(ch)) != 0; };
  const auto digit = [](char ch) { return std::isdigit(static_cast<unsigned char>(ch)) != 0; };
  if (!alpha(key[0]) && key[0] != '_') return false;
  for (char ch : key) {
    if (!alpha(ch) && !digit(ch) && ch != '_' && ch != '-' && ch != '.') return false;
  }
  return true;
}

/// A YAML double-quoted scalar.
std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (char ch : s) {
    const auto u = static_cast<unsigned char>(ch);
    switch (ch) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (u < 0x20 || u == 0x7f) {
          char buf[8];
          std::snprintf(buf, sizeof(buf), "\\x%02x", u);
          out += buf;
        } else {
          out += ch;
        }
    }
  }
  return out + "\"";
}

double number(const std::string& path, const cv::FileNode& n, const std::string& what) {
  if (!n.isInt() && !n.isReal()) fail(path, "'" + what + "' is missing or not a number");
  return static_cast<double>(n);
}

int integer(const std::string& path, const cv::FileNode& n, const std::string& what) {
  if (!n.isInt()) fail(path, "'" + what + "' is missing or not an integer");
  return static_cast<int>(n);
}

std::vector<double> numbers(const std::string& path, const cv::FileNode& n, const std::string& what,
                            size_t count) {
  if (!n.isSeq() || n.size() != count) {
    fail(path, "'" + what + "' is missing or not a list of " + std::to_string(count) + " numbers");
  }
  std::vector<double> v;
  for (size_t i = 0; i < count; ++i) v.push_back(number(path, n[static_cast<int>(i)], what));
  return v;
}

}  // namespace

DemMetadata DemMetadata::fromGrid(const GroundGrid& grid, const Eigen::Isometry3d& ground_T_camera0,
                                  const std::vector<std::string>& layers) {
  DemMetadata m;
  m.resolution_m = grid.resolution_m;
  m.origin_x_m = grid.x0();
  m.origin_y_m = grid.y0();
  m.rows = grid.rows;
  m.cols = grid.cols;
  m.ground_T_camera0 = ground_T_camera0;
  m.layers = layers;
  return m;
}

GroundGrid DemMetadata::grid() const {
  if (!(resolution_m > 0.0)) throw std::runtime_error("DemMetadata::grid: resolution is not positive");
  const double c0 = origin_x_m / resolution_m;
  const double r0 = origin_y_m / resolution_m;
  if (std::abs(c0 - std::round(c0)) > 1e-6 || std::abs(r0 - std::round(r0)) > 1e-6) {
    throw std::runtime_error("DemMetadata::grid: origin is not on the lattice of the resolution");
  }
  GroundGrid g;
  g.resolution_m = resolution_m;
  g.col0 = static_cast<int>(std::lround(c0));
  g.row0 = static_cast<int>(std::lround(r0));
  g.rows = rows;
  g.cols = cols;
  return g;
}

void DemMetadata::write(const std::string& path) const {
  for (const auto& kv : extra_strings) {
    if (!isValidKey(kv.first) || reservedKeys().count(kv.first) != 0) {
      fail(path, "invalid or reserved extra key '" + kv.first + "'");
    }
  }
  for (const auto& kv : extra_numbers) {
    if (!isValidKey(kv.first) || reservedKeys().count(kv.first) != 0 || extra_strings.count(kv.first) != 0) {
      fail(path, "invalid, reserved or duplicate extra key '" + kv.first + "'");
    }
  }
  std::ostringstream os;
  os << "# stereo_ground_dem DEM metadata\n";
  os << "resolution: " << NumberText::yaml(resolution_m) << "  # vertex spacing [m]\n";
  os << "origin: [" << NumberText::yaml(origin_x_m) << ", " << NumberText::yaml(origin_y_m)
     << "]  # ground (x, y) of vertex (row 0, col 0) [m]\n";
  os << "rows: " << rows << "  # vertices along y\n";
  os << "cols: " << cols << "  # vertices along x\n";
  os << "# pose of the first left camera's optical frame in the ground frame, 4x4 row-major\n";
  const Eigen::Matrix4d t = ground_T_camera0.matrix();
  os << "ground_T_camera0: [";
  for (int r = 0; r < 4; ++r) {
    if (r > 0) os << ",\n                   ";
    for (int c = 0; c < 4; ++c) os << (c > 0 ? ", " : "") << NumberText::yaml(t(r, c));
  }
  os << "]\n";
  os << "layers: [";
  for (size_t i = 0; i < layers.size(); ++i) os << (i > 0 ? ", " : "") << quoted(layers[i]);
  os << "]\n";
  os << "conventions: " << quoted(conventions) << "\n";
  for (const auto& kv : extra_strings) os << kv.first << ": " << quoted(kv.second) << "\n";
  for (const auto& kv : extra_numbers) os << kv.first << ": " << NumberText::yaml(kv.second) << "\n";

  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) fail(path, "cannot open for writing");
  f << os.str();
  f.flush();
  if (!f) fail(path, "write error");
}

DemMetadata DemMetadata::read(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) fail(path, "cannot open (no such file or not readable)");
  std::ostringstream raw;
  raw << f.rdbuf();
  // OpenCV's YAML parser insists on its own "%YAML:1.0" first line, which plain YAML parsers
  // reject: drop any directive / document marker and give OpenCV the header it wants.
  std::istringstream lines(raw.str());
  std::string text = "%YAML:1.0\n", line;
  bool body = false;
  while (std::getline(lines, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!body && (line.rfind("%", 0) == 0 || line == "---")) continue;
    if (!line.empty() && line[0] != '#') body = true;
    text += line + "\n";
  }
  DemMetadata m;
  try {
    cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
    const cv::FileNode root = fs.root();
    if (!root.isMap()) fail(path, "not a YAML mapping");
    m.resolution_m = number(path, root["resolution"], "resolution");
    const std::vector<double> origin = numbers(path, root["origin"], "origin", 2);
    m.origin_x_m = origin[0];
    m.origin_y_m = origin[1];
    m.rows = integer(path, root["rows"], "rows");
    m.cols = integer(path, root["cols"], "cols");
    const std::vector<double> t = numbers(path, root["ground_T_camera0"], "ground_T_camera0", 16);
    Eigen::Matrix4d mat;
    for (int i = 0; i < 16; ++i) mat(i / 4, i % 4) = t[static_cast<size_t>(i)];
    m.ground_T_camera0.matrix() = mat;
    const cv::FileNode layers = root["layers"];
    if (!layers.isNone()) {
      if (!layers.isSeq()) fail(path, "'layers' is not a list");
      for (const cv::FileNode& n : layers) {
        if (!n.isString()) fail(path, "'layers' holds a non-string entry");
        m.layers.push_back(static_cast<std::string>(n));
      }
    }
    const cv::FileNode conv = root["conventions"];
    m.conventions = conv.isString() ? static_cast<std::string>(conv) : std::string();
    for (const cv::FileNode& n : root) {
      const std::string key = n.name();
      if (reservedKeys().count(key) != 0) continue;
      if (n.isInt() || n.isReal()) {
        m.extra_numbers[key] = static_cast<double>(n);
      } else if (n.isString()) {
        m.extra_strings[key] = static_cast<std::string>(n);
      }  // nested entries written by other tools are ignored
    }
  } catch (const cv::Exception& e) {
    fail(path, "not valid YAML: " + e.err);
  }
  if (!(m.resolution_m > 0.0) || m.rows < 0 || m.cols < 0) fail(path, "invalid resolution or size");
  return m;
}

}  // namespace stereo_ground_dem
