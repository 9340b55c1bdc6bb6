#pragma once
/// \file AllocatorTuning.hpp
/// The C library allocator settings under which a frame's large buffers (image pyramids, the
/// rasterizer's label image, per-level workspaces, sparse matrices) are reused from one frame to
/// the next instead of being returned to the kernel and faulted in again.
///
/// glibc's defaults return a freed block above its (adaptive, at most 32 MiB) mmap threshold to the
/// kernel and trim the heap top above its trim threshold; every frame then page-faults its buffers
/// back in. Measured on KITTI odometry 06 (50 frames, full resolution, 2 cores): 106,500 page faults
/// and a median of 189 ms per frame with the defaults, 22,800 and 166 ms after apply(). Resident
/// memory at its peak is the same (134-137 MB): the process keeps what it needed at its peak.
///
/// A process-wide setting: the executables (dem_offline, the benchmarks) call it first thing, and
/// the nodelet calls it in onInit (its parameter `tune_allocator`).
///
/// The price is memory the process keeps after freeing it: through ROS, 2,000 frames of the
/// synthetic road (scripts/ros_soak.py) grew the nodelet manager's resident size from 149 MB at
/// frame 200 to 168 MB, while the heap in use stayed at ~72 MB; `malloc_trim(0)` at frame 700
/// returned 15 MB of it (170 -> 155 MB). A long-running process calls releaseFreeMemory() now and
/// then (the nodelet: every `release_memory_every_frames` frames) to hand that back.

namespace stereo_ground_dem {

class AllocatorTuning {
 public:
  /// Blocks below this size come from the heap (glibc's mmap threshold; its maximum on 64 bits).
  static constexpr long kMmapThresholdBytes = 32L << 20;
  /// Free memory at the heap top kept up to this size (glibc's trim threshold).
  static constexpr long kTrimThresholdBytes = 256L << 20;

  /// Sets both thresholds (mallopt). Returns false where the C library does not support it (not
  /// glibc) or refuses a value; nothing else changes then.
  static bool apply();
  /// Returns the free memory the allocator keeps (every arena's free pages, not only the heap
  /// top) to the kernel (glibc's malloc_trim(0)); the next frame faults its buffers back in once.
  /// Returns false where unsupported (not glibc).
  static bool releaseFreeMemory();
};

}  // namespace stereo_ground_dem
