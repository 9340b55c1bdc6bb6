#pragma once
/// \file PhotometricEvaluator.hpp
/// Evaluates the objective of an AlignmentLevel at a state: rasterizes the surface into the
/// reference image (z-buffered: each pixel belongs to the nearest triangle), and in one threaded
/// pass over the reference pixels of every image pair computes the residuals, their robust
/// weights and the inverse compositional Jacobians, summed per triangle and per pair
/// (Evaluation); then the smoothness and prior costs. Internal to SurfaceAligner.

#include <array>
#include <memory>
#include <tbb/task_arena.h>
#include <vector>

#include "stereo_ground_dem/TriangleRasterizer.hpp"
#include "stereo_ground_dem/aligner/AlignmentLevel.hpp"
#include "stereo_ground_dem/aligner/Evaluation.hpp"

namespace stereo_ground_dem {
namespace aligner {

/// Buffers an evaluator reuses across evaluations, levels and frames (one per thread).
struct EvaluatorWorkspace {
  TriangleRasterizer raster;
  std::vector<TriangleRasterizer::Triangle> projected;  ///< the front-facing triangles of a rasterization
  std::vector<std::array<float, 9>> homographies;  ///< [pair * slots + slot]
  std::vector<double> row_work_change, row_work_setups;  ///< where the two drawing bands split
};

class PhotometricEvaluator {
 public:
  /// The Evaluation keeps its state's triangle planes and Jacobians (Evaluation::slot_m,
  /// slot_dm_dz); the level's triangles hold the last evaluated state's planes for its own use.
  PhotometricEvaluator(AlignmentLevel& level, EvaluatorWorkspace* workspace) : level_(level), ws_(workspace) {}

  /// sums false: costs, counts and residual samples only (Evaluation::sums), for a trial step
  /// that no solve will linearize at.
  void evaluate(const SurfaceState& s, Evaluation* ev, bool sums = true);
  /// Time spent in rasterization, slots and homographies so far [ms].
  double rasterMs() const { return raster_ms_; }
  /// The rasterization of the last evaluation (labels = triangle indices, inverse depth).
  const TriangleRasterizer& raster() const { return ws_->raster; }

 private:
  struct RowPixels;
  /// Rows [v0, v1), the pixels of slots [slot_begin, slot_end) only.
  void accumulateRows(const std::vector<PairContext>& pc, Evaluation* ev, int v0, int v1, int slot_begin,
                      int slot_end, ThreadPart* part) const;
  /// One image pair over one row: residuals and weights (pairRow), then the sums (accumulateRuns).
  void dispatchRow(const PairContext& p, size_t j, size_t ns, int v, float y, RowPixels& px, Evaluation* ev,
                   ThreadPart* part, int runs) const;
  template <int kKind, bool kShift>
  void pairRow(const PairContext& p, size_t j, size_t ns, int v, RowPixels& px, ThreadPart* part) const;
  template <bool kWorld, bool kTriangles>
  void accumulateRuns(const PairContext& p, size_t j, float y, const RowPixels& px, int runs, Evaluation* ev,
                      ThreadPart* part) const;
  /// The level's threads, made once per evaluator (an arena per parallel section costs more
  /// than the slots' geometry it would split).
  tbb::task_arena& arena() {
    if (!arena_) arena_ = std::make_unique<tbb::task_arena>(level_.threads());
    return *arena_;
  }

  /// Rasterizes the surface at state s (the vertices projected in vertex_u_ / vertex_v_) and
  /// assigns slots, in raster order, to the triangles that won pixels.
  void rasterize(const SurfaceState& s);

  AlignmentLevel& level_;
  EvaluatorWorkspace* ws_;
  std::unique_ptr<tbb::task_arena> arena_;
  // the active vertices in the reference image at the evaluated state
  std::vector<double> vertex_u_, vertex_v_;
  std::vector<uint8_t> vertex_ok_;  ///< in front of the camera
  double raster_ms_ = 0.0;
  bool sums_ = true;  ///< the evaluation in progress accumulates the normal-equation pieces
  /// Per band of rows of a rasterization: the triangles that won pixels in raster order, each
  /// one's first row, and (valid where stamp == generation_) its last row.
  struct BandSlots {
    std::vector<int> tri, first_row;
    std::vector<unsigned> stamp;
    std::vector<int> last_row;
  };
  BandSlots band_[2];
  unsigned generation_ = 0;
  std::vector<int> slot_of_, slot_tri_;  ///< the rasterization's slots
  std::vector<int> slot_last_row_;       ///< per slot: the last row with its pixels
  std::vector<int> slots_before_row_;    ///< per row: slots first seen above it
};

}  // namespace aligner
}  // namespace stereo_ground_dem
