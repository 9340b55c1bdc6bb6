#pragma once
/// \file StereoEstimator.hpp
/// Stereo mode (METHOD.md section 5, the paper's section 2): the DEM of the ground in front of a
/// rectified stereo pair, from one pair. Start-up of the ground frame: a plane from the nominal
/// camera height and pitch, refined by a direct fit of one plane on near ground; the fitted plane
/// defines the ground frame G (z up along its normal, x along the optical axis projected on it,
/// origin below the camera). Then coarse-to-fine meshes (hierarchical meshing) with an image pyramid.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/DisparityPlaneFit.hpp"
#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/ImagePyramid.hpp"
#include "stereo_ground_dem/ObstacleDetector.hpp"
#include "stereo_ground_dem/PhotometricParams.hpp"
#include "stereo_ground_dem/RectificationMonitor.hpp"
#include "stereo_ground_dem/StereoRig.hpp"
#include "stereo_ground_dem/SurfaceAligner.hpp"

namespace stereo_ground_dem {

/// Where a camera sits on level ground: its height and the attitude nominalCameraPose takes.
struct NominalMount {
  double height_m = 1.65;
  double pitch_down_rad = 0.0;  ///< positive looking down
  double roll_rad = 0.0;
};

struct StereoEstimatorOptions {
  double grid_resolution_m = 0.5;       ///< finest mesh spacing s [m]
  int mesh_levels = 4;                  ///< meshes 2^(L-1) s, ..., 2 s, s, each with pyramid level l
  double min_range_m = 4.0;             ///< working range: camera depth of vertices [m]
  double max_range_m = 40.0;            ///< [m]
  double max_lateral_m = 20.0;          ///< |x| in the camera frame [m]
  double nominal_height_m = 1.65;       ///< camera height above the ground, start-up guess [m]
  double nominal_pitch_down_rad = 0.0;  ///< start-up guess, positive looking down [rad]
  double nominal_roll_rad = 0.0;        ///< start-up guess [rad]
  /// The start-up ground plane of the sparse matches (and a relocalization's) is tilted at most this
  /// from the ground the nominal attitude expects (nominal_pitch_down_rad, nominal_roll_rad;
  /// DisparityPlaneFitOptions::nearAttitude; 0: ground_plane's own bound around the camera's axis).
  double nominal_max_tilt_rad = 0.35;
  double plane_fit_min_range_m = 5.0;   ///< the start-up plane is fitted on ground this near [m]
  double plane_fit_max_range_m = 15.0;  ///< [m]
  int plane_fit_coarsest_level = 3;     ///< pyramid levels used by the plane fit, coarse to fine
  int plane_fit_finest_level = 1;
  /// Update constraint mu_v = update_weight * (1 + (depth_v / update_reference_depth_m)^2) [1/m^2].
  double update_weight = 100.0;
  double update_reference_depth_m = 10.0;
  /// Vertices whose triangles hold more obstacle pixels than this times their ground pixels are
  /// hidden by an obstacle: unknown in the DEM, obstacle in the obstacle layer.
  double hidden_pixel_ratio = 0.3;
  int min_ground_pixels = 6;            ///< fewer pixels: the vertex is not observed
  /// A vertex whose estimated surface the camera sees this many times more obliquely than level
  /// ground at the same place (SurfaceIncidence) is not observed: the mesh runs along the rays
  /// there (draped over a hidden strip behind a rail or wall, the back of a crest). 0: off.
  double min_incidence_ratio = 0.1;
  bool use_hierarchy = true;            ///< false: the finest mesh only, at pyramid levels L-1..0
  /// Gaussian blur of level 0 (see ImagePyramid) [px]: every frame of a sequence, its start-up and
  /// relocalizations included (makePyramid).
  double presmooth_sigma_px = 0.8;
  /// ... of a one-pair run (makeStereoPyramid: `dem_offline --left --right`, estimate() from
  /// images) [px]. Unblurred, the one-pair ground disagrees with the LiDAR on KITTI raw 0013's road
  /// in 0.60 % of the pixels (D1) instead of 1.85 %: sunlit low-texture asphalt between tree
  /// shadows and clipped white paving no longer ripple the mesh (docs/results.md, "Stereo mode
  /// against the LiDAR"). A sequence keeps presmooth_sigma_px at its start-up too: started from an
  /// unblurred map, the rolling scene's 95th percentile went from 4.3 to 32 cm.
  double stereo_presmooth_sigma_px = 0.0;
  int iterations_per_level = 8;
  SurfaceAlignerOptions aligner;        ///< its depth range is overridden by the fields above
  ObstacleDetectorOptions obstacles;    ///< occlusion reasoning; camera_height_m follows nominal_height_m
  /// Model the residual vertical misalignment of the rectification (VerticalMisalignment), measured
  /// by sparse matches (RectificationMonitor). Either way, a pair whose matches show swapped
  /// cameras, no common content or no rectification at all is refused.
  bool model_rectification = true;
  /// A measured misalignment smaller than this everywhere in the image is not modelled [px]: the
  /// noise floor of the sparse-match fit (on rendered pairs with a perfect rig it reaches 0.15 px,
  /// e.g. c3 = -0.15, c4 = 0.13 px on the bump scene; both KITTI rigs show 1.4 px).
  double min_rectification_correction_px = 0.2;
  RectificationMonitorOptions rectification;
  /// The dominant plane of the sparse matches: a pair without a plausible ground plane in view is
  /// refused, and the start-up plane fit starts from this plane instead of the nominal pose.
  DisparityPlaneFitOptions ground_plane;

