#include "stereo_ground_dem/io/KittiSequence.hpp"

#include <algorithm>
#include <cmath>
#include <dirent.h>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <sys/stat.h>

#include "stereo_ground_dem/io/ImageFileReader.hpp"
#include "stereo_ground_dem/io/TrajectoryWriter.hpp"

namespace stereo_ground_dem {

namespace {

using CameraPair = CalibrationReader::CameraPair;

bool isDir(const std::string& p) {
  struct stat st {};
  return stat(p.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}
bool isFile(const std::string& p) {
  struct stat st {};
  return stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}
std::vector<std::string> imagesIn(const std::string& dir) {
  std::vector<std::string> names;
  DIR* d = opendir(dir.c_str());
  if (!d) return names;
  while (dirent* e = readdir(d)) {
    std::string n = e->d_name;
    const auto dot = n.rfind('.');
    if (dot == std::string::npos) continue;
    std::string ext = n.substr(dot + 1);
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    if (ext == "png" || ext == "jpg" || ext == "jpeg" || ext == "pgm" || ext == "ppm" || ext == "tif" || ext == "tiff") {
      names.push_back(n);
    }
  }
  closedir(d);
  std::sort(names.begin(), names.end());
  return names;
}

struct Layout {
  CameraPair pair;  ///< kAuto: the unnamed image_l/image_r pair
  const char* label;
  std::vector<std::pair<std::string, std::string>> folders;  ///< candidates, first existing wins
};

const Layout kLayouts[] = {
    {CameraPair::kGray, "image_0/image_1", {{"image_0", "image_1"}, {"image_00/data", "image_01/data"}, {"image_00", "image_01"}}},
    {CameraPair::kColor, "image_2/image_3", {{"image_2", "image_3"}, {"image_02/data", "image_03/data"}, {"image_02", "image_03"}}},
    {CameraPair::kAuto, "image_l/image_r", {{"image_l", "image_r"}}},
};

/// The first existing folder pair of `l` under dir, or empty strings.
std::pair<std::string, std::string> findFolders(const std::string& dir, const Layout& l) {
  for (const auto& f : l.folders) {
    if (isDir(dir + "/" + f.first) && isDir(dir + "/" + f.second)) return {dir + "/" + f.first, dir + "/" + f.second};
  }
  return {};
}

/// Whether the calibration can serve the layout's cameras, and with which pair to read it.
bool calibrationFits(const CalibrationReader::Contents& c, const Layout& l, CameraPair* read_as) {
  switch (l.pair) {
    case CameraPair::kGray:
      *read_as = c.gray ? CameraPair::kGray : CameraPair::kAuto;
      return c.gray || (c.unkeyed && !c.color);
    case CameraPair::kColor:
      *read_as = c.color ? CameraPair::kColor : CameraPair::kAuto;
      return c.color || (c.unkeyed && !c.gray);
    case CameraPair::kAuto: *read_as = CameraPair::kAuto; return true;
  }
  return false;
}

}  // namespace

KittiSequence KittiSequence::open(const std::string& dir, const KittiSequenceOptions& options) {
  KittiSequence s;
  s.dir_ = dir;
  auto fail = [&dir](const std::string& why) { throw std::runtime_error("sequence '" + dir + "': " + why); };
  if (!isDir(dir)) fail("is not a directory");
  if (isFile(dir + "/calib.txt")) s.calib_path_ = dir + "/calib.txt";
  else if (isFile(dir + "/calib_cam_to_cam.txt")) s.calib_path_ = dir + "/calib_cam_to_cam.txt";
  else fail("has no calib.txt or calib_cam_to_cam.txt");
  const CalibrationReader::Contents contents = CalibrationReader::inspect(s.calib_path_);

  // ---- camera pair and folders
  const Layout* chosen = nullptr;
  CameraPair read_as = CameraPair::kAuto;
  std::pair<std::string, std::string> folders;
  if (options.cameras != CameraPair::kAuto) {
    for (const Layout& l : kLayouts) {
      if (l.pair != options.cameras) continue;
      folders = findFolders(dir, l);
      if (folders.first.empty()) {
        fail(std::string("has no ") + l.label + " folders (or KITTI raw's image_0X/data) for cameras " +
             CalibrationReader::name(options.cameras));
      }
      chosen = &l;
      if (!calibrationFits(contents, l, &read_as)) read_as = options.cameras;  // the reader names what is missing
    }
  } else {
    std::string found;
    for (const Layout& l : kLayouts) {
      const auto f = findFolders(dir, l);
      if (f.first.empty()) continue;
      found += (found.empty() ? "" : ", ") + std::string(l.label);
      if (!calibrationFits(contents, l, &read_as)) continue;
      chosen = &l;
      folders = f;
      break;
    }
    if (!chosen) {
      if (found.empty()) fail("has no image_0/image_1, image_2/image_3 or image_l/image_r folders");
      fail(s.calib_path_ + " has no calibration for the cameras of the image folders found (" + found + ")");
    }
  }
  s.cameras_ = chosen->pair;
  s.left_dir_ = folders.first;
  s.right_dir_ = folders.second;
  s.rig_ = CalibrationReader::read(s.calib_path_, read_as);
  const std::string rectification = s.rig_.rectificationWarning();
  if (!rectification.empty()) s.warnings_.push_back(rectification);

  // ---- frames
  const std::vector<std::string> ln = imagesIn(s.left_dir_), rn = imagesIn(s.right_dir_);
  if (ln.empty()) fail("no images in " + s.left_dir_);
  int missing = 0;
  std::string first_missing;
  for (const auto& n : ln) {
    if (!std::binary_search(rn.begin(), rn.end(), n)) {
      if (missing++ == 0) first_missing = s.right_dir_ + "/" + n;
    }
    s.left_.push_back(s.left_dir_ + "/" + n);
    s.right_.push_back(s.right_dir_ + "/" + n);
  }
  if (missing == static_cast<int>(ln.size())) {
    fail("no image of " + s.left_dir_ + " has a right image of the same name in " + s.right_dir_);
  }
  if (missing > 0) {
    s.warnings_.push_back(std::to_string(missing) + " right image(s) missing (first " + first_missing +
                          "): those frames will be skipped");
  }

  // ---- times.txt
  if (isFile(dir + "/times.txt")) {
    std::ifstream in(dir + "/times.txt");
    std::string line;
    int line_no = 0;
    while (std::getline(in, line)) {
      ++line_no;
      std::istringstream ls(line);
      std::string token, extra;
      if (!(ls >> token)) continue;  // blank line
      char* end = nullptr;
      const double t = std::strtod(token.c_str(), &end);
      if (end == token.c_str() || *end != '\0' || (ls >> extra)) {
        fail("times.txt line " + std::to_string(line_no) + " is not one number");
      }
      s.times_.push_back(t);
    }
    if (static_cast<int>(s.times_.size()) < s.size()) {
      fail("times.txt has " + std::to_string(s.times_.size()) + " stamps for " + std::to_string(s.size()) + " frames");
    }
    int non_finite = 0, not_increasing = 0, first_nf = -1, first_ni = -1;
    std::vector<double> steps;
    double last = std::numeric_limits<double>::quiet_NaN();
    for (int i = 0; i < s.size(); ++i) {
      const double t = s.times_[static_cast<size_t>(i)];
      if (!std::isfinite(t)) {
        if (non_finite++ == 0) first_nf = i;
        continue;
      }
      if (std::isfinite(last)) {
        if (!(t > last)) {
          if (not_increasing++ == 0) first_ni = i;
        } else {
          steps.push_back(t - last);
        }
      }
      last = std::isfinite(last) ? std::max(last, t) : t;
    }
    if (non_finite > 0) {
      s.warnings_.push_back("times.txt: " + std::to_string(non_finite) + " stamp(s) not finite (first frame " +
                            std::to_string(first_nf) + "); those frames will be rejected");
    }
    if (not_increasing > 0) {
      s.warnings_.push_back("times.txt: " + std::to_string(not_increasing) + " stamp(s) do not increase (first frame " +
                            std::to_string(first_ni) + ")");
    }
    if (steps.size() >= 2) {
      std::vector<double> sorted = steps;
      std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2), sorted.end());
      const double median = sorted[sorted.size() / 2];
      const auto big = std::count_if(steps.begin(), steps.end(),
                                     [&](double d) { return d > options.time_jump_factor * median; });
      if (big > 0) {
        std::ostringstream os;
        os << "times.txt: " << big << " step(s) longer than " << options.time_jump_factor << " x the median step of "
           << median << " s (longest " << *std::max_element(steps.begin(), steps.end()) << " s)";
        s.warnings_.push_back(os.str());
      }
    }
  }
  if (options.read_ground_truth && isFile(dir + "/poses.txt")) s.poses_ = TrajectoryWriter::readKitti(dir + "/poses.txt");

