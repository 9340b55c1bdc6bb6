#include "stereo_ground_dem/StereoEstimator.hpp"
#include "stereo_ground_dem/SurfaceIncidence.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace stereo_ground_dem {

SurfaceAlignerOptions StereoEstimatorOptions::alignerOptions() const {
  SurfaceAlignerOptions ao = aligner;
  ao.min_depth_m = min_range_m;
  ao.max_depth_m = max_range_m;
  ao.max_lateral_m = max_lateral_m;
  return ao;
}

bool StereoEstimatorOptions::isValid(std::string* why) const {
  auto bad = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(grid_resolution_m > 0.0)) return bad("grid_resolution_m must be > 0");
  if (mesh_levels < 1 || mesh_levels > 6) return bad("mesh_levels must be in 1..6");
  if (!(min_range_m > 0.0) || !(max_range_m > min_range_m)) return bad("need 0 < min_range_m < max_range_m");
  if (!(max_lateral_m > 0.0)) return bad("max_lateral_m must be > 0");
  if (!(nominal_height_m > 0.0)) return bad("nominal_height_m must be > 0");
  if (!(nominal_max_tilt_rad >= 0.0 && nominal_max_tilt_rad < 1.5)) return bad("nominal_max_tilt_rad must be in [0, 1.5)");
  if (!(std::abs(nominal_pitch_down_rad) < 1.2)) return bad("nominal_pitch_down_rad must be within +-1.2 rad");
  if (!(plane_fit_min_range_m > 0.0) || !(plane_fit_max_range_m > plane_fit_min_range_m)) {
    return bad("need 0 < plane_fit_min_range_m < plane_fit_max_range_m");
  }
  if (plane_fit_finest_level < 0 || plane_fit_coarsest_level < plane_fit_finest_level) {
    return bad("need 0 <= plane_fit_finest_level <= plane_fit_coarsest_level");
  }
  if (!(update_weight >= 0.0) || !(update_reference_depth_m > 0.0)) {
    return bad("update_weight must be >= 0 and update_reference_depth_m > 0");
  }
  if (iterations_per_level < 1) return bad("iterations_per_level must be >= 1");
  if (!(presmooth_sigma_px >= 0.0) || !(stereo_presmooth_sigma_px >= 0.0) || !(presmooth_sigma_px < 100.0) ||
      !(stereo_presmooth_sigma_px < 100.0))
    return bad("presmooth_sigma_px and stereo_presmooth_sigma_px must be in [0, 100)");
  if (!(hidden_pixel_ratio >= 0.0) || min_ground_pixels < 1) return bad("need hidden_pixel_ratio >= 0 and min_ground_pixels >= 1");
  if (!(min_incidence_ratio >= 0.0) || !(min_incidence_ratio < 1.0)) return bad("min_incidence_ratio must be in [0, 1)");
  std::string w;
  if (!aligner.isValid(&w)) return bad("aligner: " + w);
  if (!obstacles.isValid(&w)) return bad("obstacles: " + w);
  if (!rectification.isValid(&w)) return bad("rectification: " + w);
  if (!(min_rectification_correction_px >= 0.0)) return bad("min_rectification_correction_px must be >= 0");
  return true;
}

Eigen::Vector3d StereoEstimatorOptions::nominalDown() const {
  return StereoEstimator::nominalCameraPose(1.0, nominal_pitch_down_rad, nominal_roll_rad).linear() *
         -Eigen::Vector3d::UnitZ();
}

DisparityPlaneFitOptions StereoEstimatorOptions::nearNominalAttitude(const DisparityPlaneFitOptions& plane) const {
  return nominal_max_tilt_rad > 0.0 ? plane.nearAttitude(nominalDown(), nominal_max_tilt_rad) : plane;
}

StereoEstimator::StereoEstimator(const StereoRig& rig, const StereoEstimatorOptions& options)
    : rig_(rig), options_(options) {
  std::string why;
  if (!rig_.isValid(&why)) throw std::invalid_argument("StereoEstimator: rig: " + why);
  if (!options_.isValid(&why)) throw std::invalid_argument("StereoEstimatorOptions: " + why);
}