  /// `plane` (the sparse matches' ground plane of the start-up, or a relocalization's) near the
  /// nominal attitude: tilted at most nominal_max_tilt_rad from the ground it expects.
  DisparityPlaneFitOptions nearNominalAttitude(const DisparityPlaneFitOptions& plane) const;
  /// The ground's down direction (the ground frame's -z) in the camera at the nominal mount.
  Eigen::Vector3d nominalDown() const;
  /// `aligner` with the working range (min_range_m, max_range_m, max_lateral_m) filled in.
  SurfaceAlignerOptions alignerOptions() const;
  bool isValid(std::string* why) const;
};

struct StereoResult {
  bool ok = false;
  std::string message;                 ///< why not ok
  GroundGrid grid;                     ///< the finest mesh, in the ground frame
  Eigen::VectorXd heights;             ///< per vertex [m]; NaN = not observed
  Eigen::VectorXd information;         ///< per vertex, data term [1/m^2]
  Eigen::VectorXi pixels;              ///< per vertex, pixels in its triangles at level 0
  Eigen::Isometry3d ground_T_camera = Eigen::Isometry3d::Identity();  ///< left camera in G
  PhotometricParams photometric;       ///< left = gain * right + bias
  std::vector<AlignmentReport> reports;  ///< plane fit levels, then mesh levels
  double median_abs_residual_grey = 0.0;
  ObstacleMask obstacles;                ///< pixels excluded from the ground data term
  /// Per vertex: 1 obstacle (hidden by or under one), 0 ground seen, NaN unknown; and the
  /// obstacle's height above the surface [m] where 3-D obstacle points fell (NaN elsewhere).
  Eigen::VectorXd obstacle, obstacle_height;
  ObstacleEvidence obstacle_evidence;
  Eigen::VectorXi excluded_pixels;      ///< per vertex, obstacle pixels of its triangles at level 0
  StereoPairCheck pair_check;           ///< sparse matches of this pair (sanity, misalignment)
  VerticalMisalignment rectification;   ///< the misalignment modelled for this estimate
};

class StereoEstimator {
 public:
  StereoEstimator(const StereoRig& rig, const StereoEstimatorOptions& options);

  /// Full stereo mode on one pair (any accepted image type, see ImagePyramid).
  StereoResult estimate(const cv::Mat& left, const cv::Mat& right) const;
  StereoResult estimate(const ImagePyramid& left, const ImagePyramid& right) const;

  /// Only the start-up plane: returns ground_T_camera whose ground plane is the fitted plane, and
  /// the gain/bias estimate.
  /// `start` (optional): camera_T_ground of the first guess, instead of the nominal pose.
  bool fitGroundPlane(const ImagePyramid& left, const ImagePyramid& right, Eigen::Isometry3d* ground_T_camera,
                      PhotometricParams* photometric, std::vector<AlignmentReport>* reports,
                      std::string* message, const Eigen::Isometry3d* start = nullptr) const;

  /// camera_T_ground of a camera `height_m` above a plane whose unit normal toward it points
  /// along -down (camera frame): G's z along the plane's up, x along the optical axis projected.
  static Eigen::Isometry3d poseAbovePlane(const Eigen::Vector3d& down, double height_m);

  /// The disparity [px] the surface implies at every left pixel (0 where no surface), level 0.
  cv::Mat impliedDisparity(const StereoResult& result, const ImagePyramid& left) const;

  /// Inverse depth [1/m] of the surface (`heights` on `grid`, seen from camera_T_ground) at every
  /// pixel of `reference`'s pyramid level `level` (0 where no triangle in the working range).
  cv::Mat surfaceInverseDepth(const ImagePyramid& reference, const GroundGrid& grid, const Eigen::VectorXd& heights,
                              const Eigen::Isometry3d& camera_T_ground, int level) const;

  /// camera_T_ground of a camera at height h above the origin, looking along +x, pitched down.
  static Eigen::Isometry3d nominalCameraPose(double height_m, double pitch_down_rad, double roll_rad);
  /// The inverse of nominalCameraPose: the mount of a camera (optical frame: x right, y down, z
  /// forward) at `ground_T_camera` in a frame whose x-y plane is the ground and z points up (a
  /// robot's base_footprint, REP 103). Its yaw is dropped (the map's x axis is the camera's heading).
  static NominalMount nominalMount(const Eigen::Isometry3d& ground_T_camera);

