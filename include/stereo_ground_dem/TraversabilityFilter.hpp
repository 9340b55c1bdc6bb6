#pragma once
/// \file TraversabilityFilter.hpp
/// Traversability of the estimated ground surface (METHOD.md section 7), following the common
/// elevation-mapping practice (ETH elevation_mapping / traversability_estimation): per DEM vertex a
/// slope, a step height and a roughness, each compared with a critical value, combined into a
/// traversability in 0..1 (1 = as good as flat ground, 0 = not traversable), NaN where unknown.
///
/// Windows. Every window is a square of vertices centred on the vertex (GroundGrid conventions:
/// row along y, column along x), of half side k = max(1, round(radius_m / resolution_m)) cells, so
/// "radius" is the half side of the square (its Chebyshev radius) in metres, and results are in
/// metres and radians whatever the resolution. Windows are clipped at the grid border: vertices
/// outside the grid are neither known nor counted in the window's size.
///
/// Slope [rad]: the angle to z of the normal of the least-squares plane through the known heights
///   of the slope window. A plane fit rather than the steepest incident mesh triangle because a
///   triangle's gradient amplifies height noise by 1 / resolution (1 cm of noise on a 0.1 m grid
///   is a 6 deg error) and the maximum over six triangles is biased upwards, while a vehicle's
///   attitude is set by the ground under its whole wheelbase. With slope_window_radius_m = 0 the
///   steepest incident mesh triangle is used instead (exact for the mesh; for smooth or coarse DEMs).
/// Step [m]: the largest height difference between two known vertices of the step window that lie
///   within one square of n x n vertices, n - 1 = max(1, round(step_run_m / resolution_m)) cells:
///   a height change counts as a step only if it happens over at most ~step_run_m horizontally, so
///   a long gentle slope is not a step (a plane of gradient g adds only (n - 1) * resolution_m *
///   (|g_x| + |g_y|), at most run * sqrt(2) * tan(slope)). A vertical jump of h gives exactly h.
///   n is at most 2k + 1; step_run_m >= 2 * step_window_radius_m gives the plain max - min of the
///   window. (ETH's step filter uses the same two-window idea: a small first window for the local
///   max - min, a robot-sized second one.)
/// Roughness [m]: the standard deviation of the residuals of the least-squares plane fit over the
///   roughness window, sqrt(RSS / (N - 3)) (unbiased for white noise about a plane).
/// Traversability: with ratios q_s = slope / critical_slope_rad, q_t = step / critical_step_m,
///   q_r = roughness / critical_roughness_m: 0 if any ratio >= 1, else
///   slope_weight (1 - q_s) + step_weight (1 - q_t) + roughness_weight (1 - q_r).
/// Probability of being traversable (probability()): each ratio below 1 with the height's standard
///   deviation sigma (the map's variance, floored at height_std_floor_m) propagated through its
///   measure, assumed Gaussian and independent:
///   P = Phi((tan(crit_slope) - tan(slope)) / sigma_g) Phi((crit_step - step) / (sqrt(2) sigma))
///       Phi((crit_roughness - roughness) / sigma),
///   sigma_g = sigma / (s sqrt((2k+1)^2 k (k+1) / 3)) the least-squares gradient's std over the
///   (2k+1)^2 slope window of spacing s (sqrt(2) sigma / s for the mesh triangles, k = 0). A step is
///   a difference of two heights; the roughness is taken as uncertain by about one sigma.
/// Unknown: every layer is NaN where the vertex's height is NaN (or infinite), or where fewer than
///   min_known_fraction of its window's (clipped) vertices are known, or where the plane fit is
///   degenerate (known vertices collinear); the traversability is NaN where any layer is.
///
/// Cost: O(1) per vertex and window size for the plane fits (box sums of the ten moments of the
/// known vertices, as running sums row by row, O(cols) memory), separable min / max filters
/// (cv::erode / cv::dilate on the masked layer) for the steps: ~10 ms for a 400 x 400 grid, one
/// thread, -O2 (test Timing400x400 prints it).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>

#include "stereo_ground_dem/GroundGrid.hpp"

namespace stereo_ground_dem {

/// Defaults are the passenger-car preset (forCar()).
struct TraversabilityOptions {
  double critical_slope_rad = 0.3490658503988659;  ///< 20 deg: traversability 0 at or above [rad]
  double critical_step_m = 0.20;                   ///< step height giving 0 [m]
  double critical_roughness_m = 0.08;              ///< residual std giving 0 [m]
  /// Half side of the square plane-fit window for the slope [m]; 0: steepest incident mesh triangle.
  double slope_window_radius_m = 1.0;
  double step_window_radius_m = 1.0;       ///< half side of the robot-sized step window [m]
  double step_run_m = 0.2;                 ///< horizontal extent over which a rise counts as a step [m]
  double roughness_window_radius_m = 1.0;  ///< half side of the roughness plane-fit window [m]
  double slope_weight = 0.25;              ///< weights of (1 - ratio) in the traversability; sum 1
  double step_weight = 0.5;
  double roughness_weight = 0.25;
  double min_known_fraction = 0.5;  ///< of a window's vertices that must be known, in (0, 1]
  /// Floor on the heights' standard deviation in probability() [m]: the map's variance counts only
  /// the data of the frames (docs/method.md), real errors on KITTI are centimetres.
  double height_std_floor_m = 0.02;

