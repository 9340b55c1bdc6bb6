#include "stereo_ground_dem/TrackingCheck.hpp"

#include <algorithm>
#include <sstream>
#include <stdexcept>

namespace stereo_ground_dem {

bool TrackingCheckOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(max_speed_m_per_s > 0.0) || !(max_turn_rate_rad_per_s > 0.0)) return bad("motion limits must be > 0");
  if (!(max_height_jump_m > 0.0) || !(max_jump_fraction > 0.0)) return bad("height-jump limits must be > 0");
  if (!(max_outside_fraction > 0.0 && max_outside_fraction <= 1.0)) return bad("max_outside_fraction must be in (0, 1]");
  if (!(max_residual_ratio > 1.0) || !(max_residual_increase_grey > 0.0)) {
    return bad("max_residual_ratio must exceed 1 and max_residual_increase_grey be > 0");
  }
  if (min_samples < 0) return bad("min_samples must be >= 0");
  if (!(min_observed_fraction >= 0.0 && min_observed_fraction < 1.0)) return bad("min_observed_fraction must be in [0, 1)");
  return true;
}

TrackingCheck::TrackingCheck(const TrackingCheckOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("TrackingCheckOptions: " + why);
}

std::string TrackingCheck::failure(const TrackingEvidence& e) const {
  const TrackingCheckOptions& o = options_;
  std::ostringstream why;
  const double limit = std::max(o.max_residual_ratio * e.usual_residual_grey,
                                e.usual_residual_grey + o.max_residual_increase_grey);
  const double temporal_limit = std::max(o.max_residual_ratio * e.usual_temporal_residual_grey,
                                         e.usual_temporal_residual_grey + o.max_residual_increase_grey) *
                                std::max(1.0, e.temporal_gap_ratio);
  if (e.degenerate) {
    why << "normal equations degenerate";
  } else if (!e.finite) {
    why << "estimate is not finite";
  } else if (e.step.head<3>().norm() / e.dt_s > o.max_speed_m_per_s) {
    why << "implausible motion: " << e.step.head<3>().norm() / e.dt_s << " m/s";
  } else if (e.step.tail<3>().norm() / e.dt_s > o.max_turn_rate_rad_per_s) {
    why << "implausible rotation: " << e.step.tail<3>().norm() / e.dt_s << " rad/s";
  } else if (e.samples < o.min_samples || e.outside > o.max_outside_fraction * e.samples) {
    why << "too few pixels overlap between the images (" << e.outside << " of " << e.samples << " samples outside)";
  } else if (e.well_known > 20 && e.jumps > o.max_jump_fraction * e.well_known) {
    why << e.jumps << " of " << e.well_known << " well-known vertices moved more than " << o.max_height_jump_m << " m";
  } else if (e.usual_residual_grey > 0.0 && e.median_residual_grey > limit) {
    why << "alignment did not converge: median residual " << e.median_residual_grey << " grey (usual "
        << e.usual_residual_grey << ")";
  } else if (e.usual_temporal_residual_grey > 0.0 && e.temporal_residual_grey > temporal_limit) {
    why << "the motion does not explain the previous image: its median residual " << e.temporal_residual_grey
        << " grey (usual " << e.usual_temporal_residual_grey;
    if (e.temporal_gap_ratio >= 1.1) why << ", over " << e.temporal_gap_ratio << "x the usual stamp gap";
    why << ")";
  } else if (e.usual_observed_vertices > 0.0 && e.observed_vertices < o.min_observed_fraction * e.usual_observed_vertices) {
    why << "the ground support collapsed: " << e.observed_vertices << " vertices observed (usual "
        << static_cast<int>(std::lround(e.usual_observed_vertices)) << ")";
  }
  return why.str();
}

}  // namespace stereo_ground_dem