  // ---- image size from the first readable left image
  for (int i = 0; i < s.size(); ++i) {
    const cv::Mat first = ImageFileReader::read(s.left_[static_cast<size_t>(i)], nullptr);
    if (first.empty()) continue;
    try {
      s.rig_ = s.rig_.withImageSize(first.cols, first.rows);
    } catch (const std::invalid_argument& e) {
      fail("calibration " + s.calib_path_ + " does not fit " + s.left_[static_cast<size_t>(i)] + ": " + e.what());
    }
    return s;
  }
  fail("none of the " + std::to_string(s.size()) + " images in " + s.left_dir_ + " can be read");
  return s;
}

double KittiSequence::stamp(int i) const {
  return times_.empty() ? 0.1 * i : times_.at(static_cast<size_t>(i));
}

bool KittiSequence::tryRead(int i, cv::Mat* left, cv::Mat* right, std::string* why) const {
  *left = ImageFileReader::read(leftPath(i), why);
  if (left->empty()) return false;
  *right = ImageFileReader::read(rightPath(i), why);
  return !right->empty();
}

void KittiSequence::read(int i, cv::Mat* left, cv::Mat* right) const {
  std::string why;
  if (!tryRead(i, left, right, &why)) throw std::runtime_error(why);
}

}  // namespace stereo_ground_dem
