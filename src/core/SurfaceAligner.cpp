#include "stereo_ground_dem/SurfaceAligner.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "stereo_ground_dem/aligner/AlignmentLevel.hpp"
#include "stereo_ground_dem/aligner/HeightSystemSolver.hpp"
#include "stereo_ground_dem/aligner/PhotometricEvaluator.hpp"

namespace stereo_ground_dem {

bool SurfaceAlignerOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (max_iterations < 0) return bad("max_iterations must be >= 0");
  if (max_step_halvings < 0) return bad("max_step_halvings must be >= 0");
  if (!(image_noise_std_grey > 0.0)) return bad("image_noise_std_grey must be > 0");
  if (!(smoothness_weight >= 0.0)) return bad("smoothness_weight must be >= 0");
  if (!(min_depth_m > 0.0) || !(max_depth_m > min_depth_m)) {
    return bad("need 0 < min_depth_m < max_depth_m");
  }
  if (!(max_lateral_m > 0.0)) return bad("max_lateral_m must be > 0");
  if (border_margin_px < 1) return bad("border_margin_px must be >= 1");
  if (!(saturated_level_grey > dark_level_grey)) return bad("saturated_level_grey must exceed dark_level_grey");
  if (!(textured_gradient_grey_per_px >= 0.0) || !std::isfinite(textured_gradient_grey_per_px)) {
    return bad("textured_gradient_grey_per_px must be finite and >= 0");
  }
  if (!(outside_penalty_factor >= 0.0)) return bad("outside_penalty_factor must be >= 0");
  if (num_threads < 1) return bad("num_threads must be >= 1");
  if (!(cg_tolerance > 0.0 && cg_tolerance < 1.0)) return bad("cg_tolerance must be in (0, 1)");
  if (cg_max_iterations < 1) return bad("cg_max_iterations must be >= 1");
  return true;
}

