#include "stereo_ground_dem/io/KittiSequence.hpp"

#include <algorithm>
#include <dirent.h>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <sys/stat.h>

#include "stereo_ground_dem/CalibrationReader.hpp"
#include "stereo_ground_dem/io/TrajectoryWriter.hpp"

namespace stereo_ground_dem {

namespace {
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
}  // namespace

KittiSequence KittiSequence::open(const std::string& dir) {
  KittiSequence s;
  s.dir_ = dir;
  auto fail = [&dir](const std::string& why) { throw std::runtime_error("sequence '" + dir + "': " + why); };
  if (!isDir(dir)) fail("is not a directory");
  if (!isFile(dir + "/calib.txt")) fail("has no calib.txt");
  const std::pair<const char*, const char*> layouts[] = {{"image_0", "image_1"}, {"image_2", "image_3"}, {"image_l", "image_r"}};
  std::string ldir, rdir;
  for (const auto& l : layouts) {
    if (isDir(dir + "/" + l.first) && isDir(dir + "/" + l.second)) {
      ldir = dir + "/" + l.first;
      rdir = dir + "/" + l.second;
      break;
    }
  }
  if (ldir.empty()) fail("has no image_0/image_1, image_2/image_3 or image_l/image_r folders");
  const std::vector<std::string> ln = imagesIn(ldir), rn = imagesIn(rdir);
  if (ln.empty()) fail("no images in " + ldir);
  for (const auto& n : ln) {
    if (!std::binary_search(rn.begin(), rn.end(), n)) fail("right image " + rdir + "/" + n + " is missing");
    s.left_.push_back(ldir + "/" + n);
    s.right_.push_back(rdir + "/" + n);
  }
  if (isFile(dir + "/times.txt")) {
    std::ifstream in(dir + "/times.txt");
    double t;
    while (in >> t) s.times_.push_back(t);
    if (static_cast<int>(s.times_.size()) < s.size()) {
      fail("times.txt has " + std::to_string(s.times_.size()) + " stamps for " + std::to_string(s.size()) + " frames");
    }
  }
  if (isFile(dir + "/poses.txt")) s.poses_ = TrajectoryWriter::readKitti(dir + "/poses.txt");
  s.rig_ = CalibrationReader::read(dir + "/calib.txt");
  const cv::Mat first = cv::imread(s.left_[0], cv::IMREAD_UNCHANGED);
  if (first.empty()) fail("cannot read " + s.left_[0]);
  s.rig_.width = first.cols;
  s.rig_.height = first.rows;
  return s;
}

double KittiSequence::stamp(int i) const {
  return times_.empty() ? 0.1 * i : times_.at(static_cast<size_t>(i));
}

void KittiSequence::read(int i, cv::Mat* left, cv::Mat* right) const {
  *left = cv::imread(leftPath(i), cv::IMREAD_UNCHANGED);
  if (left->empty()) throw std::runtime_error("cannot read image '" + leftPath(i) + "'");
  *right = cv::imread(rightPath(i), cv::IMREAD_UNCHANGED);
  if (right->empty()) throw std::runtime_error("cannot read image '" + rightPath(i) + "'");
}

}  // namespace stereo_ground_dem
