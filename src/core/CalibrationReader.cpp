#include "stereo_ground_dem/CalibrationReader.hpp"

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace stereo_ground_dem {

namespace {

struct ParsedFile {
  std::map<std::string, std::vector<double>> keyed;  ///< "P0" -> numbers
  std::vector<std::vector<double>> unkeyed;          ///< lines without a key
};

[[noreturn]] void fail(const std::string& path, const std::string& why) {
  throw std::runtime_error("calibration file '" + path + "': " + why);
}

ParsedFile parse(const std::string& path) {
  std::ifstream in(path);
  if (!in) fail(path, "cannot be opened");
  ParsedFile out;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    std::string key;
    std::string rest = line;
    const auto colon = line.find(':');
    if (colon != std::string::npos) {
      key = line.substr(0, colon);
      key.erase(0, key.find_first_not_of(" \t"));
      key.erase(key.find_last_not_of(" \t") + 1);
      rest = line.substr(colon + 1);
    }
    std::istringstream ss(rest);
    std::vector<double> numbers;
    std::string token;
    bool numeric = true;
    while (ss >> token) {
      char* end = nullptr;
      const double v = std::strtod(token.c_str(), &end);
      if (end == token.c_str() || *end != '\0') {
        numeric = false;
        break;
      }
      numbers.push_back(v);
    }
    if (!numeric) {
      // Non-numeric values (e.g. "calib_time: 09-Jan-2012 13:57:47") are fine for other keys.
      if (key.empty()) fail(path, "line " + std::to_string(line_no) + " is not a list of numbers");
      continue;
    }
    if (key.empty()) {
      out.unkeyed.push_back(numbers);
    } else {
      out.keyed[key] = numbers;
    }
  }
  return out;
}

Eigen::Matrix<double, 3, 4> toProjection(const std::string& path, const std::string& name,
                                         const std::vector<double>& v) {
  if (v.size() != 12) {
    fail(path, name + " has " + std::to_string(v.size()) + " numbers, expected 12 (a 3x4 matrix)");
  }
  Eigen::Matrix<double, 3, 4> p;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) p(r, c) = v[static_cast<size_t>(r * 4 + c)];
  if (!p.allFinite()) fail(path, name + " contains a non-finite number");
  return p;
}

StereoRig makeRig(const std::string& path, const Eigen::Matrix<double, 3, 4>& pl,
                  const Eigen::Matrix<double, 3, 4>& pr, int w, int h) {
  try {
    return StereoRig::fromProjectionMatrices(pl, pr, w, h);
  } catch (const std::invalid_argument& e) {
    fail(path, e.what());
  }
}

}  // namespace

StereoRig CalibrationReader::readKittiOdometry(const std::string& path) {
  const ParsedFile f = parse(path);
  const auto has = [&f](const char* k) { return f.keyed.count(k) > 0; };
  if (has("P0") && has("P1")) {
    return makeRig(path, toProjection(path, "P0", f.keyed.at("P0")),
                   toProjection(path, "P1", f.keyed.at("P1")), 0, 0);
  }
  if (has("P2") && has("P3")) {
    return makeRig(path, toProjection(path, "P2", f.keyed.at("P2")),
                   toProjection(path, "P3", f.keyed.at("P3")), 0, 0);
  }
  if (f.unkeyed.size() >= 2) {
    return makeRig(path, toProjection(path, "line 1", f.unkeyed[0]),
                   toProjection(path, "line 2", f.unkeyed[1]), 0, 0);
  }
  fail(path,
       "no P0:/P1: (or P2:/P3:) entries and no two lines of 12 numbers; not a KITTI odometry "
       "calib.txt");
}

StereoRig CalibrationReader::readKittiRaw(const std::string& path, RawPair pair) {
  const ParsedFile f = parse(path);
  const std::string l = pair == RawPair::kGray ? "00" : "02";
  const std::string r = pair == RawPair::kGray ? "01" : "03";
  const std::string kl = "P_rect_" + l, kr = "P_rect_" + r;
  if (!f.keyed.count(kl) || !f.keyed.count(kr)) {
    fail(path, "missing " + kl + " or " + kr + "; not a KITTI raw calib_cam_to_cam.txt");
  }
  int w = 0, h = 0;
  const auto s = f.keyed.find("S_rect_" + l);
  if (s != f.keyed.end()) {
    if (s->second.size() != 2 || !(s->second[0] > 0) || !(s->second[1] > 0)) {
      fail(path, "S_rect_" + l + " must hold two positive numbers (width height)");
    }
    w = static_cast<int>(std::lround(s->second[0]));
    h = static_cast<int>(std::lround(s->second[1]));
  }
  return makeRig(path, toProjection(path, kl, f.keyed.at(kl)), toProjection(path, kr, f.keyed.at(kr)),
                 w, h);
}

StereoRig CalibrationReader::read(const std::string& path) {
  std::ifstream in(path);
  if (!in) fail(path, "cannot be opened");
  std::stringstream ss;
  ss << in.rdbuf();
  if (ss.str().find("P_rect_") != std::string::npos) return readKittiRaw(path, RawPair::kColor);
  return readKittiOdometry(path);
}

}  // namespace stereo_ground_dem
