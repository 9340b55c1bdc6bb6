// sgd_long_run: memory over a long synthetic drive (the map must stay bounded).
//
//   sgd_long_run [--frames N] [--scale F] [--scene flat|bump|offroad] [--config FILE]
//
// Renders a straight drive frame by frame (nothing stored), runs the incremental estimator, and
// prints the resident memory, the map's tiles and the pose error against the rendered truth
// (position [m] and rotation [deg] relative to frame 0) every 100 frames.

#include <malloc.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>

#include "stereo_ground_dem/io/AllocatorTuning.hpp"
#include "stereo_ground_dem/IncrementalEstimator.hpp"
#include "stereo_ground_dem/ParameterTable.hpp"
#include "stereo_ground_dem/sim/SequenceGenerator.hpp"

using namespace stereo_ground_dem;

namespace {
double residentMb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  }
  return 0.0;
}
}  // namespace

int main(int argc, char** argv) {
  int frames = 2000;
  double scale = 0.5;
  std::string scene_name = "flat";
  std::string config;
  auto usage = [] {
    std::fprintf(stderr, "usage: sgd_long_run [--frames N] [--scale F] [--scene flat|bump|offroad] [--config FILE]\n"
                         "  --config: estimator parameters (YAML, the names of docs/parameters.md); default: built-in\n");
    return 2;
  };
  for (int i = 1; i < argc; i += 2) {
    if (i + 1 >= argc) return usage();  // a lone flag (--help) or a missing value
    if (!std::strcmp(argv[i], "--frames")) frames = std::atoi(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--scale")) scale = std::atof(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--scene")) scene_name = argv[i + 1];
    else if (!std::strcmp(argv[i], "--config")) config = argv[i + 1];
    else return usage();
  }
  if (frames < 1 || !(scale > 0.0)) return usage();
  AllocatorTuning::apply();  // as dem_offline
  sim::SceneKind kind;
  if (!sim::sceneKindFromName(scene_name, &kind)) {
    std::fprintf(stderr, "sgd_long_run: unknown scene '%s'\n", scene_name.c_str());
    return 2;
  }
  const sim::SyntheticScene scene(sim::SceneOptions::standard(kind, 1));
  const StereoRig rig = sim::StereoRenderer::kittiLikeRig(scale);
  sim::SequenceOptions sq;
  sq.frames = frames;
  sim::RenderOptions ro;
  ro.supersampling = 1;  // speed; texture band-limiting still prevents aliasing
  const sim::SequenceGenerator gen(scene, rig, sq, ro);
  PipelineOptions po;
  try {
    po = ParameterTable::load(config);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sgd_long_run: %s\n", e.what());
    return 2;
  }
  IncrementalEstimator est(rig, po.estimator);
  int failures = 0;
  double ms = 0.0;
  std::printf("frame,resident_mb,map_tiles,map_mb,evicted_tiles,failures,mean_ms,position_error_m,rotation_error_deg\n");
  for (int k = 0; k < frames; ++k) {
    const sim::RenderedPair p = gen.render(k);
    const FrameResult r = est.processFrame(p.left.image, p.right.image, gen.frames()[static_cast<size_t>(k)].time_s);
    failures += r.status == FrameStatus::kFailed;
    if (r.status != FrameStatus::kTracked && r.status != FrameStatus::kInitialized) {
      std::fprintf(stderr, "frame %d: %s %s\n", k, toString(r.status), r.message.c_str());
    }
    ms += r.time_ms;
    if ((k + 1) % 100 == 0) {
      // Give freed heap pages back first, so the resident size shows what is held, not what the
      // allocator keeps cached from the last frame's temporaries.
      malloc_trim(0);
      const Eigen::Isometry3d truth =
          gen.frames().front().ground_T_left.inverse() * gen.frames()[static_cast<size_t>(k)].ground_T_left;
      const Eigen::Isometry3d error = truth.inverse() * r.camera0_T_camera;
      const double rotation_deg = Eigen::AngleAxisd(error.linear()).angle() * 180.0 / 3.14159265358979;
      std::printf("%d,%.1f,%zu,%.2f,%d,%d,%.1f,%.3f,%.3f\n", k + 1, residentMb(), est.map().tileCount(),
                  est.map().memoryBytes() / 1048576.0, est.map().evictedTiles(), failures, ms / (k + 1),
                  error.translation().norm(), rotation_deg);
      std::fflush(stdout);
    }
  }
  return 0;
}
