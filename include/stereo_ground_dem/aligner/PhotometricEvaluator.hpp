#pragma once
/// \file PhotometricEvaluator.hpp
/// Evaluates the objective of an AlignmentLevel at a state: rasterizes the surface into the
/// reference image (z-buffered: each pixel belongs to the nearest triangle), and in one threaded
/// pass over the reference pixels of every image pair computes the residuals, their robust
/// weights and the inverse compositional Jacobians, summed per triangle and per pair
/// (Evaluation); then the smoothness and prior costs. Internal to SurfaceAligner.

#include <array>
#include <vector>

#include "stereo_ground_dem/TriangleRasterizer.hpp"
#include "stereo_ground_dem/aligner/AlignmentLevel.hpp"
#include "stereo_ground_dem/aligner/Evaluation.hpp"

namespace stereo_ground_dem {
namespace aligner {

/// Buffers an evaluator reuses across evaluations, levels and frames (one per thread).
struct EvaluatorWorkspace {
  TriangleRasterizer raster;
  std::vector<std::array<float, 9>> homographies;  ///< [pair * slots + slot]
};

class PhotometricEvaluator {
 public:
  /// The level's triangles record the planes of the last evaluated state (TriangleGeometry::m).
  PhotometricEvaluator(AlignmentLevel& level, EvaluatorWorkspace* workspace) : level_(level), ws_(workspace) {}

  void evaluate(const SurfaceState& s, Evaluation* ev);
  /// The rasterization of the last evaluation (labels = triangle indices, inverse depth).
  const TriangleRasterizer& raster() const { return ws_->raster; }

 private:
  struct RowPixels;
  void accumulateRows(const std::vector<PairContext>& pc, const Evaluation& ev, int v0, int v1, Chunk* ch) const;
  void dispatchRow(const PairContext& p, size_t j, size_t ns, int v, float y, const RowPixels& px, Chunk* ch,
                   bool photo) const;
  template <int kKind, bool kWorld, bool kShift>
  void pairRow(const PairContext& p, size_t j, size_t ns, int v, float y, const RowPixels& px, Chunk* ch,
               bool photo) const;

  AlignmentLevel& level_;
  EvaluatorWorkspace* ws_;
};

}  // namespace aligner
}  // namespace stereo_ground_dem
