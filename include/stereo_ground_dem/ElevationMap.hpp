#pragma once
/// \file ElevationMap.hpp
/// The fused DEM: vertex heights on the global ground lattice (see GroundGrid.hpp for the
/// conventions), stored in square tiles that are created as the vehicle drives and evicted when
/// they fall farther than `keep_radius_m` from it, so memory stays bounded on drives of any length.
/// Evicted tiles are dropped or, with an archive directory, written to disk (one binary file per
/// tile, re-loadable with loadArchive()).
///
/// Per vertex the map keeps the height, its information (1 / variance) and the number of frames
/// that observed it. Fusion is Bayesian: the estimator uses the map as a prior, so its estimate is
/// already the posterior; fuse() stores it with the prior information plus the frame's data
/// information (capped at max_information, which keeps the map able to follow a changing scene).

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <unordered_map>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"

namespace stereo_ground_dem {

struct ElevationMapOptions {
  double resolution_m = 0.5;        ///< lattice spacing [m]
  int tile_size = 64;               ///< vertices per tile side
  double keep_radius_m = 200.0;     ///< tiles whose centre is farther from the vehicle are evicted [m]
  double max_information = 1e6;     ///< cap on a vertex's information [1/m^2] (std >= 1 mm)
  /// Score added by a frame that sees an obstacle there: below obstacle_mark_score, so that a mark
  /// needs two frames' evidence (one frame's misplaced obstacle points, which scatter from frame to
  /// frame, mark nothing; docs/results.md, "The obstacle layer").
  double obstacle_hit = 0.6;
  double obstacle_mark_score = 1.0;  ///< a vertex with at least this score is an obstacle
  double obstacle_miss = 1.0;        ///< score removed by a frame that sees the ground there
  double obstacle_max_score = 2.0;   ///< cap: two frames that see the ground clear a mark (>= mark)
  std::string archive_directory;    ///< empty: evicted tiles are dropped

  bool isValid(std::string* why) const;
};

class ElevationMap {
 public:
  /// kObstacle: 1 where an obstacle is believed (hidden by or under one), 0 where the ground was
  /// seen last, NaN unknown; kObstacleHeight: the obstacle's height above the ground [m] where a
  /// 3-D obstacle point fell into the cell.
  enum class Layer { kElevation, kVariance, kObservations, kLastUpdate, kObstacle, kObstacleHeight };

  explicit ElevationMap(const ElevationMapOptions& options = ElevationMapOptions());

  /// Heights and information of the window's vertices (NaN / 0 where the map knows nothing).
  void sample(const GroundGrid& window, Eigen::VectorXd* heights, Eigen::VectorXd* information,
              Eigen::VectorXi* observations = nullptr) const;

  /// Writes the posterior heights of the window's vertices where `update[v]` is set:
  /// height = heights[v], information = min(max_information, prior_information[v] + data_information[v]).
  /// `window` must be on the map's lattice (same resolution).
  void fuse(const GroundGrid& window, const Eigen::VectorXd& heights, const Eigen::VectorXd& prior_information,
            const Eigen::VectorXd& data_information, const std::vector<uint8_t>& update, int frame_index);

  /// Marks the known heights that the rays of pixels which saw past the surface refute: a vertex
  /// not updated by this frame (`update[v]` 0) whose height stands more than `margin_m` above its
  /// `ceilings[v]` (FarGroundSeeds::ceilings: the ground lies below such a ray). A refuted vertex
  /// keeps its height and information for sample() (the estimator's start, unchanged), but the
  /// layers publish it as unknown until a frame fuses it again. Returns how many were newly marked.
  int markRefuted(const GroundGrid& window, const Eigen::VectorXd& ceilings, double margin_m,
                  const std::vector<uint8_t>& update);

  /// Obstacle evidence of one frame on `window` (vectors per window vertex): hits raise a
  /// vertex's obstacle score, ground observations lower it, so that moving objects leave no
  /// ghosts once the ground behind them is seen again.
  void updateObstacles(const GroundGrid& window, const std::vector<uint8_t>& hit, const std::vector<uint8_t>& ground,
                       const Eigen::VectorXd& obstacle_height, int frame_index);

  /// Removes (or archives) the tiles whose centre is farther than keep_radius_m from (x, y).
  int evictFarFrom(double x, double y);

  /// The bounding grid of every tile in memory (empty grid if none).
  GroundGrid bounds() const;
  /// The bounding grid of the vertices that hold data (tighter than bounds()).
  GroundGrid knownBounds() const;
  /// A dense layer over `window`: CV_32F rows x cols, NaN where unknown. A vertex is known where it
  /// holds a height with information > 0 (sample() also returns heights fused without information,
  /// which the estimator treats as unknown) that no far ray refuted since (markRefuted()).
  cv::Mat layer(Layer which, const GroundGrid& window) const;

  /// Loads archived tiles back (e.g. to export the whole drive); returns how many were read.
  /// A tile already in memory is replaced by its archived copy.
  int loadArchive(const std::string& directory);
  /// Writes every tile in memory to `directory` (which must exist) in the archive's format, one
  /// file per tile, so that loadArchive() restores the map (a map saved to be continued later);
  /// returns how many were written. Throws std::runtime_error when a file cannot be written.
  int saveTiles(const std::string& directory) const;

  void clear();
  size_t tileCount() const { return tiles_.size(); }
  size_t memoryBytes() const;
  int evictedTiles() const { return evicted_; }
  const ElevationMapOptions& options() const { return options_; }

 private:
  struct Tile {
    std::vector<float> height;       ///< NaN = unknown
    std::vector<float> information;  ///< [1/m^2]
    std::vector<uint16_t> observations;
    std::vector<int32_t> last_update;
    std::vector<float> obstacle_score;   ///< log-odds-like; >= 1: obstacle
    std::vector<float> obstacle_height;  ///< [m] above the ground, NaN unknown
    std::vector<uint8_t> refuted;        ///< 1: a far ray passed under the height (markRefuted)
  };
  using Key = std::int64_t;
  static Key key(int tile_row, int tile_col) {
    // shifted as unsigned: a left shift of a negative value is undefined before C++20 (UBSan);
    // the bits are the same as before (row in the high word, column in the low word)
    return static_cast<Key>((static_cast<std::uint64_t>(static_cast<std::uint32_t>(tile_row)) << 32) |
                            static_cast<std::uint32_t>(tile_col));
  }
  Tile* tileFor(int lattice_row, int lattice_col, bool create, int* index);
  const Tile* tileFor(int lattice_row, int lattice_col, int* index) const;
  void archive(Key k, const Tile& t) const;
  void writeTile(const std::string& directory, Key k, const Tile& t) const;

  ElevationMapOptions options_;
  std::unordered_map<Key, Tile> tiles_;
  int evicted_ = 0;
};

}  // namespace stereo_ground_dem