  /// A passenger car (tyre radius ~0.3 m, ground clearance 0.13-0.20 m, track ~1.6 m, wheelbase
  /// ~2.7 m):
  ///  - critical slope 20 deg: the steepest public streets are ~17-19 deg (30-35 %), about what a
  ///    car can start on; steeper ground risks traction loss and scraping;
  ///  - critical step 0.20 m: about where the tyre can no longer roll up a vertical face and the
  ///    sills touch; a 0.10-0.15 m curb (mountable slowly) comes out as low, non-zero traversability;
  ///  - critical roughness 0.08 m: residual std of 8 cm means +-16 cm (2 sigma) bumps, the ground
  ///    clearance;
  ///  - windows of half side 1.0 m: a 2 m square, between track and wheelbase, over which the
  ///    chassis rests; step run 0.2 m (~2/3 of the tyre radius: a rise completed over a shorter
  ///    distance loads the tyre like a face, a longer one it rolls up like a ramp);
  ///  - weights 0.25 / 0.5 / 0.25: steps are what damage tyres, rims and bumpers; slopes below 20 deg
  ///    and moderate roughness are comfort issues.
  static TraversabilityOptions forCar();
  /// A small wheeled ground robot (~0.5 m long, wheel radius ~0.1 m, ground clearance 6-8 cm):
  ///  - critical slope 15 deg: high centre of gravity over a narrow track and little traction; such
  ///    robots are typically rated for 15-20 deg, 15 keeps a margin;
  ///  - critical step 0.08 m: the ground clearance, and a bit more than the ~half wheel radius such
  ///    wheels climb reliably; a 0.10-0.15 m curb is not traversable;
  ///  - critical roughness 0.03 m: +-6 cm bumps (2 sigma) touch the chassis;
  ///  - windows of half side 0.3 m: a 0.6 m square, the footprint with a margin; step run 0.1 m
  ///    (the wheel radius);
  ///  - weights 0.3 / 0.4 / 0.3: small wheels and low clearance make roughness and slope count
  ///    relatively more than for a car.
  static TraversabilityOptions forSmallRobot();

  bool isValid(std::string* why) const;
};

/// Per vertex layers, each CV_32F of grid.rows x grid.cols, element (r, c) = vertex (r, c), NaN
/// where unknown.
struct TraversabilityLayers {
  cv::Mat slope_rad;       ///< inclination of the local plane (or steepest triangle) [rad]
  cv::Mat step_m;          ///< largest short-run height difference in the step window [m]
  cv::Mat roughness_m;     ///< std of the plane-fit residuals [m]
  cv::Mat traversability;  ///< 0 (not traversable) .. 1 (flat)
};

/// The window sizes in cells that the options give at one resolution.
struct TraversabilityWindows {
  int slope_half = 0;      ///< half side of the slope window [cells]; 0 = mesh triangles
  int step_half = 1;       ///< half side of the step window [cells]
  int step_run = 1;        ///< side of the short-run squares, n - 1 [cells], 1 .. 2 * step_half
  int roughness_half = 1;  ///< half side of the roughness window [cells]
};

class TraversabilityFilter {
 public:
  /// Throws std::invalid_argument with the reason if `options` is invalid.
  explicit TraversabilityFilter(const TraversabilityOptions& options = TraversabilityOptions());

  /// `heights`: CV_32F (or CV_64F) of grid.rows x grid.cols, element (r, c) = height of vertex
  /// (r, c) [m], NaN unknown. Throws std::invalid_argument on a size or type mismatch.
  TraversabilityLayers compute(const GroundGrid& grid, const cv::Mat& heights) const;
  /// The same with the heights as a row-major vector (index r * cols + c), as in SurfaceState.
  TraversabilityLayers compute(const GroundGrid& grid, const Eigen::VectorXd& heights) const;

  /// The traversability of one set of values (no NaN handling): 0 if any ratio >= 1, else the
  /// weighted sum of (1 - ratio).
  double combine(double slope_rad, double step_m, double roughness_m) const;

  /// Per vertex, the probability that the vertex is traversable (every ratio below 1) given the
  /// heights' variance [m^2] (CV_32F, same size; NaN unknown): CV_32F, NaN where `layers` is.
  cv::Mat probability(const GroundGrid& grid, const TraversabilityLayers& layers, const cv::Mat& variance) const;

  TraversabilityWindows windows(double resolution_m) const;
  const TraversabilityOptions& options() const { return options_; }

 private:
  TraversabilityOptions options_;
};

}  // namespace stereo_ground_dem
