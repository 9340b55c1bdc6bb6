#pragma once
/// \file RoadPath.hpp
/// A road centreline in the ground plane made of straight and circular pieces joined with a common
/// tangent, parametrized by arc length s [m]. The road's markings are laid out in path
/// coordinates (s, n): n is the signed offset from the centreline, positive to the left of the
/// direction of travel. The vehicle model follows a parallel of the path (SequenceGenerator).
///
/// The pieces cover s in [start_s_m, start_s_m + total length]; the pose at s = 0 is the anchor.
/// Beyond its ends the path continues its first and last pieces (a straight line goes on, a
/// circle goes round). Poses are closed-form (exact to rounding): on a piece of curvature k
/// starting at (p, theta), heading theta + k u and position p + ((sin(theta + k u) - sin theta) /
/// k, (cos theta - cos(theta + k u)) / k) after u metres.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace stereo_ground_dem::sim {

/// One piece of a road path: straight (curvature 0) or a circular arc.
struct RoadPiece {
  double length_m = 100.0;       ///< [m], > 0
  double curvature_per_m = 0.0;  ///< 1 / radius, positive turning left [1/m]
};

struct RoadPathOptions {
  Eigen::Vector2d anchor_xy_m = Eigen::Vector2d::Zero();  ///< the centreline at s = 0 [m]
  double anchor_heading_rad = 0.0;  ///< direction of travel at s = 0, counter-clockwise from +x
  double start_s_m = 0.0;           ///< arc length where the first piece starts [m], <= 0
  std::vector<RoadPiece> pieces;    ///< empty: no path

  bool empty() const { return pieces.empty(); }
  bool isValid(std::string* why = nullptr) const;
};

class RoadPath {
 public:
  struct Pose {
    Eigen::Vector2d xy = Eigen::Vector2d::Zero();  ///< [m]
    double heading_rad = 0.0;                      ///< direction of travel [rad]
    double curvature_per_m = 0.0;                  ///< of the piece [1/m]
    /// Unit vectors along and to the left of the direction of travel.
    Eigen::Vector2d tangent() const;
    Eigen::Vector2d normal() const;
  };

  /// The nearest centreline point of (x, y) in path coordinates.
  struct Coordinates {
    double s_m = 0.0;              ///< arc length [m]
    double n_m = 0.0;              ///< signed offset, positive to the left [m]
    double heading_rad = 0.0;      ///< direction of travel at s [rad]
    double curvature_per_m = 0.0;  ///< of the piece at s [1/m]
  };

  RoadPath() = default;
  /// `options` must be valid (throws std::invalid_argument otherwise).
  explicit RoadPath(const RoadPathOptions& options);

  bool empty() const { return pieces_.empty(); }
  double startS() const { return start_s_; }
  double endS() const { return end_s_; }

  /// The centreline pose at arc length s (any s: the end pieces are continued).
  Pose poseAt(double s_m) const;

  /// Path coordinates of (x, y): over the pieces whose normals pass through the point, the one
  /// with the smallest |n| (the end pieces continued as in poseAt). Unique within the smaller of
  /// the pieces' radii from the path.
  Coordinates coordinates(double x, double y) const;

  /// The arc length s on the centreline reached by a vehicle that keeps the offset `offset_m`
  /// and drives `distance_m` (along its own parallel curve, negative: backwards) from s = 0. On a
  /// piece of curvature k the parallel is (1 - k offset_m) times as long as the centreline.
  double arcLengthAfter(double offset_m, double distance_m) const;

 private:
  struct Piece {
    double s0 = 0.0;     ///< arc length at the start
    double length = 0.0;
    double curvature = 0.0;
    Pose start;          ///< pose at s0
    Eigen::Vector2d tangent = Eigen::Vector2d::UnitX();  ///< start.tangent()
    Eigen::Vector2d normal = Eigen::Vector2d::UnitY();   ///< start.normal()
  };
  Pose advance(const Piece& piece, double u) const;

  std::vector<Piece> pieces_;
  double start_s_ = 0.0;
  double end_s_ = 0.0;
};

}  // namespace stereo_ground_dem::sim