Eigen::Isometry3d StereoEstimator::nominalCameraPose(double height_m, double pitch_down_rad, double roll_rad) {
  Eigen::Matrix3d optical_to_ground;
  optical_to_ground << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  Eigen::Isometry3d ground_T_camera = Eigen::Isometry3d::Identity();
  ground_T_camera.linear() = (Eigen::AngleAxisd(pitch_down_rad, Eigen::Vector3d::UnitY()) *
                              Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
                                 .toRotationMatrix() *
                             optical_to_ground;
  ground_T_camera.translation() = Eigen::Vector3d(0.0, 0.0, height_m);
  return ground_T_camera.inverse();
}

NominalMount StereoEstimator::nominalMount(const Eigen::Isometry3d& ground_T_camera) {
  Eigen::Matrix3d optical_to_ground;
  optical_to_ground << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  // ground_T_camera's rotation = Rz(yaw) Ry(pitch) Rx(roll) optical_to_ground (nominalCameraPose's,
  // turned by a yaw): the last row of Rz Ry Rx is (-sin pitch, cos pitch sin roll, cos pitch cos roll).
  const Eigen::Matrix3d m = ground_T_camera.linear() * optical_to_ground.transpose();
  NominalMount mount;
  mount.height_m = ground_T_camera.translation().z();
  mount.pitch_down_rad = std::asin(std::clamp(-m(2, 0), -1.0, 1.0));
  mount.roll_rad = std::atan2(m(2, 1), m(2, 2));
  return mount;
}

Eigen::VectorXd StereoEstimator::updateWeights(const GroundGrid& grid, const Eigen::VectorXd& heights,
                                               const Eigen::Isometry3d& camera_T_ground) const {
  Eigen::VectorXd mu(grid.vertexCount());
  for (int v = 0; v < grid.vertexCount(); ++v) {
    const Eigen::Vector2d xy = grid.position(v);
    const double h = std::isfinite(heights[v]) ? heights[v] : 0.0;
    const double depth = std::max(0.0, (camera_T_ground * Eigen::Vector3d(xy.x(), xy.y(), h)).z());
    const double r = depth / options_.update_reference_depth_m;
    mu[v] = options_.update_weight * (1.0 + r * r);
  }
  return mu;
}

PhotometricParams StereoEstimator::initialPhotometric(const ImagePyramid& left, const ImagePyramid& right,
                                                      const Eigen::Isometry3d& camera_T_ground) const {
  // Rows that see the ground between the near and far range, from the nominal geometry.
  auto rowOf = [&](double range) {
    const Eigen::Vector3d xc = camera_T_ground * Eigen::Vector3d(range, 0.0, 0.0);
    return rig_.fy * xc.y() / std::max(xc.z(), 1e-3) + rig_.cy;
  };
  const cv::Mat& l = left.level(0).image;
  const int v0 = std::clamp(static_cast<int>(rowOf(options_.max_range_m)), 0, l.rows - 1);
  const int v1 = std::clamp(static_cast<int>(rowOf(options_.min_range_m)), v0 + 1, l.rows);
  double ml, sl, mr, sr;
  left.rowRangeStats(v0, v1, &ml, &sl);
  right.rowRangeStats(v0, v1, &mr, &sr);
  PhotometricParams p;
  if (sr > 1.0 && sl > 1.0) {
    p.gain = std::clamp(sl / sr, 0.25, 4.0);
    p.bias_grey = ml - p.gain * mr;
  }
  return p;
}

bool StereoEstimator::fitGroundPlane(const ImagePyramid& left, const ImagePyramid& right,
                                     Eigen::Isometry3d* ground_T_camera, PhotometricParams* photometric,
                                     std::vector<AlignmentReport>* reports, std::string* message,
                                     const Eigen::Isometry3d* start) const {
  const StereoEstimatorOptions& o = options_;
  const Eigen::Isometry3d camera_T_ground0 =
      start ? *start : nominalCameraPose(o.nominal_height_m, o.nominal_pitch_down_rad, o.nominal_roll_rad);
  const double res = std::max(1.0, o.grid_resolution_m);
  const GroundGrid grid = GroundGrid::covering(0.0, o.plane_fit_max_range_m / std::cos(std::min(0.5, std::abs(o.nominal_pitch_down_rad))) + 2.0 * res,
                                               -o.max_lateral_m, o.max_lateral_m, res);
  // heights = p x + q y + c: the basis [x y 1]
  std::vector<Eigen::Triplet<double>> trip;
  for (int v = 0; v < grid.vertexCount(); ++v) {
    const Eigen::Vector2d xy = grid.position(v);
    trip.emplace_back(v, 0, xy.x());
    trip.emplace_back(v, 1, xy.y());
    trip.emplace_back(v, 2, 1.0);
  }
  Eigen::SparseMatrix<double, Eigen::RowMajor> basis(grid.vertexCount(), 3);
  basis.setFromTriplets(trip.begin(), trip.end());

  SurfaceAlignerOptions ao = o.aligner;
  ao.min_depth_m = o.plane_fit_min_range_m;
  ao.max_depth_m = o.plane_fit_max_range_m;
  ao.max_lateral_m = o.max_lateral_m;
  ao.estimate_motion = false;
  ao.smoothness_weight = 0.0;  // a plane has no curvature
  ao.max_iterations = std::max(ao.max_iterations, 10);
  const SurfaceAligner aligner(ao);

  SurfaceState state;
  state.camera_T_ground = camera_T_ground0;
  state.heights = Eigen::VectorXd::Zero(grid.vertexCount());
  state.photometric = {initialPhotometric(left, right, camera_T_ground0)};
  const AlignerTarget target = stereoTarget(right, rectification_);
  AlignmentProblem prob;
  prob.reference = &left;
  prob.rig = &rig_;
  prob.grid = &grid;
  prob.targets = {target};
  prob.basis = &basis;
  prob.update_weight = Eigen::Vector3d(1e2, 1e2, 1e0);  // mild damping of (p, q, c)
  const int coarsest = std::min(o.plane_fit_coarsest_level, left.levels() - 1);
  for (int l = coarsest; l >= std::min(o.plane_fit_finest_level, coarsest); --l) {
    prob.level = l;
    const AlignmentReport rep = aligner.align(prob, state);
    if (reports) reports->push_back(rep);
    if (rep.valid_pixels < 200) {
      if (message) {
        std::ostringstream os;
        os << "start-up plane fit: only " << rep.valid_pixels << " usable ground pixels at pyramid level " << l
           << " (is the camera looking at the ground? check nominal_height_m/nominal_pitch_down_rad)";
        *message = os.str();
      }
      return false;
    }
  }
  // The fitted plane z = p x + q y + c in the start-up frame (heights stay in the basis' span).
  Eigen::MatrixXd a(grid.vertexCount(), 3);
  for (int v = 0; v < grid.vertexCount(); ++v) a.row(v) << grid.position(v).x(), grid.position(v).y(), 1.0;
  const Eigen::Vector3d pqc = a.colPivHouseholderQr().solve(state.heights);
  Eigen::Vector3d n(-pqc.x(), -pqc.y(), 1.0);
  const double norm = n.norm();
  n /= norm;
  const double offset = pqc.z() / norm;  // n . X = offset on the plane
  const Eigen::Isometry3d g0_T_c = camera_T_ground0.inverse();
  const Eigen::Vector3d c = g0_T_c.translation();
  const double height = n.dot(c) - offset;
  const double tilt = std::acos(std::min(1.0, n.z()));
  if (!(height > 0.1 && height < 20.0) || !(tilt < 0.5) || !pqc.allFinite()) {
    if (message) {
      std::ostringstream os;
      os << "start-up plane fit diverged (camera height " << height << " m, tilt " << tilt
         << " rad from the nominal plane)";
      *message = os.str();
    }
    return false;
  }
  const Eigen::Vector3d foot = c - height * n;
  Eigen::Vector3d xaxis = g0_T_c.linear().col(2);
  xaxis -= n * n.dot(xaxis);
  xaxis.normalize();
  const Eigen::Vector3d yaxis = n.cross(xaxis);
  Eigen::Isometry3d g_T_g0 = Eigen::Isometry3d::Identity();
  g_T_g0.linear().row(0) = xaxis.transpose();
  g_T_g0.linear().row(1) = yaxis.transpose();
  g_T_g0.linear().row(2) = n.transpose();
  g_T_g0.translation() = -(g_T_g0.linear() * foot);
  *ground_T_camera = g_T_g0 * g0_T_c;
  *photometric = state.photometric[0];
  return true;
}

StereoResult StereoEstimator::estimate(const cv::Mat& left, const cv::Mat& right) const {
  if (left.size() != right.size()) {
    StereoResult r;
    std::ostringstream os;
    os << "left and right images differ in size (" << left.cols << "x" << left.rows << " vs " << right.cols << "x"
       << right.rows << ")";
    r.message = os.str();
    return r;
  }
  return estimate(makeStereoPyramid(left), makeStereoPyramid(right));
}

int StereoEstimator::pyramidLevels() const {
  return std::max(options_.mesh_levels, options_.plane_fit_coarsest_level + 1);
}

ImagePyramid StereoEstimator::makePyramid(const cv::Mat& image, ImagePyramid::ColorOrder order) const {
  return ImagePyramid(image, pyramidLevels(), order, options_.presmooth_sigma_px);
}

ImagePyramid StereoEstimator::makeStereoPyramid(const cv::Mat& image, ImagePyramid::ColorOrder order) const {
  return ImagePyramid(image, pyramidLevels(), order, options_.stereo_presmooth_sigma_px);
}

void StereoEstimator::levelBasis(const GroundGrid& fine, int level, const Eigen::VectorXd& heights,
                                 const Eigen::Isometry3d& camera_T_ground,
                                 Eigen::SparseMatrix<double, Eigen::RowMajor>* basis, Eigen::VectorXd* weights) const {
  if (options_.use_hierarchy && level > 0) {
    const GroundGrid coarse = fine.coarsened(1 << level);
    *basis = fine.prolongationFrom(coarse);
    Eigen::VectorXd zc(coarse.vertexCount());
    for (int r = 0; r < coarse.rows; ++r)
      for (int c = 0; c < coarse.cols; ++c) zc[coarse.index(r, c)] = heights[fine.index(r << level, c << level)];
    *weights = updateWeights(coarse, zc, camera_T_ground);
  } else {
    *basis = Eigen::SparseMatrix<double, Eigen::RowMajor>();
    *weights = updateWeights(fine, heights, camera_T_ground);
  }
}

StereoResult StereoEstimator::estimate(const ImagePyramid& left, const ImagePyramid& right) const {
  const StereoEstimatorOptions& o = options_;
  StereoResult res;
  if (left.width() != right.width() || left.height() != right.height()) {
    res.message = "left and right images differ in size";
    return res;
  }
  if ((rig_.width > 0 && rig_.width != left.width()) || (rig_.height > 0 && rig_.height != left.height())) {
    std::ostringstream os;
    os << "image size " << left.width() << "x" << left.height() << " does not match the calibration ("
       << rig_.width << "x" << rig_.height << ")";
    res.message = os.str();
    return res;
  }
  if (left.levels() < o.mesh_levels || right.levels() < o.mesh_levels) {
    res.message = "image pyramids have fewer levels than mesh_levels";
    return res;
  }
  const StereoPairCheck check = checkPair(left, right);
  if (!check.ok()) {
    res.pair_check = check;
    res.message = check.problem;
    return res;
  }
  StereoPairCheck used;
  const DisparityPlane plane = groundPlane(left, right, check, &used);
  if (!plane.ok) {
    res.pair_check = check;
    res.message = "no ground in view: " + plane.message;
    return res;
  }
  const Eigen::Isometry3d start = poseAbovePlane(plane.down, plane.height_m);
  StereoResult res2 = estimateWith(left, right, modelled(rectification_set_ ? rectification_ : used.fit), &start);
  res2.pair_check = used;
  return res2;
}

DisparityPlane StereoEstimator::groundPlane(const ImagePyramid& left, const ImagePyramid& right,
                                            const StereoPairCheck& check, StereoPairCheck* used) const {
  const DisparityPlaneFit plane_fit(options_.nearNominalAttitude(options_.ground_plane));
  const DisparityPlane plane = plane_fit.fit(check.points, rig_);
  if (used) *used = check;
  if (plane.ok) return plane;
  // Matched again along the ground the mount expects: from a low camera the near ground's
  // disparity changes too fast per row for the plain windows (docs/results.md, "A low camera's
  // start-up matches").
  const StereoPairCheck along = checkPairAlongNominalGround(left, right);
  DisparityPlane second = along.ok() ? plane_fit.fit(along.points, rig_) : DisparityPlane();
  if (!second.ok) return plane;  // (the first try's message)
  if (used) *used = along;
  return second;
}

Eigen::Isometry3d StereoEstimator::poseAbovePlane(const Eigen::Vector3d& down, double height_m) {
  const Eigen::Vector3d up = -down.normalized();          // G's z in the camera frame
  Eigen::Vector3d xaxis = Eigen::Vector3d::UnitZ() - up * up.z();  // optical axis on the plane
  if (xaxis.norm() < 1e-6) xaxis = Eigen::Vector3d::UnitX();
  xaxis.normalize();
  const Eigen::Vector3d yaxis = up.cross(xaxis);
  Eigen::Isometry3d camera_T_ground = Eigen::Isometry3d::Identity();
  camera_T_ground.linear().col(0) = xaxis;
  camera_T_ground.linear().col(1) = yaxis;
  camera_T_ground.linear().col(2) = up;
  // the camera centre is height_m above the origin: camera_T_ground * (0, 0, h) = 0
  camera_T_ground.translation() = -height_m * up;
  return camera_T_ground;
}

StereoResult StereoEstimator::estimateWith(const ImagePyramid& left, const ImagePyramid& right,
                                           const VerticalMisalignment& m, const Eigen::Isometry3d* start) const {
  const StereoEstimatorOptions& o = options_;
  StereoResult res;
  res.rectification = m;
  StereoEstimator local = *this;  // fitGroundPlane models the estimator's own misalignment
  local.rectification_ = m;
  if (!local.fitGroundPlane(left, right, &res.ground_T_camera, &res.photometric, &res.reports, &res.message, start)) {
    return res;
  }

  const int top = o.mesh_levels - 1;
  const int align = 1 << top;
  res.grid = GroundGrid::covering(0.0, o.max_range_m + 2.0 * o.grid_resolution_m, -o.max_lateral_m - 1.0,
                                  o.max_lateral_m + 1.0, o.grid_resolution_m, align);
  SurfaceState state;
  state.camera_T_ground = res.ground_T_camera.inverse();
  state.heights = Eigen::VectorXd::Zero(res.grid.vertexCount());
  state.photometric = {res.photometric};

  SurfaceAlignerOptions ao = o.alignerOptions();
  ao.estimate_motion = false;
  ao.max_iterations = o.iterations_per_level;
  const SurfaceAligner aligner(ao);

  const AlignerTarget target = stereoTarget(right, res.rectification);
  res.obstacles = detectObstacles(left, right, res.grid, state.heights, state.camera_T_ground, res.photometric);
  AlignmentProblem prob;
  prob.reference = &left;
  prob.rig = &rig_;
  prob.grid = &res.grid;
  prob.targets = {target};
  prob.excluded = &res.obstacles.excluded;
  AlignmentReport last;
  for (int l = top; l >= 0; --l) {
    prob.level = l;
    Eigen::SparseMatrix<double, Eigen::RowMajor> basis;
    levelBasis(res.grid, l, state.heights, state.camera_T_ground, &basis, &prob.update_weight);
    prob.basis = basis.size() > 0 ? &basis : nullptr;
    last = aligner.align(prob, state);
    res.reports.push_back(last);
    if (last.degenerate) {
      res.message = "normal equations degenerate at mesh level " + std::to_string(l);
      return res;
    }
  }
  res.heights = state.heights;
  res.information = last.vertex_information;
  res.pixels = last.vertex_pixels;
  res.excluded_pixels = last.vertex_excluded_pixels;
  const Eigen::Vector3d camera_position = res.ground_T_camera.translation();
  res.obstacle_evidence = ObstacleDetector::evidence(
      res.grid, state.heights, res.pixels, res.excluded_pixels, res.obstacles.groundPoints(rig_, res.ground_T_camera),
      o.hidden_pixel_ratio, o.min_ground_pixels, o.obstacles.min_obstacle_height_m, o.obstacles.hidden_body_depth_m, 2,
      o.obstacles.hidden_body_along_ray ? &camera_position : nullptr);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  res.obstacle = Eigen::VectorXd::Constant(res.grid.vertexCount(), nan);
  res.obstacle_height = res.obstacle_evidence.height;
  // seen along its rays (min_incidence_ratio): not measured by its pixels
  const Eigen::VectorXd incidence =
      o.min_incidence_ratio > 0.0 ? SurfaceIncidence::ratios(res.grid, state.heights, res.ground_T_camera.translation())
                                  : Eigen::VectorXd();
  for (int v = 0; v < res.grid.vertexCount(); ++v) {
    const bool hit = res.obstacle_evidence.hit[static_cast<size_t>(v)];
    if (hit) res.obstacle[v] = 1.0;
    else if (res.obstacle_evidence.ground[static_cast<size_t>(v)]) res.obstacle[v] = 0.0;
    // unseen, weakly seen or hidden ground stays unknown rather than invented
    // (too few textured pixels: also too few pixels, they are a subset)
    if (hit || res.obstacle_evidence.hidden[static_cast<size_t>(v)] || last.vertex_textured_pixels[v] < o.min_ground_pixels ||
        (incidence.size() > 0 && incidence[v] < o.min_incidence_ratio)) {
      res.heights[v] = nan;
    }
  }
  res.photometric = state.photometric[0];
  res.median_abs_residual_grey = last.median_abs_residual_grey;
  res.ok = true;
  return res;
}

Eigen::Isometry3d StereoEstimator::rightTLeft(const VerticalMisalignment& m) const {
  return Eigen::Translation3d(-rig_.baseline_m, -m.rightCameraOffsetY(rig_), 0.0) * Eigen::Isometry3d::Identity();
}

AlignerTarget StereoEstimator::stereoTarget(const ImagePyramid& right, const VerticalMisalignment& m) const {
  AlignerTarget target;
  target.pyramid = &right;
  target.rig_fixed = true;
  target.target_T_reference = rightTLeft(m);
  target.row_shift_px = m.row_shift_px;
  return target;
}

VerticalMisalignment StereoEstimator::modelled(const VerticalMisalignment& m) const {
  if (!options_.model_rectification) return VerticalMisalignment();
  StereoRig r = rig_;
  if (r.width <= 0 || r.height <= 0) {  // size unknown: the principal point as the half size
    r.width = static_cast<int>(2.0 * r.cx + 1.0);
    r.height = static_cast<int>(2.0 * r.cy + 1.0);
  }
  if (!(m.maxAbsPx(r, options_.rectification.max_disparity_px) >= options_.min_rectification_correction_px)) {
    return VerticalMisalignment();
  }
  return m;
}

StereoPairCheck StereoEstimator::checkPairAtMatchLevel(const ImagePyramid& left, const ImagePyramid& right,
                                                       const std::vector<float>* row_disparity) const {
  const int l = std::min(options_.rectification.match_level, left.levels() - 1);
  RectificationMonitorOptions o = options_.rectification;
  o.match_level = l;
  return RectificationMonitor(o).measure(left.level(l).image, right.level(l).image, rig_, row_disparity);
}

StereoPairCheck StereoEstimator::checkPair(const ImagePyramid& left, const ImagePyramid& right) const {
  return checkPairAtMatchLevel(left, right, nullptr);
}

StereoPairCheck StereoEstimator::checkPairAlongNominalGround(const ImagePyramid& left, const ImagePyramid& right) const {
  const int l = std::min(options_.rectification.match_level, left.levels() - 1);
  // The nominal ground n . X = h in the camera (n its down direction): at pixel (u, v) the
  // disparity is fx * baseline * n . K^-1 (u, v, 1) / h, taken at the principal column.
  const Eigen::Vector3d down = options_.nominalDown();
  const double scale = std::ldexp(1.0, l);
  const int rows = left.level(l).image.rows;
  std::vector<float> row_disparity(static_cast<size_t>(rows), 0.0f);
  for (int v = 0; v < rows; ++v) {
    const double v0 = scale * v;
    const double n_ray = down.y() * (v0 - rig_.cy) / rig_.fy + down.z();
    const double d0 = rig_.fx * rig_.baseline_m * n_ray / options_.nominal_height_m;
    row_disparity[static_cast<size_t>(v)] = static_cast<float>(std::max(0.0, d0) / scale);
  }
  return checkPairAtMatchLevel(left, right, &row_disparity);
}

ObstacleMask StereoEstimator::detectObstacles(const ImagePyramid& left, const ImagePyramid& right,
                                              const GroundGrid& grid, const Eigen::VectorXd& heights,
                                              const Eigen::Isometry3d& camera_T_ground,
                                              const PhotometricParams& photometric) const {
  ObstacleDetectorOptions oo = options_.obstacles;
  oo.camera_height_m = std::max(options_.nominal_height_m, oo.min_obstacle_height_m + 0.1);
  oo.level = std::min(oo.level, left.levels() - 1);
  oo.num_threads = options_.aligner.num_threads;
  const ObstacleDetector detector(oo);
  cv::Mat rho = surfaceInverseDepth(left, grid, heights, camera_T_ground, oo.level);
  // Beyond the mesh (farther than max_range_m or wider than max_lateral_m) the ground hypothesis
  // is the level plane z = 0 of the ground frame: an obstacle near the mesh's far edge rises
  // into image rows whose ground lies beyond it, and must be tested there too.
  const StereoRig r = rig_.atLevel(oo.level);
  const Eigen::Vector3d n = camera_T_ground.linear().col(2);  // ground z axis in the camera
  const double nt = n.dot(camera_T_ground.translation());    // = -camera height above z = 0
  if (nt < 0.0) {
    for (int v = 0; v < rho.rows; ++v) {
      float* p = rho.ptr<float>(v);
      for (int u = 0; u < rho.cols; ++u) {
        if (p[u] > 0.0f) continue;
        const Eigen::Vector3d m((u - r.cx) / r.fx, (v - r.cy) / r.fy, 1.0);
        const double inv_z = n.dot(m) / nt;
        if (inv_z > 0.0 && inv_z < 1.0 / options_.max_range_m) p[u] = static_cast<float>(inv_z);
      }
    }
  }
  return detector.detect(left, right, rig_, photometric, rho);
}

cv::Mat StereoEstimator::surfaceInverseDepth(const ImagePyramid& reference, const GroundGrid& grid,
                                             const Eigen::VectorXd& heights, const Eigen::Isometry3d& camera_T_ground,
                                             int level) const {
  AlignmentProblem prob;
  prob.reference = &reference;
  prob.rig = &rig_;
  prob.grid = &grid;
  prob.level = level;
  SurfaceState state;
  state.camera_T_ground = camera_T_ground;
  state.heights = heights;
  return SurfaceAligner(options_.alignerOptions()).renderInverseDepth(prob, state);
}

cv::Mat StereoEstimator::impliedDisparity(const StereoResult& result, const ImagePyramid& left) const {
  if (!result.ok) return cv::Mat::zeros(left.height(), left.width(), CV_32F);
  return surfaceInverseDepth(left, result.grid, result.heights, result.ground_T_camera.inverse(), 0) *
         rig_.disparityTimesDepth();
}

}  // namespace stereo_ground_dem
