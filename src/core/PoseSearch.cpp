#include "stereo_ground_dem/PoseSearch.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "stereo_ground_dem/Se3.hpp"

namespace stereo_ground_dem {

std::vector<int> pairSlots(bool temporal, bool cross) {
  if (!temporal) return {0};
  if (!cross) return {0, 1};
  return {0, 1, 2};
}

PoseSearch::PoseSearch(const PoseSearchOptions& options, const PoseSearchContext& context)
    : options_(options), c_(context) {
  if (!c_.rig || !c_.stereo || !c_.map || !c_.predictor || !c_.prev_left || !c_.prev_right) {
    throw std::invalid_argument("PoseSearch: the context needs the rig, stereo estimator, map view, predictor and previous images");
  }
}

PhotometricParams PoseSearch::statsPhotometric(const ImagePyramid& ref, const ImagePyramid& other,
                                               const Eigen::Isometry3d& camera_T_ground) const {
  return c_.stereo->initialPhotometric(ref, other, camera_T_ground);
}

std::vector<Eigen::Isometry3d> PoseSearch::rankedStarts(const ImagePyramid& left, double stamp_s,
                                                        const std::vector<cv::Mat>& skipped) const {
  // Score every pose of the search grid by its photometric cost alone (no iteration) against the
  // previous left image at the coarsest level; far from the minimum the robust cost is too flat
  // for Gauss-Newton to walk the whole way (measured on KITTI: it stalls at 0.3 m of a 1.2 m step).
  const MotionPredictor& predictor = *c_.predictor;
  const MapView& map = *c_.map;
  SurfaceAlignerOptions ao = options_.aligner;
  ao.max_iterations = 0;  // cost only
  ao.estimate_motion = false;
  const SurfaceAligner aligner(ao);
  AlignerTarget prev;
  prev.pyramid = c_.prev_left;
  prev.rig_fixed = false;
  prev.target_T_ground = c_.prev_camera_T_ground;
  prev.estimate_photometric = false;
  if (!skipped.empty()) prev.reference_excluded = &skipped;
  AlignmentProblem prob;
  prob.reference = &left;
  prob.rig = c_.rig;
  prob.level = std::min(options_.search_level, left.levels() - 1);
  prob.targets = {prev};
  prob.estimate_heights = false;
  const std::vector<Eigen::Isometry3d> grid = predictor.searchGrid(stamp_s);
  GroundGrid window = map.window(predictor.lastPose());
  Eigen::VectorXd heights, info;
  map.initialHeights(window, predictor.lastPose(), &heights, &info);
  // The photometric cost of a pose per sample (comparable across overlaps); infinite without any.
  const auto score = [&](const Eigen::Isometry3d& pose) {
    const GroundGrid w = map.window(pose);
    if (!w.sameLayout(window)) {
      window = w;
      map.initialHeights(window, pose, &heights, &info);
    }
    prob.grid = &window;
    SurfaceState s;
    s.camera_T_ground = pose;
    s.heights = heights;
    s.photometric = {statsPhotometric(left, *c_.prev_left, pose)};
    const AlignmentReport rep = aligner.align(prob, s);
    const int samples = rep.valid_pixels + rep.outside_pixels;
    return samples > 0 ? rep.initial_cost / samples : std::numeric_limits<double>::infinity();
  };
  std::vector<double> cost(grid.size());
  for (size_t i = 0; i < grid.size(); ++i) cost[i] = score(grid[i]);
  // The candidates are the local minima of the cost along the step (the cheapest heading at each
  // step), best first, not the best poses overall: those are neighbours of one minimum. Without a
  // velocity and after a long gap, the cheapest step is often near zero: far ground and everything
  // above it barely change there, while the true step's minimum is only local (KITTI raw 0013,
  // every 3rd / 4th frame: 3.6 m / 4.9 m steps, the global minimum at 0.4 m). The pre-alignment
  // of every candidate then picks the one that aligns best.
  const size_t rows = std::max<size_t>(1, predictor.options().search_yaw_rad.size());
  const size_t n = grid.size() / rows;  // searchGrid: yaw-major, steps in increasing order
  std::vector<std::pair<double, size_t>> best_of_step;  // (cost, index into poses) per step
  std::vector<Eigen::Isometry3d> poses = grid;
  for (size_t j = 0; j < n; ++j) {
    std::pair<double, size_t> b{std::numeric_limits<double>::infinity(), j};
    for (size_t r = 0; r < rows; ++r) b = std::min(b, std::make_pair(cost[r * n + j], r * n + j));
    best_of_step.push_back(b);
  }
  // The camera's pitch may have changed too (a bump, rough ground: 2-3 deg between frames): a
  // uniform vertical shift of the image that no forward step explains, so the true step is no
  // minimum without it (the rendered bouncing drive, seed 2: a 0.7 m step found as 1.6 m). Each
  // step's best heading is tried pitched by search_pitch_rad as well.
  for (size_t j = 0; j < n; ++j) {
    if (!std::isfinite(best_of_step[j].first)) continue;
    const Eigen::Isometry3d base = poses[best_of_step[j].second];
    for (double pitch : predictor.options().search_pitch_rad) {
      Vector6d xi = Vector6d::Zero();
      xi[3] = pitch;
      const Eigen::Isometry3d pose = Se3::exp(xi) * base;
      const double c = score(pose);
      if (c < best_of_step[j].first) {
        best_of_step[j] = {c, poses.size()};
        poses.push_back(pose);
      }
    }
  }
  std::vector<std::pair<double, size_t>> minima;
  for (size_t j = 0; j < n; ++j) {
    const double c = best_of_step[j].first;
    if (!std::isfinite(c)) continue;
    if ((j == 0 || c <= best_of_step[j - 1].first) && (j + 1 == n || c <= best_of_step[j + 1].first)) {
      minima.push_back(best_of_step[j]);
    }
  }
  std::sort(minima.begin(), minima.end());
  std::vector<Eigen::Isometry3d> out;
  for (size_t k = 0; k < minima.size() && static_cast<int>(out.size()) < options_.search_candidates; ++k) {
    out.push_back(poses[minima[k].second]);
  }
  if (out.empty()) out.push_back(predictor.lastPose());
  return out;
}

// 1. Motion only, at a coarse level, against the known surface, from the starting poses in
// order until one aligns about as well as the usual frame (hypothesis_accept_ratio): a wide
// basin for sudden pitch and roll changes (a bump, a pothole) that a constant velocity does not
// predict. The cheapest result is kept.
Prealignment PoseSearch::prealign(PrealignRequest q) const {
  const ImagePyramid& pl = *q.left;
  const ImagePyramid& pr = *q.right;
  std::vector<Eigen::Isometry3d>& starts = q.starts;
  size_t anchored_index = q.anchored_index;
  const MotionPredictor& predictor = *c_.predictor;
  const MapView& map = *c_.map;
  Prealignment out;
  GroundGrid& window = out.window;
  Eigen::VectorXd* heights = &out.heights;
  Eigen::VectorXd* info = &out.information;
  window = map.window(starts.front());
  map.initialHeights(window, starts.front(), heights, info);
  SurfaceState state;
  state.heights = *heights;
  const Eigen::Isometry3d predicted = starts.front();  // camera_T_ground
  bool anchored_tried = !predictor.velocityKnown();
  SurfaceAlignerOptions pre = options_.aligner;
  pre.estimate_motion = true;
  pre.max_iterations = options_.prealign_iterations;
  const SurfaceAligner aligner(pre);
  // With a velocity, the attitude and scale steps are screened with fewer iterations, and only
  // a winner among them gets the rest (on hard ground all of them are tried every frame).
  const int screen_iterations = options_.prealign_screen_iterations;
  SurfaceAlignerOptions pre_screen = pre;
  pre_screen.max_iterations = screen_iterations;
  const SurfaceAligner screen_aligner(pre_screen);
  bool chosen_screened = false;
  AlignmentProblem prob;
  prob.reference = &pl;
  prob.rig = c_.rig;
  prob.grid = &window;
  prob.level = std::min(options_.prealign_level, pl.levels() - 1);
  const std::vector<int> slots = pairSlots(true, options_.use_cross_temporal_pair);
  for (int sl : slots) prob.targets.push_back(q.targets[static_cast<size_t>(sl)]);
  prob.estimate_heights = false;
  double best = std::numeric_limits<double>::infinity();
  size_t chosen = 0;
  bool good = false;
  // Without a velocity (the first tracked frame, after a failure: rare) every start is tried;
  // with one, the first good one ends the search.
  const bool try_all = !predictor.velocityKnown();
  // Whether any start's alignment accepted a step, and the first start's result: when none moved
  // (under an overpass with an earlier frame in the sun, say: no global gain and bias explains
  // the change, every step raises the cost) the costs compare starting points the images cannot
  // tell apart, and the prediction is kept rather than the cheapest of them.
  bool any_moved = false;
  double first_cost = std::numeric_limits<double>::infinity();
  SurfaceState first_state;
  for (size_t k = 0; k < starts.size() && (try_all || !good); ++k) {
    if (k == 2 && !anchored_tried) {
      // The constant-velocity starts did not align: the attitude the ground itself shows.
      anchored_tried = true;
      Eigen::Isometry3d anchored;
      if (map.groundAnchoredPose(c_.stereo->checkPair(pl, pr), starts[1], &anchored)) {
        starts.insert(starts.begin() + 2, anchored);
        anchored_index = 2;
      }
    }
    // A start far from the first (a wrong stamp's unscaled step) sees another part of the map.
    const GroundGrid start_window = map.window(starts[k]);
    if (!start_window.sameLayout(window)) {
      window = start_window;
      map.initialHeights(window, starts[k], heights, info);
    }
    SurfaceState s;
    s.camera_T_ground = starts[k];
    s.heights = *heights;
    const std::vector<PhotometricParams> photo3 = {statsPhotometric(pl, pr, starts[k]),
                                                   statsPhotometric(pl, *c_.prev_left, starts[k]),
                                                   statsPhotometric(pl, *c_.prev_right, starts[k])};
    for (int sl : slots) s.photometric.push_back(photo3[static_cast<size_t>(sl)]);
    const bool screened = screen_iterations > 0 && screen_iterations < pre.max_iterations && !try_all && k >= 2 &&
                          k != anchored_index;
    const AlignmentReport rep = (screened ? screen_aligner : aligner).align(prob, s);
    out.reports.push_back(rep);
    const int samples = rep.valid_pixels + rep.outside_pixels;
    double cost = samples > 0 ? rep.final_cost / samples : std::numeric_limits<double>::infinity();
    // With a velocity, another start's alignment must end within the acceleration bound of the
    // prediction too. The hypotheses are attitude and scale steps around it; one that ends
    // metres away has walked the ground out of view (a camera pitched up at the bottom of a
    // ditch, 30 rows of ground: every pixel fewer lowers the cost) and is no candidate.
    if (predictor.velocityKnown() && k > 0 && std::isfinite(cost) &&
        (s.camera_T_ground.inverse().translation() - predicted.inverse().translation()).norm() > q.max_shift_m) {
      cost = std::numeric_limits<double>::infinity();
      ++out.discarded;
    }
    any_moved = any_moved || rep.accepted_steps > 0;
    if (k == 0) first_cost = cost;
    // Good enough: the cost per sample near the usual one of good frames (unknown on the first
    // tracked frames: then the first two starts are tried, or all without a velocity).
    const bool usual = q.usual_cost > 0.0 ? cost <= options_.hypothesis_accept_ratio * q.usual_cost : k >= 1;
    // With a velocity, the prediction is the prior: another start must beat it clearly.
    const bool wins = try_all || k == 0 || !std::isfinite(first_cost) || cost < options_.hypothesis_win_ratio * first_cost;
    if (cost < best && wins) {
      good = usual;
      best = cost;
      chosen = k;
      chosen_screened = screened;
      state.camera_T_ground = s.camera_T_ground;
      state.photometric = photo3;
      for (size_t i = 0; i < slots.size(); ++i) state.photometric[static_cast<size_t>(slots[i])] = s.photometric[i];
    }
    if (k == 0) first_state = state;  // a finite first cost always wins (best starts infinite)
  }
  if (!any_moved && predictor.velocityKnown() && chosen != 0 && std::isfinite(first_cost)) {
    chosen = 0;
    best = first_cost;
    chosen_screened = false;
    state = first_state;
  }
  // Continues the chosen start with `iterations` more motion-only iterations at pyramid `level`
  // (the window follows the pose); keeps the result when it is sound. Returns its cost per
  // sample, or infinity when it was not kept.
  const auto continueChosen = [&](int iterations, int level) {
    const GroundGrid chosen_window = map.window(state.camera_T_ground);
    if (!chosen_window.sameLayout(window)) {
      window = chosen_window;
      map.initialHeights(window, state.camera_T_ground, heights, info);
    }
    SurfaceAlignerOptions more = pre;
    more.max_iterations = iterations;
    AlignmentProblem at_level = prob;
    at_level.level = level;
    SurfaceState s;
    s.camera_T_ground = state.camera_T_ground;
    s.heights = *heights;
    for (int sl : slots) s.photometric.push_back(state.photometric[static_cast<size_t>(sl)]);
    const AlignmentReport rep = SurfaceAligner(more).align(at_level, s);
    out.reports.push_back(rep);
    const int samples = rep.valid_pixels + rep.outside_pixels;
    if (rep.degenerate || !s.camera_T_ground.matrix().allFinite() || samples <= 0) {
      return std::numeric_limits<double>::infinity();
    }
    state.camera_T_ground = s.camera_T_ground;
    for (size_t i = 0; i < slots.size(); ++i) state.photometric[static_cast<size_t>(slots[i])] = s.photometric[i];
    return rep.final_cost / samples;
  };
  if (chosen_screened && std::isfinite(best)) {
    // the winner was screened with fewer iterations: the rest of them now
    const double continued = continueChosen(pre.max_iterations - screen_iterations, prob.level);
    if (std::isfinite(continued)) best = continued;
  }
  out.cost = best;
  // When the motion was not what the constant velocity predicted (another start won, no
  // velocity was known, or frames were dropped), the chosen start is refined one pyramid level
  // finer (prealign_refine_iterations, 8; 0: off): the coarse level gives the wide basin that
  // abrupt attitude changes need, the finer one the precision before the joint levels. Measured
  // with 8 iterations: the bouncing zoo scene 1.81 -> 0.39 % drift and 0.46 -> 0.07 deg, every
  // 3rd / 4th frame of a rendered drive 7.4 -> 2.3 cm / 30 -> 9.4 cm. (On 2026-12-01 it made one
  // KITTI 06 frame land 32 cm long, 1.06 -> 1.42 %; with the tracking of 2026-12-02, 1.05 -> 1.01 %.)
  const bool surprising = chosen > 0 || !predictor.velocityKnown() || q.gap_s > 1.5 * options_.nominal_frame_period_s;
  if (std::isfinite(best) && surprising && options_.prealign_refine_iterations > 0 && prob.level > 0) {
    continueChosen(options_.prealign_refine_iterations, prob.level - 1);
  }
  // A physically impossible change of the predicted motion: something moving pulled the
  // pre-alignment (the overtaking car and its shadow on the shadows scene, which halved a 1 m
  // step), and the obstacles detected at that pose would be the wrong ones.
  // (Only where a prediction exists and a start aligned; the cost of a rejected one does not
  // enter the running level of good frames.)
  if (std::isfinite(best) && predictor.velocityKnown()) {
    out.shift_m = (state.camera_T_ground.inverse().translation() - predicted.inverse().translation()).norm();
    if (chosen == 0 && out.shift_m > q.max_shift_m) {
      out.rejected = true;
      best = std::numeric_limits<double>::infinity();
      out.cost = best;
    }
  }
  if (!std::isfinite(best)) {
    state.camera_T_ground = predicted;
    state.photometric = {statsPhotometric(pl, pr, predicted), statsPhotometric(pl, *c_.prev_left, predicted),
                         statsPhotometric(pl, *c_.prev_right, predicted)};
  }
  out.camera_T_ground = state.camera_T_ground;
  out.photometric = state.photometric;
  return out;
}

}  // namespace stereo_ground_dem
