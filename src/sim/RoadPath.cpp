#include "stereo_ground_dem/sim/RoadPath.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace stereo_ground_dem::sim {

namespace {

constexpr double kTwoPi = 2.0 * M_PI;

// The pose u metres along a piece of curvature k from `start` (u may be negative).
RoadPath::Pose advancePose(const RoadPath::Pose& start, double k, double u) {
  RoadPath::Pose p;
  p.curvature_per_m = k;
  const double th0 = start.heading_rad;
  if (k == 0.0) {
    p.xy = start.xy + u * Eigen::Vector2d(std::cos(th0), std::sin(th0));
    p.heading_rad = th0;
  } else {
    const double th1 = th0 + k * u;
    p.xy = start.xy + Eigen::Vector2d((std::sin(th1) - std::sin(th0)) / k,
                                      (std::cos(th0) - std::cos(th1)) / k);
    p.heading_rad = th1;
  }
  return p;
}

}  // namespace

bool RoadPathOptions::isValid(std::string* why) const {
  auto bad = [why](const char* msg) {
    if (why) *why = msg;
    return false;
  };
  if (pieces.empty()) return true;
  if (!anchor_xy_m.allFinite() || !std::isfinite(anchor_heading_rad) || !std::isfinite(start_s_m) ||
      start_s_m > 0.0) {
    return bad("road path: finite anchor pose and start_s_m <= 0");
  }
  double total = 0.0;
  for (const auto& p : pieces) {
    if (!(p.length_m > 0.0) || !std::isfinite(p.length_m) || !std::isfinite(p.curvature_per_m) ||
        std::abs(p.curvature_per_m) > 1.0) {
      return bad("road path: piece lengths > 0, |curvature| <= 1 / m");
    }
    if (p.curvature_per_m != 0.0 && p.length_m * std::abs(p.curvature_per_m) > kTwoPi + 1e-9) {
      return bad("road path: an arc turns at most once round");
    }
    total += p.length_m;
  }
  if (start_s_m + total < 0.0) return bad("road path: the pieces must reach s = 0 (the anchor)");
  return true;
}

Eigen::Vector2d RoadPath::Pose::tangent() const {
  return {std::cos(heading_rad), std::sin(heading_rad)};
}

Eigen::Vector2d RoadPath::Pose::normal() const {
  return {-std::sin(heading_rad), std::cos(heading_rad)};
}

RoadPath::RoadPath(const RoadPathOptions& options) {
  std::string why;
  if (!options.isValid(&why)) throw std::invalid_argument(why);
  if (options.pieces.empty()) return;
  start_s_ = options.start_s_m;
  double s = start_s_;
  for (const auto& p : options.pieces) {
    Piece piece;
    piece.s0 = s;
    piece.length = p.length_m;
    piece.curvature = p.curvature_per_m;
    pieces_.push_back(piece);
    s += p.length_m;
  }
  end_s_ = s;
  // The piece holding the anchor (s = 0) starts where the anchor pose, walked back, is.
  size_t a = 0;
  while (a + 1 < pieces_.size() && pieces_[a].s0 + pieces_[a].length < 0.0) ++a;
  Pose anchor;
  anchor.xy = options.anchor_xy_m;
  anchor.heading_rad = options.anchor_heading_rad;
  pieces_[a].start = advancePose(anchor, pieces_[a].curvature, pieces_[a].s0);
  for (size_t i = a + 1; i < pieces_.size(); ++i) {
    const Piece& prev = pieces_[i - 1];
    pieces_[i].start = advancePose(prev.start, prev.curvature, prev.length);
    pieces_[i].start.curvature_per_m = pieces_[i].curvature;
  }
  for (size_t i = a; i-- > 0;) {
    const Piece& next = pieces_[i + 1];
    pieces_[i].start = advancePose(next.start, pieces_[i].curvature, -pieces_[i].length);
  }
  for (Piece& p : pieces_) {
    p.tangent = p.start.tangent();
    p.normal = p.start.normal();
  }
}

