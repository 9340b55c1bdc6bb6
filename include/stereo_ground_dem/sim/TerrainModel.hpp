#pragma once
/// \file TerrainModel.hpp
/// The terrain height field of a SyntheticScene: smooth components plus piecewise-constant steps,
/// the axis-parallel feature lines that separate its pieces, and the bounds on slope and curvature
/// that make exact ray casting possible (RayCaster).
///
/// Model:
///  - height(x, y) = smooth part + piecewise-constant steps;
///  - every step (curb, terrace) and every edge of a feature's support (bump, ruts, embankment
///    kinks) lies on an axis-parallel line x = const or y = const ("feature lines");
///  - between feature lines (in one "cell"), the smooth part is C1 with known bounds on its slope
///    and curvature along any ray direction (rayBounds(), cellBounds()), so a ray can be marched
///    with provably safe steps; at a feature line, a ray below the terrain on the far side hits a
///    vertical face exactly on that line.

#include <Eigen/Core>
#include <vector>

#include "stereo_ground_dem/sim/SceneOptions.hpp"

namespace stereo_ground_dem::sim {

class TerrainModel {
 public:
  /// A plane sinusoid of the rolling terrain: amp * sin(kx x + ky y + phase).
  struct RollingWave {
    double kx, ky;  ///< wave vector [rad/m]
    double amp;     ///< [m]
    double phase;   ///< [rad]
  };

  /// Which features are active between two feature lines.
  struct Cell {
    bool bump = false;        ///< inside the bump's support
    bool bump_taper = false;  ///< ... in its lateral taper
    bool rut[2] = {false, false};
    int embankment = 0;       ///< 0 before the foot, 1 on the slope, 2 on top
    double offset = 0.0;      ///< sum of the steps (curb, terrace) [m]
  };

  /// Per-ray bounds of |d/dt h(o + t d)| (slope) and |d^2/dt^2 h| (curvature) of each feature.
  struct RayBounds {
    double rolling_slope = 0.0, rolling_curv = 0.0;
    double bump_slope = 0.0, bump_curv = 0.0;
    double taper_slope = 0.0, taper_curv = 0.0;
    double rut_slope = 0.0, rut_curv = 0.0;
    double emb_slope = 0.0;
  };

  /// `options` must be valid (SceneOptions::isValid).
  explicit TerrainModel(const SceneOptions& options);

  /// Exact height [m] at (x, y). Region tests are strict: the sidewalk is y < curb_y_m, the
  /// terrace x > terrace_x_min_m && y > terrace_y_min_m.
  double height(double x, double y) const;
  /// Gradient (dz/dx, dz/dy) of the smooth part at (x, y) (the steps have none).
  Eigen::Vector2d gradient(double x, double y) const;

  /// Lowest and highest height anywhere [m].
  double minHeight() const { return z_min_; }
  double maxHeight() const { return z_max_; }

  const std::vector<double>& xLines() const { return x_lines_; }  ///< feature lines x = const
  const std::vector<double>& yLines() const { return y_lines_; }  ///< feature lines y = const

  Cell cellAt(double x, double y) const;
  /// Height and gradient at (x, y) with the features of `cell` (one-sided values on lines).
  double heightInCell(double x, double y, const Cell& cell, double* gx, double* gy) const;

  /// The directional bounds of every feature along rays of direction `d` (need not be unit).
  RayBounds rayBounds(const Eigen::Vector3d& d) const;
  /// Slope and curvature bounds along the ray inside `cell`, and the highest height there.
  void cellBounds(const RayBounds& rb, const Cell& cell, double* slope, double* curv,
                  double* z_top) const;

  const std::vector<RollingWave>& rollingWaves() const { return waves_; }
  double rollingOffset() const { return rolling_offset_m_; }

 private:
  SceneOptions options_;
  std::vector<RollingWave> waves_;
  double rolling_offset_m_ = 0.0;
  double rolling_amp_sum_m_ = 0.0;
  double embankment_tan_ = 0.0;       ///< tan(embankment_slope_rad)
  double embankment_top_y_m_ = 0.0;   ///< where the embankment slope ends
  std::vector<double> x_lines_;
  std::vector<double> y_lines_;
  double z_min_ = 0.0;
  double z_max_ = 0.0;
};

}  // namespace stereo_ground_dem::sim
