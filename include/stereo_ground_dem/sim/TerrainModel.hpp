#pragma once
/// \file TerrainModel.hpp
/// The terrain height field of a SyntheticScene: smooth components plus piecewise-constant steps,
/// the axis-parallel feature lines that separate its pieces, and the bounds on slope and curvature
/// that make exact ray casting possible (RayCaster).
///
/// Model:
///  - height(x, y) = smooth part + piecewise-constant steps;
///  - every step (curb, terrace) and every edge of a feature's support (bump, ruts, embankment
///    kinks, the ends of vertical curves and of transverse wave rows, potholes) lies on an
///    axis-parallel line x = const or y = const ("feature lines");
///  - the banking around a circle is C1 everywhere with global bounds (no feature lines);
///  - between feature lines (in one "cell"), the smooth part is C1 with known bounds on its slope
///    and curvature along any ray direction (rayBounds(), cellBounds()), so a ray can be marched
///    with provably safe steps; at a feature line, a ray below the terrain on the far side hits a
///    vertical face exactly on that line.

#include <Eigen/Core>
#include <cstdint>
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
    int profile_piece = -1;   ///< piece of the longitudinal profile (-1: no profile)
    int wave_row = -1;        ///< transverse wave row covering x (-1: none)
    uint32_t potholes = 0;    ///< bit i: inside pothole i
  };

  /// Per-ray bounds of |d/dt h(o + t d)| (slope) and |d^2/dt^2 h| (curvature) of each feature.
  struct RayBounds {
    double rolling_slope = 0.0, rolling_curv = 0.0;
    double bump_slope = 0.0, bump_curv = 0.0;
    double taper_slope = 0.0, taper_curv = 0.0;
    double rut_slope = 0.0, rut_curv = 0.0;
    double emb_slope = 0.0;
    double bank_slope = 0.0, bank_curv = 0.0;
    double dx = 0.0;              ///< d.x
    double adx = 0.0, ady = 0.0;  ///< |d.x|, |d.y|
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
  /// Inside `cell`, along the ray: h = (a part linear in t, of slope `linear` per unit t) + (a
  /// rest whose slope and curvature are bounded by `slope` and `curv`); `z_top` bounds h.
  /// (The linear part: the longitudinal profile on a straight grade; 0 for the other features.)
  void cellBounds(const RayBounds& rb, const Cell& cell, double* slope, double* curv,
                  double* z_top, double* linear) const;

  const std::vector<RollingWave>& rollingWaves() const { return waves_; }
  double rollingOffset() const { return rolling_offset_m_; }

 private:
  /// A piece of the longitudinal profile: z = z0 + g0 u + c u^2 / 2, u = x - x0.
  struct ProfilePiece {
    double x0, z0, g0, c;
    double slope_max;  ///< max |dz/dx| on the piece
    double z_max;      ///< highest z on the piece
    double z_min;      ///< lowest z on the piece
  };
  /// A transverse wave row with its derivative bounds per unit |d.x| (and |d.x|^2).
  struct WaveRow {
    double x0, x1, k, half_height;  ///< k = 2 pi / period
    double slope, curv;
  };

  void buildProfile();
  void buildWaves();
  double profileHeight(double x, int piece, double* gx) const;
  double bankHeight(double x, double y, double* gx, double* gy) const;

  SceneOptions options_;
  std::vector<ProfilePiece> profile_;
  std::vector<double> profile_breaks_;  ///< profile_[i + 1] starts at profile_breaks_[i]
  std::vector<WaveRow> wave_rows_;      ///< sorted along x
  double bank_top_m_ = 0.0;             ///< |superelevation| * (half width + transition / 2)
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
