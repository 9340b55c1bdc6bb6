#include "stereo_ground_dem/CalibrationReader.hpp"

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace stereo_ground_dem {

namespace {

struct Line {
  std::vector<double> numbers;
  int line_no = 0;
};

struct ParsedFile {
  std::map<std::string, Line> keyed;  ///< "P0" -> numbers
  std::vector<Line> unkeyed;          ///< lines of numbers without a key
};

[[noreturn]] void fail(const std::string& path, const std::string& why) {
  throw std::runtime_error("calibration file '" + path + "': " + why);
}

/// Keys this reader uses: their values must be numbers and appear once.
bool usedKey(const std::string& key) {
  return key == "P0" || key == "P1" || key == "P2" || key == "P3" || key.rfind("P_rect_", 0) == 0 ||
         key.rfind("S_rect_", 0) == 0;
}

/// Printable, short form of a token for an error message.
std::string shown(const std::string& token) {
  std::string s;
  for (char c : token.substr(0, 24)) s += (c >= 32 && c < 127) ? c : '?';
  return token.size() > 24 ? s + "..." : s;
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
    Line parsed;
    parsed.line_no = line_no;
    std::string token, bad_token;
    while (ss >> token) {
      char* end = nullptr;
      const double v = std::strtod(token.c_str(), &end);
      if (end == token.c_str() || *end != '\0') {
        bad_token = token;
        break;
      }
      parsed.numbers.push_back(v);
    }
    const std::string where = "line " + std::to_string(line_no);
    if (!bad_token.empty()) {
      // Non-numeric values (e.g. "calib_time: 09-Jan-2012 13:57:47") are fine for other keys.
      if (key.empty()) fail(path, where + " is not a list of numbers ('" + shown(bad_token) + "')");
      if (usedKey(key)) fail(path, shown(key) + " on " + where + " holds '" + shown(bad_token) + "', not a number");
      continue;
    }
    if (key.empty()) {
      out.unkeyed.push_back(parsed);
      continue;
    }
    const auto previous = out.keyed.find(key);
    if (previous != out.keyed.end() && usedKey(key)) {
      fail(path, shown(key) + " appears twice (lines " + std::to_string(previous->second.line_no) + " and " +
                     std::to_string(line_no) + ")");
    }
    out.keyed[key] = parsed;
  }
  return out;
}

Eigen::Matrix<double, 3, 4> toProjection(const std::string& path, const std::string& name, const Line& l) {
  const std::vector<double>& v = l.numbers;
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

struct PairKeys {
  std::string left, right, size;  ///< size: S_rect key or ""
};

/// The keys of `pair` present in the file (odometry names first); empty left when absent. A pair
/// with only one of its two matrices is an error.
PairKeys findPair(const std::string& path, const ParsedFile& f, CalibrationReader::CameraPair pair) {
  const bool gray = pair == CalibrationReader::CameraPair::kGray;
  const PairKeys candidates[2] = {
      gray ? PairKeys{"P0", "P1", ""} : PairKeys{"P2", "P3", ""},
      gray ? PairKeys{"P_rect_00", "P_rect_01", "S_rect_00"} : PairKeys{"P_rect_02", "P_rect_03", "S_rect_02"}};
  for (const PairKeys& k : candidates) {
    const bool l = f.keyed.count(k.left) > 0, r = f.keyed.count(k.right) > 0;
    if (l && r) return k;
    if (l != r) fail(path, "has " + (l ? k.left : k.right) + " but no " + (l ? k.right : k.left));
  }
  return {};
}

StereoRig readPair(const std::string& path, const ParsedFile& f, const PairKeys& k) {
  int w = 0, h = 0;
  if (!k.size.empty()) {
    const auto s = f.keyed.find(k.size);
    if (s != f.keyed.end()) {
      const std::vector<double>& v = s->second.numbers;
      const auto sideOk = [](double x) { return x >= 1.0 && x <= 100000.0 && x == std::floor(x); };
      if (v.size() != 2 || !sideOk(v[0]) || !sideOk(v[1])) {
        fail(path, k.size + " must hold two whole numbers 1..100000 (width height)");
      }
      w = static_cast<int>(v[0]);
      h = static_cast<int>(v[1]);
    }
  }
  return makeRig(path, toProjection(path, k.left, f.keyed.at(k.left)), toProjection(path, k.right, f.keyed.at(k.right)),
                 w, h);
}

StereoRig readUnkeyed(const std::string& path, const ParsedFile& f) {
  return makeRig(path, toProjection(path, "line " + std::to_string(f.unkeyed[0].line_no), f.unkeyed[0]),
                 toProjection(path, "line " + std::to_string(f.unkeyed[1].line_no), f.unkeyed[1]), 0, 0);
}

}  // namespace

const char* CalibrationReader::name(CameraPair pair) {
  switch (pair) {
    case CameraPair::kAuto: return "auto";
    case CameraPair::kGray: return "0,1";
    case CameraPair::kColor: return "2,3";
  }
  return "?";
}

CalibrationReader::Contents CalibrationReader::inspect(const std::string& path) {
  const ParsedFile f = parse(path);
  Contents c;
  c.gray = !findPair(path, f, CameraPair::kGray).left.empty();
  c.color = !findPair(path, f, CameraPair::kColor).left.empty();
  c.unkeyed = f.unkeyed.size() >= 2;
  return c;
}

StereoRig CalibrationReader::read(const std::string& path, CameraPair pair) {
  const ParsedFile f = parse(path);
  const PairKeys gray = findPair(path, f, CameraPair::kGray);
  const PairKeys color = findPair(path, f, CameraPair::kColor);
  const bool unkeyed = f.unkeyed.size() >= 2;
  switch (pair) {
    case CameraPair::kAuto:
      if (!gray.left.empty()) return readPair(path, f, gray);
      if (!color.left.empty()) return readPair(path, f, color);
      if (unkeyed) return readUnkeyed(path, f);
      fail(path,
           "no P0:/P1: or P2:/P3: (KITTI odometry), no P_rect_00/01 or P_rect_02/03 (KITTI raw) and no two "
           "lines of 12 numbers");
    case CameraPair::kGray:
      if (!gray.left.empty()) return readPair(path, f, gray);
      if (unkeyed && color.left.empty()) return readUnkeyed(path, f);
      fail(path, "no P0:/P1: or P_rect_00/P_rect_01 entries for cameras 0,1");
    case CameraPair::kColor:
      if (!color.left.empty()) return readPair(path, f, color);
      fail(path, "no P2:/P3: or P_rect_02/P_rect_03 entries for cameras 2,3");
  }
  fail(path, "unknown camera pair");
}

StereoRig CalibrationReader::readKittiOdometry(const std::string& path) {
  const ParsedFile f = parse(path);
  const auto has = [&f](const char* k) { return f.keyed.count(k) > 0; };
  if (has("P0") && has("P1")) return readPair(path, f, {"P0", "P1", ""});
  if (has("P2") && has("P3")) return readPair(path, f, {"P2", "P3", ""});
  if (f.unkeyed.size() >= 2) return readUnkeyed(path, f);
  fail(path,
       "no P0:/P1: (or P2:/P3:) entries and no two lines of 12 numbers; not a KITTI odometry "
       "calib.txt");
}

StereoRig CalibrationReader::readKittiRaw(const std::string& path, CameraPair pair) {
  const ParsedFile f = parse(path);
  const bool color = pair == CameraPair::kColor;
  const PairKeys k = color ? PairKeys{"P_rect_02", "P_rect_03", "S_rect_02"} : PairKeys{"P_rect_00", "P_rect_01", "S_rect_00"};
  if (!f.keyed.count(k.left) || !f.keyed.count(k.right)) {
    fail(path, "missing " + k.left + " or " + k.right + "; not a KITTI raw calib_cam_to_cam.txt");
  }
  return readPair(path, f, k);
}

}  // namespace stereo_ground_dem