RoadPath::Pose RoadPath::advance(const Piece& piece, double u) const {
  return advancePose(piece.start, piece.curvature, u);
}

RoadPath::Pose RoadPath::poseAt(double s_m) const {
  if (pieces_.empty()) {
    Pose p;
    p.xy = {s_m, 0.0};
    return p;
  }
  size_t i = 0;
  while (i + 1 < pieces_.size() && s_m > pieces_[i].s0 + pieces_[i].length) ++i;
  return advance(pieces_[i], s_m - pieces_[i].s0);
}

RoadPath::Coordinates RoadPath::coordinates(double x, double y) const {
  Coordinates best;
  if (pieces_.empty()) {
    best.s_m = x;
    best.n_m = y;
    return best;
  }
  double best_abs_n = std::numeric_limits<double>::infinity();
  const Eigen::Vector2d q(x, y);
  const size_t last = pieces_.size() - 1;
  for (size_t i = 0; i < pieces_.size(); ++i) {
    const Piece& pc = pieces_[i];
    const Pose& st = pc.start;
    double u, n;
    if (pc.curvature == 0.0) {
      const Eigen::Vector2d w = q - st.xy;
      u = w.dot(pc.tangent);
      n = w.dot(pc.normal);
      if ((u < 0.0 && i != 0) || (u > pc.length && i != last)) continue;
    } else {
      const double k = pc.curvature;
      const double radius = 1.0 / std::abs(k);
      const Eigen::Vector2d centre = st.xy + pc.normal / k;
      const Eigen::Vector2d a = st.xy - centre;
      const Eigen::Vector2d w = q - centre;
      const double r = w.norm();
      // Angle from the start radius to the point, in the direction of travel, in [0, 2 pi).
      double phi = std::atan2(a.x() * w.y() - a.y() * w.x(), a.dot(w));
      if (k < 0.0) phi = -phi;
      if (phi < 0.0) phi += kTwoPi;
      u = phi * radius;
      if (u > pc.length) {
        // Outside the arc's angular range: past its end (continued by the last piece) or before
        // its start (continued by the first piece), whichever end is angularly nearer.
        const double before = u - kTwoPi * radius;  // the same point reached backwards
        const bool past_end = (u - pc.length) < -before;
        if (past_end && i == last) {
          // keep u
        } else if (!past_end && i == 0) {
          u = before;
        } else {
          continue;
        }
      }
      n = (k > 0.0 ? 1.0 : -1.0) * (radius - r);
    }
    if (std::abs(n) < best_abs_n) {
      best_abs_n = std::abs(n);
      best.s_m = pc.s0 + u;
      best.n_m = n;
      best.heading_rad = st.heading_rad + pc.curvature * u;
      best.curvature_per_m = pc.curvature;
    }
  }
  return best;
}

double RoadPath::arcLengthAfter(double offset_m, double distance_m) const {
  if (pieces_.empty()) return distance_m;
  // Walk from s = 0 forwards or backwards over the pieces; the ratio of parallel length to
  // centreline length is (1 - k offset) on each.
  size_t i = 0;
  while (i + 1 < pieces_.size() && 0.0 > pieces_[i].s0 + pieces_[i].length) ++i;
  double s = 0.0;
  double left = distance_m;
  if (left >= 0.0) {
    for (;; ++i) {
      const Piece& pc = pieces_[i];
      const double ratio = 1.0 - pc.curvature * offset_m;
      const double room = i == pieces_.size() - 1 ? std::numeric_limits<double>::infinity()
                                                  : (pc.s0 + pc.length - s) * ratio;
      if (left <= room) return s + left / ratio;
      left -= room;
      s = pc.s0 + pc.length;
    }
  }
  for (;; --i) {
    const Piece& pc = pieces_[i];
    const double ratio = 1.0 - pc.curvature * offset_m;
    const double room = i == 0 ? std::numeric_limits<double>::infinity() : (s - pc.s0) * ratio;
    if (-left <= room) return s + left / ratio;
    left += room;
    s = pc.s0;
  }
}

}  // namespace stereo_ground_dem::sim