  /// Gain/bias guess from the grey-level statistics of the rows that see the working range.
  PhotometricParams initialPhotometric(const ImagePyramid& left, const ImagePyramid& right,
                                       const Eigen::Isometry3d& camera_T_ground) const;

  const StereoRig& rig() const { return rig_; }
  const StereoEstimatorOptions& options() const { return options_; }

  /// The update-constraint weights of every vertex of `grid` as seen from camera_T_ground.
  Eigen::VectorXd updateWeights(const GroundGrid& grid, const Eigen::VectorXd& heights,
                                const Eigen::Isometry3d& camera_T_ground) const;

  /// Hierarchical meshing at mesh level `level` of `fine` (spacing 2^level s): the prolongation
  /// basis (empty matrix for level 0 or without hierarchy) and its update-constraint weights.
  void levelBasis(const GroundGrid& fine, int level, const Eigen::VectorXd& heights,
                  const Eigen::Isometry3d& camera_T_ground,
                  Eigen::SparseMatrix<double, Eigen::RowMajor>* basis, Eigen::VectorXd* weights) const;

  /// Occlusion reasoning: the pixels of `left` that see obstacles above the surface
  /// (`heights` on `grid`, seen from camera_T_ground).
  ObstacleMask detectObstacles(const ImagePyramid& left, const ImagePyramid& right, const GroundGrid& grid,
                               const Eigen::VectorXd& heights, const Eigen::Isometry3d& camera_T_ground,
                               const PhotometricParams& photometric) const;

  /// The stereo partner as an aligner target: the right camera at (baseline, offset y, 0) and the
  /// rectification's pixel correction (see VerticalMisalignment).
  AlignerTarget stereoTarget(const ImagePyramid& right, const VerticalMisalignment& m) const;
  /// right_T_left including the vertical offset that `m` models.
  Eigen::Isometry3d rightTLeft(const VerticalMisalignment& m) const;
  /// `m`, or zero when it is below min_rectification_correction_px or modelling is off.
  VerticalMisalignment modelled(const VerticalMisalignment& m) const;

  /// Sparse-match check of a pair at the monitor's level (see RectificationMonitor).
  StereoPairCheck checkPair(const ImagePyramid& left, const ImagePyramid& right) const;
  /// The same with the right image's rows shifted by the disparity of the ground the nominal mount
  /// expects (RectificationMonitor::measure's row_disparity): the start-up's second try when the
  /// matches hold no ground plane.
  StereoPairCheck checkPairAlongNominalGround(const ImagePyramid& left, const ImagePyramid& right) const;
  /// The ground plane of `check`'s matches (checkPair's of this pair) near the mounted attitude
  /// (nominal_max_tilt_rad); when they hold none, of the matches along the nominal ground. `used`
  /// (optional) gets the matches it came from; not ok: no ground in view (the plane's message).
  DisparityPlane groundPlane(const ImagePyramid& left, const ImagePyramid& right, const StereoPairCheck& check,
                             StereoPairCheck* used = nullptr) const;


  /// The misalignment to model from now on (the incremental mode's running estimate); until it is
  /// set, estimate() models the one its own pair's sparse matches show.
  void setRectification(const VerticalMisalignment& m) {
    rectification_ = m;
    rectification_set_ = true;
  }
  void clearRectification() { rectification_set_ = false; }
  bool rectificationSet() const { return rectification_set_; }
  const VerticalMisalignment& rectification() const { return rectification_; }

  /// Builds the pyramid a sequence's frames use for an input image (presmooth_sigma_px).
  ImagePyramid makePyramid(const cv::Mat& image,
                           ImagePyramid::ColorOrder order = ImagePyramid::ColorOrder::kBgr) const;
  /// Builds the pyramid of a one-pair run (stereo_presmooth_sigma_px).
  ImagePyramid makeStereoPyramid(const cv::Mat& image,
                                 ImagePyramid::ColorOrder order = ImagePyramid::ColorOrder::kBgr) const;
  int pyramidLevels() const;

 private:
  /// checkPair at the monitor's level, optionally along per-row disparities of that level.
  StereoPairCheck checkPairAtMatchLevel(const ImagePyramid& left, const ImagePyramid& right,
                                        const std::vector<float>* row_disparity) const;
  StereoResult estimateWith(const ImagePyramid& left, const ImagePyramid& right, const VerticalMisalignment& m,
                            const Eigen::Isometry3d* start) const;

  StereoRig rig_;
  StereoEstimatorOptions options_;
  VerticalMisalignment rectification_;
  bool rectification_set_ = false;
};

}  // namespace stereo_ground_dem
