#include "stereo_ground_dem/io/TrajectoryWriter.hpp"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "stereo_ground_dem/io/NumberText.hpp"

namespace stereo_ground_dem {

namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw std::runtime_error("TrajectoryWriter: " + path + ": " + what);
}

[[noreturn]] void failAt(const std::string& path, int line, const std::string& what) {
  throw std::runtime_error("TrajectoryWriter: " + path + ":" + std::to_string(line) + ": " + what);
}

void writeText(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) fail(path, "cannot open for writing");
  f << text;
  f.flush();
  if (!f) fail(path, "write error");
}

/// Calls `on_line(line_number, tokens)` for every non-blank line (and non-comment line if
/// `comments` is set).
template <typename F>
void forEachLine(const std::string& path, bool comments, F on_line) {
  std::ifstream f(path, std::ios::binary);
  if (!f) fail(path, "cannot open (no such file or not readable)");
  std::string line;
  int number = 0;
  while (std::getline(f, line)) {
    ++number;
    std::istringstream is(line);
    std::vector<std::string> tokens;
    std::string tok;
    while (is >> tok) tokens.push_back(tok);
    if (tokens.empty()) continue;
    if (comments && tokens[0][0] == '#') continue;
    on_line(number, tokens);
  }
  if (f.bad()) fail(path, "read error");
}

std::vector<double> parseNumbers(const std::string& path, int line, const std::vector<std::string>& tokens,
                                 size_t expected) {
  if (tokens.size() != expected) {
    failAt(path, line,
           "expected " + std::to_string(expected) + " numbers, found " + std::to_string(tokens.size()) +
               " fields");
  }
  std::vector<double> v(expected);
  for (size_t i = 0; i < expected; ++i) {
    if (!NumberText::parse(tokens[i], &v[i]) || !std::isfinite(v[i])) {
      failAt(path, line, "field " + std::to_string(i + 1) + " ('" + tokens[i] + "') is not a finite number");
    }
  }
  return v;
}

}  // namespace

void TrajectoryWriter::writeKitti(const std::string& path, const std::vector<Eigen::Isometry3d>& poses) {
  std::ostringstream os;
  for (const Eigen::Isometry3d& p : poses) {
    const Eigen::Matrix4d m = p.matrix();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) os << (r + c > 0 ? " " : "") << NumberText::shortest(m(r, c));
    }
    os << "\n";
  }
  writeText(path, os.str());
}

void TrajectoryWriter::writeTum(const std::string& path, const std::vector<double>& stamps_s,
                                const std::vector<Eigen::Isometry3d>& poses) {
  if (stamps_s.size() != poses.size()) {
    fail(path, std::to_string(stamps_s.size()) + " stamps for " + std::to_string(poses.size()) + " poses");
  }
  std::ostringstream os;
  os << "# timestamp tx ty tz qx qy qz qw\n";
  for (size_t i = 0; i < poses.size(); ++i) {
    const Eigen::Vector3d t = poses[i].translation();
    Eigen::Quaterniond q(poses[i].rotation());
    q.normalize();
    if (q.w() < 0.0) q.coeffs() *= -1.0;  // one of the two equivalent signs, for diffable files
    os << NumberText::shortest(stamps_s[i]);
    for (double v : {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()}) os << " " << NumberText::shortest(v);
    os << "\n";
  }
  writeText(path, os.str());
}

std::vector<Eigen::Isometry3d> TrajectoryWriter::readKitti(const std::string& path) {
  std::vector<Eigen::Isometry3d> poses;
  forEachLine(path, false, [&](int line, const std::vector<std::string>& tokens) {
    const std::vector<double> v = parseNumbers(path, line, tokens, 12);
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    for (int i = 0; i < 12; ++i) m(i / 4, i % 4) = v[static_cast<size_t>(i)];
    const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
    if ((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-3 ||
        r.determinant() < 0.0) {
      failAt(path, line, "the 3x3 block is not a rotation matrix");
    }
    Eigen::Isometry3d p;
    p.matrix() = m;
    poses.push_back(p);
  });
  return poses;
}

StampedTrajectory TrajectoryWriter::readTum(const std::string& path) {
  StampedTrajectory out;
  forEachLine(path, true, [&](int line, const std::vector<std::string>& tokens) {
    const std::vector<double> v = parseNumbers(path, line, tokens, 8);
    Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);  // (w, x, y, z)
    const double n = q.norm();
    if (!(n > 1e-9)) failAt(path, line, "zero quaternion");
    q.coeffs() /= n;
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    p.linear() = q.toRotationMatrix();
    p.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
    out.stamps_s.push_back(v[0]);
    out.poses.push_back(p);
  });
  return out;
}

}  // namespace stereo_ground_dem
