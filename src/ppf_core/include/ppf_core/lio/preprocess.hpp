// Preprocess stage: range/stride filter and voxel-grid downsampling of the RAW scan, each output
// point carrying the mean time of the points it stands for, so that de-skew (deskew.hpp) runs on
// the few thousand downsampled points instead of the ~130k raw ones of a 64-beam scan.
//
// Why downsample before de-skew (the paper de-skews first): de-skew is an affine function of each
// point for a fixed time, and within one 0.5 m voxel of a spinning LiDAR the points are a few
// milliseconds apart (neighbouring azimuths). The centroid de-skewed with the mean time equals the
// mean of the de-skewed points up to |omega| * cov(t, p) (test_preprocess bounds it). Only where
// the sweep closes do first and last firings (0.1 s apart) share a voxel; there the mean would be
// a ghost point, so voxels are also split by time bucket (time_bucket_s, half a sweep): the seam's
// two sides never mix. In exchange de-skew runs on the downsampled points, which cuts most of the
// fixed per-scan cost outside registration (docs/decisions.md, "Downsample before de-skew").
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "ppf_core/lio/time_field.hpp"
// The plain voxel grid without point times (tools, and the reference VoxelGridDownsampler is
// tested against).
#include "ppf_core/lio/voxel_downsample.hpp"

namespace ppf {

struct PreprocessOptions {
  double min_range = 0.5;     // metres; closer points (the vehicle itself) are dropped
  double max_range = 150.0;   // metres
  int point_stride = 1;       // keep every n-th input point (1 = all)
  double voxel_size = 0.5;    // metres; <= 1 mm keeps every filtered point (no downsampling)
  // Points of one voxel more than a bucket apart in time are not averaged (the sweep's seam);
  // measured from the earliest point time. Half a 10 Hz sweep; <= 0 disables the split.
  double time_bucket_s = 0.05;
  // Threads for the voxel grid (0 = OpenMP default, 1 = serial). Any count gives the serial
  // output exactly; large scans only (VoxelGridDownsampler::kParallelPoints).
  int num_threads = 0;
};

struct PreprocessStats {
  size_t valid_points = 0;        // after stride and range filtering
  size_t downsampled_points = 0;  // output size
};

// Voxel grid with per-voxel centroid (position, intensity, time), in order of first appearance
// (deterministic). Keeps its hash table between calls: construct once, call per scan.
class VoxelGridDownsampler {
 public:
  // Fewer (sampled) input points than this run serially. The serial path keys its points four at
  // a time and prefetches its slots, so the parallel one's owner lists, second pass and two team
  // wake-ups outweigh what a second thread saves below a few 10k points: a 16-beam sweep runs
  // serially (docs/profiles.md, thirty-third pass).
  static constexpr size_t kParallelPoints = 65536;

  // Returns the filtered (and, if voxel_size > 1 mm, downsampled) points of `in` in `out`.
  // t_begin: the earliest point time (DecodedScan::t_begin); time buckets count from it.
  PreprocessStats Run(const std::vector<TimedPoint>& in, double t_begin,
                      const PreprocessOptions& options, std::vector<TimedPoint>* out);

 private:
  struct Slot {
    uint64_t key = 0;
    uint32_t generation = 0;  // empty unless equal to the grid's generation
    uint32_t index = 0;       // into the accumulators
  };
  struct Accumulator {
    double x = 0, y = 0, z = 0, dt = 0;
    float intensity = 0.f;
    uint32_t count = 0;
    uint64_t key = 0;  // for re-insertion
  };
  // One open-addressing voxel table with its accumulators in order of first appearance. The serial
  // path uses one; the parallel path one per thread, each owning a hash-chosen share of the voxels
  // and seeing every point of them in input order, so that every voxel's sums are added in the
  // serial order (floating-point sums depend on it).
  //
  // The table hashes into its first `active` slots (a power of two) and doubles that share when
  // half full, re-inserting the voxels from their accumulators' keys. Within the allocated slots
  // that allocates nothing: the parallel path allocates every grid's memory on the calling
  // thread, for every key the grid owns, and its threads only store into it (a sanitizer sees a
  // region's start and end only through the OpenMP runtime, so a buffer a worker reallocated and
  // the calling thread later freed reads as a race).
  struct Grid {
    std::vector<Slot> table;
    std::vector<Accumulator> acc;
    std::vector<uint32_t> first;  // parallel path: input index of each voxel's first point
    size_t active = 0;
    uint32_t generation = 0;
    // Starts a call: `expected_voxels` sizes the hashed share, and no buffer reallocates before
    // `max_voxels` voxels (the serial path passes its estimate: it may grow on its own thread).
    void Begin(size_t expected_voxels, size_t max_voxels);
    void Grow();
    // for_each(add, prefetch) calls add(key, point, input index) for this grid's points in input
    // order; prefetch(key) may announce a later key.
    template <bool kRecordFirst, typename ForEach>
    void Accumulate(double t_ref, ForEach&& for_each);
  };
  PreprocessStats RunParallel(const std::vector<TimedPoint>& in, double t_begin,
                              const PreprocessOptions& options, int threads,
                              std::vector<TimedPoint>* out);

  std::vector<Grid> grids_{1};
  // Parallel path: the kept points' keys and input indices, one list per (input range, owning
  // thread), each in input order.
  std::vector<uint64_t> keys_;
  std::vector<uint32_t> kept_index_;
};

namespace detail {
// The grid's range filter and voxel keys, for test_preprocess to hold the vector path to the
// scalar one: the key and input offset (s - begin) * stride of every point in[s * stride], s in
// [begin, end), that passes the range filter. Returns their count; keys and indices hold
// end - begin + 4. `vector`: the path the grid takes on this CPU (AVX2 where it has it); false:
// the scalar path.
size_t GridKeys(bool vector, const std::vector<TimedPoint>& in, size_t begin, size_t end,
                size_t stride, double t_begin, const PreprocessOptions& options, uint64_t* keys,
                uint32_t* indices);
bool GridKeysHaveVectorPath();
}  // namespace detail

}  // namespace ppf