namespace {

using aligner::AlignmentLevel;
using aligner::Evaluation;
using aligner::HeightSystemSolver;
using aligner::PhotometricEvaluator;

/// Buffers reused across iterations, levels and frames (one per thread).
struct Workspace {
  aligner::EvaluatorWorkspace evaluator;
  Evaluation eval[2];
};

double median(std::vector<float> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

void checkProblem(const AlignmentProblem& p, const SurfaceState& s) {
  if (!p.reference || !p.rig || !p.grid) throw std::invalid_argument("SurfaceAligner: reference, rig and grid are required");
  if (p.level < 0 || p.level >= p.reference->levels()) throw std::invalid_argument("SurfaceAligner: no such pyramid level");
  if (s.photometric.size() != p.targets.size()) {
    throw std::invalid_argument("SurfaceAligner: one PhotometricParams per target is required");
  }
  for (const auto& t : p.targets) {
    if (!t.pyramid || t.pyramid->levels() <= p.level) throw std::invalid_argument("SurfaceAligner: target pyramid missing or too shallow");
  }
  if (p.prior && (p.prior->mean.size() != p.grid->vertexCount() || p.prior->information.size() != p.grid->vertexCount())) {
    throw std::invalid_argument("SurfaceAligner: prior does not match the grid");
  }
  if (!p.vertex_mask.empty() && static_cast<int>(p.vertex_mask.size()) != p.grid->vertexCount()) {
    throw std::invalid_argument("SurfaceAligner: vertex mask does not match the grid");
  }
}

}  // namespace

SurfaceAligner::SurfaceAligner(const SurfaceAlignerOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("SurfaceAlignerOptions: " + why);
}

AlignmentReport SurfaceAligner::align(const AlignmentProblem& problem, SurfaceState& state) const {
  checkProblem(problem, state);
  thread_local Workspace ws;
  AlignmentReport report;
  report.level = problem.level;
  report.pairs = static_cast<int>(problem.targets.size());
  report.motion = options_.estimate_motion;
  report.heights = problem.estimate_heights;
  using Clock = std::chrono::steady_clock;
  auto ms = [](Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double, std::milli>(b - a).count(); };
  auto t0 = Clock::now();
  AlignmentLevel level(options_, problem, state);
  PhotometricEvaluator evaluator(level, &ws.evaluator);
  HeightSystemSolver solver(level);
  report.setup_ms = ms(t0, Clock::now());
  report.working_triangles = static_cast<int>(level.triangles().size());
  report.active_vertices = level.activeCount();
  if (level.empty()) {
    report.vertex_information = Eigen::VectorXd::Zero(problem.grid->vertexCount());
    report.vertex_pixels = Eigen::VectorXi::Zero(problem.grid->vertexCount());
    report.vertex_excluded_pixels = Eigen::VectorXi::Zero(problem.grid->vertexCount());
    report.vertex_textured_pixels = Eigen::VectorXi::Zero(problem.grid->vertexCount());
    return report;
  }
  Evaluation* ev = &ws.eval[0];
  Evaluation* trial_ev = &ws.eval[1];
  SurfaceState trial;
  // An Evaluation holds all that the solve and the report need of its state (slots, sums, the
  // triangles' planes and Jacobians), so the start taken keeps its own. Starts are compared by their
  // cost per sample (as PoseSearch compares them): a pose that sees less of the ground has fewer
  // samples, and one that sees none has none (infinite).
  auto perSample = [](const Evaluation& e) {
    long samples = 0;
    for (const auto& pa : e.pair) samples += pa.valid + pa.outside;
    return samples > 0 ? e.total() / static_cast<double>(samples) : std::numeric_limits<double>::infinity();
  };
  double alternative_cost = std::numeric_limits<double>::infinity();
  if (problem.alternative_start) {
    trial = state;
    trial.camera_T_ground = *problem.alternative_start;
    t0 = Clock::now();
    evaluator.evaluate(trial, trial_ev);
    report.evaluate_ms += ms(t0, Clock::now());
    report.evaluations++;
    alternative_cost = perSample(*trial_ev);
  }
  t0 = Clock::now();
  evaluator.evaluate(state, ev);
  report.evaluate_ms += ms(t0, Clock::now());
  report.evaluations++;
  if (alternative_cost < problem.alternative_win_ratio * perSample(*ev)) {
    state = trial;
    std::swap(ev, trial_ev);
    report.started_from_alternative = true;
  }
  report.initial_cost = ev->total();
  // A trial that no solve will linearize at is evaluated for its cost only: the final step's, and
  // the last iteration's when no final step follows (unless the motion information is wanted at
  // the final state).
  const bool final_step = options_.final_undamped_step && problem.estimate_heights;
  const bool info_at_end = options_.estimate_motion && problem.want_motion_information;
  for (int it = 0; it < options_.max_iterations; ++it) {
    report.iterations = it + 1;
    t0 = Clock::now();
    const auto step = solver.solve(state, *ev, &report);
    report.solve_ms += ms(t0, Clock::now());
    if (!step.ok) break;
    double alpha = 1.0;
    bool accepted = false;
    double max_dz = 0.0;
    const bool sums = it + 1 < options_.max_iterations || final_step || info_at_end;
    for (int h = 0; h <= options_.max_step_halvings; ++h, alpha *= 0.5) {
      max_dz = level.apply(step, alpha, state, &trial);
      t0 = Clock::now();
      evaluator.evaluate(trial, trial_ev, sums);
      report.evaluate_ms += ms(t0, Clock::now());
      report.evaluations++;
      if (trial_ev->total() <= ev->total() * (1.0 + 1e-9)) {
        accepted = true;
        break;
      }
    }
    if (!accepted) {
      report.stalled = true;
      break;
    }
    const double decrease = ev->total() - trial_ev->total();
    state = trial;
    std::swap(ev, trial_ev);
    report.accepted_steps++;
    if (decrease < options_.converged_relative_decrease * ev->total()) {
      report.converged = true;
      break;
    }
    bool small = max_dz < options_.converged_height_step_m;
    if (options_.estimate_motion) {
      small = small && alpha * step.dglobal.head<3>().norm() < options_.converged_translation_m &&
              alpha * step.dglobal.segment<3>(3).norm() < options_.converged_rotation_rad;
    }
    if (small) {
      report.converged = true;
      break;
    }
  }
  // The update constraint damps every step by mu (most where data is weak, far away): with a few
  // iterations, far vertices stay near their starting heights. A last step with almost no
  // damping moves them to where data, smoothness and prior put them. Not after a stall: that step
  // would be solved from the linearization whose damped step raised the cost at every halving,
  // and it was rejected as well in 79 of 80 such passes (KITTI clips, shadows, traffic, rolling,
  // off-road), three evaluations each.
  if (final_step && !report.stalled) {
    level.setDampingScale(options_.final_step_damping_scale);
    t0 = Clock::now();
    const auto step = solver.solve(state, *ev, &report);
    report.solve_ms += ms(t0, Clock::now());
    if (step.ok) {
      double alpha = 1.0;
      for (int h = 0; h <= options_.max_step_halvings; ++h, alpha *= 0.5) {
        level.apply(step, alpha, state, &trial);
        t0 = Clock::now();
        evaluator.evaluate(trial, trial_ev, info_at_end);
        report.evaluate_ms += ms(t0, Clock::now());
        report.evaluations++;
        report.final_step_evaluations++;
        if (trial_ev->total() <= ev->total() * (1.0 + 1e-9)) {
          state = trial;
          std::swap(ev, trial_ev);
          report.accepted_steps++;
          break;
        }
      }
    }
    level.setDampingScale(1.0);
  }
  if (options_.estimate_motion && problem.want_motion_information) {
    t0 = Clock::now();
    AlignmentReport tmp;
    solver.solve(state, *ev, &tmp, true);  // the Schur complement at the final state
    report.motion_information = tmp.motion_information;
    report.solve_ms += ms(t0, Clock::now());
  }
  // ev holds the evaluation at the final state; vertex_information comes from the last
  // linearization (the state before the last accepted step), which differs only to second order.
  level.fillPixels(*ev, &report);
  report.raster_ms = evaluator.rasterMs();
  report.final_cost = ev->total();
  report.data_cost = ev->data_cost;
  report.smoothness_cost = ev->smoothness_cost;
  report.prior_cost = ev->prior_cost;
  report.valid_pixels = 0;
  report.outside_pixels = 0;
  for (const auto& pa : ev->pair) {
    report.valid_pixels += pa.valid;
    report.outside_pixels += pa.outside;
  }
  report.median_abs_residual_grey = median(ev->abs_residuals);
  for (const auto& r : ev->pair_abs_residuals) report.target_median_abs_residual_grey.push_back(median(r));
  return report;
}

cv::Mat SurfaceAligner::renderInverseDepth(const AlignmentProblem& problem, const SurfaceState& state,
                                           cv::Mat* labels) const {
  checkProblem(problem, state);
  SurfaceAlignerOptions o = options_;
  o.estimate_motion = false;
  AlignmentProblem p = problem;
  p.targets.clear();
  p.estimate_heights = false;  // only drawn: no smoothness, no height pattern
  SurfaceState s = state;
  s.photometric.clear();
  AlignmentLevel level(o, p, s);
  aligner::EvaluatorWorkspace ws;
  Evaluation ev;
  PhotometricEvaluator(level, &ws).evaluate(s, &ev);
  if (labels) *labels = ws.raster.labels().clone();
  return ws.raster.inverseDepth().clone();
}

}  // namespace stereo_ground_dem
