#include "ppf_core/lio/preprocess.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace ppf {
namespace {

// The parallel grid's per-thread counters live on the stack: teams up to this size.
constexpr size_t kMaxGridThreads = 64;

// 20 bits per axis (+-2^19 voxels, +-262 km at 0.5 m: the scan is in the sensor frame) and
// 4 bits of time bucket.
constexpr double kKeyBias = static_cast<double>(int64_t{1} << 19);
constexpr uint64_t kKeyAxisMask = (uint64_t{1} << 20) - 1;

// The key's floor: BiasedFloor (voxel_key.hpp) of the float product in double, v >= -2^19 (all the
// key's range holds). A point within 2^-34 voxel below a face joins the voxel above; an exact floor
// cost a truncation, a conversion back and a compare per axis.
uint64_t KeyAxis(float v) { return BiasedFloor(static_cast<double>(v), kKeyBias); }

uint64_t PackKey(uint64_t biased_x, uint64_t biased_y, uint64_t biased_z, int64_t bucket) {
  return ((biased_x & kKeyAxisMask) << 44) | ((biased_y & kKeyAxisMask) << 24) |
         ((biased_z & kKeyAxisMask) << 4) |
         static_cast<uint64_t>(std::clamp<int64_t>(bucket, 0, 15));
}

uint64_t Mix(uint64_t key) { return key * 0x9E3779B97F4A7C15ull; }

// The thread owning a voxel in the parallel path: a second multiplier, so that the owner is
// independent of the table slot (the top bits of Mix) and each thread's table fills evenly.
int Owner(uint64_t key, int threads) {
  const uint64_t h = (key * 0xC2B2AE3D27D4EB4Full) >> 32;
  return static_cast<int>((h * static_cast<uint64_t>(threads)) >> 32);
}

// Range filter and voxel key of one point, shared by both paths.
struct KeyMaker {
  float min_r2, max_r2, inv;
  double t_ref, inv_bucket;
  bool Keep(const TimedPoint& tp) const {
    const float r2 = tp.p.squaredNorm();
    return r2 >= min_r2 && r2 <= max_r2;
  }
  uint64_t Key(const TimedPoint& tp) const {
    return PackKey(KeyAxis(tp.p.x() * inv), KeyAxis(tp.p.y() * inv), KeyAxis(tp.p.z() * inv),
                   static_cast<int64_t>((tp.t - t_ref) * inv_bucket));
  }
};

template <typename Acc>
void WriteMean(const Acc& a, double t_ref, TimedPoint* tp) {
  const double inv_n = 1.0 / a.count;
  tp->p = Eigen::Vector3f(static_cast<float>(a.x * inv_n), static_cast<float>(a.y * inv_n),
                          static_cast<float>(a.z * inv_n));
  tp->intensity = static_cast<float>(a.intensity * inv_n);
  tp->t = t_ref + a.dt * inv_n;
}

// The table slots for a voxel count: at most half full, at least 1024.
size_t SlotsFor(size_t voxels) {
  size_t slots = 1024;
  while (slots < 2 * voxels) slots <<= 1;
  return slots;
}

}  // namespace

void VoxelGridDownsampler::Grid::Begin(size_t expected_voxels, size_t max_voxels) {
  if (++generation == 0) {  // wrapped after 2^32 scans: forget every stamp once
    table.assign(table.size(), Slot());
    generation = 1;
  }
  acc.clear();
  first.clear();
  acc.reserve(max_voxels);
  first.reserve(max_voxels);
  const size_t slots = SlotsFor(max_voxels);
  if (slots > table.size()) table.assign(slots, Slot());  // stamps 0: never a generation
  // The share keeps what earlier calls grew it to, as the whole table did before it had one.
  active = std::min(table.size(), std::max(active, SlotsFor(expected_voxels)));
}

void VoxelGridDownsampler::Grid::Grow() {
  if (2 * active > table.size()) {
    table.assign(2 * active, Slot());  // serial path only
  } else {
    // Empty the old share stamp by stamp (a strided store, never a memset call: a sanitizer
    // intercepts that one); the slots beyond it were never stamped in this call.
    for (size_t h = 0; h < active; ++h) table[h].generation = 0;
  }
  active *= 2;
  const int shift = 64 - __builtin_ctzll(active);
  for (size_t i = 0; i < acc.size(); ++i) {
    const uint64_t key = acc[i].key;
    size_t h = Mix(key) >> shift;
    while (table[h].generation == generation) h = (h + 1) & (active - 1);
    table[h] = Slot{key, generation, static_cast<uint32_t>(i)};
  }
}

template <bool kRecordFirst, typename ForEach>
void VoxelGridDownsampler::Grid::Accumulate(double t_ref, ForEach&& for_each) {
  // Locals, not members, in the probe loop: the slot stores could otherwise alias them.
  const uint32_t gen = generation;
  Slot* slots = table.data();
  size_t mask = active - 1;
  int shift = 64 - __builtin_ctzll(active);
  // The parallel path knows the keys ahead: it prefetches the slot of a later key, since the
  // slot load misses the cache on most points.
  const auto prefetch = [&](uint64_t key) { __builtin_prefetch(&slots[Mix(key) >> shift]); };
  // The voxel count in a local too: read from acc per point, it cost a load and a division.
  size_t voxels = acc.size();
  Accumulator* accs = acc.data();
  const auto add = [&](uint64_t key, const TimedPoint& tp, size_t input_index) {
    size_t h = Mix(key) >> shift;
    while (slots[h].generation == gen && slots[h].key != key) h = (h + 1) & mask;
    Slot& slot = slots[h];
    uint32_t index = slot.index;
    if (slot.generation != gen) {
      index = static_cast<uint32_t>(voxels++);
      slot = Slot{key, gen, index};
      acc.emplace_back().key = key;
      accs = acc.data();
      if (kRecordFirst) first.push_back(static_cast<uint32_t>(input_index));
      if (2 * voxels > mask + 1) {
        Grow();  // moves slots, not indices
        slots = table.data();
        mask = active - 1;
        shift = 64 - __builtin_ctzll(active);
      }
    }
    Accumulator& a = accs[index];
    a.x += tp.p.x();
    a.y += tp.p.y();
    a.z += tp.p.z();
    a.dt += tp.t - t_ref;
    a.intensity += tp.intensity;
    ++a.count;
  };
  for_each(add, prefetch);
}

PreprocessStats VoxelGridDownsampler::Run(const std::vector<TimedPoint>& in, double t_begin,
                                          const PreprocessOptions& options,
                                          std::vector<TimedPoint>* out) {
  PreprocessStats stats;
  out->clear();
  const size_t stride = static_cast<size_t>(std::max(1, options.point_stride));
  const KeyMaker km{static_cast<float>(options.min_range * options.min_range),
                    static_cast<float>(options.max_range * options.max_range),
                    static_cast<float>(1.0 / options.voxel_size), t_begin,
                    options.time_bucket_s > 0.0 ? 1.0 / options.time_bucket_s : 0.0};

  if (!(options.voxel_size > 1e-3)) {
    out->reserve(in.size() / stride + 1);
    for (size_t i = 0; i < in.size(); i += stride) {
      if (km.Keep(in[i])) out->push_back(in[i]);
    }
    stats.valid_points = stats.downsampled_points = out->size();
    return stats;
  }

  int threads = 1;
#ifdef _OPENMP
  threads = options.num_threads > 0 ? options.num_threads : omp_get_max_threads();
#endif
  const size_t sampled = (in.size() + stride - 1) / stride;
  threads = std::min(threads, static_cast<int>(kMaxGridThreads));
  if (threads > 1 && sampled >= kParallelPoints &&
      in.size() <= std::numeric_limits<uint32_t>::max()) {
    return RunParallel(in, t_begin, options, threads, out);
  }

  Grid& g = grids_[0];
  g.Begin(in.size() / stride / 8, in.size() / stride / 8);
  size_t valid = 0;
  g.Accumulate<false>(km.t_ref, [&](auto&& add, auto&&) {
    // Locals: the accumulator stores could alias in's size, reloaded per point otherwise.
    const TimedPoint* points = in.data();
    const size_t n = in.size();
    for (size_t i = 0; i < n; i += stride) {
      const TimedPoint& tp = points[i];
      if (!km.Keep(tp)) continue;
      ++valid;
      add(km.Key(tp), tp, i);
    }
  });
  stats.valid_points = valid;
  out->resize(g.acc.size());
  for (size_t i = 0; i < g.acc.size(); ++i) WriteMean(g.acc[i], km.t_ref, &(*out)[i]);
  stats.downsampled_points = out->size();
  return stats;
}

// Two parallel regions. In the first, each thread filters and keys its range of the input into
// one list per owning thread, then accumulates the voxels it owns from its lists of every range,
// ranges in input order: every voxel sums its points in the serial order. In the second, after the
// output is sized, each thread writes its voxels' means where the serial grid has them: by first
// input index, behind the voxels of every grid that appeared earlier.
PreprocessStats VoxelGridDownsampler::RunParallel(const std::vector<TimedPoint>& in, double t_begin,
                                                  const PreprocessOptions& options, int threads,
                                                  std::vector<TimedPoint>* out) {
  PreprocessStats stats;
  const size_t stride = static_cast<size_t>(std::max(1, options.point_stride));
  const KeyMaker km{static_cast<float>(options.min_range * options.min_range),
                    static_cast<float>(options.max_range * options.max_range),
                    static_cast<float>(1.0 / options.voxel_size), t_begin,
                    options.time_bucket_s > 0.0 ? 1.0 / options.time_bucket_s : 0.0};
  const size_t sampled = (in.size() + stride - 1) / stride;
  // Every buffer the regions share is sized here, on the calling thread, for any team size up to
  // `threads` (nt * nt lists of ceil(sampled / nt) keys fit in threads * (sampled + threads)).
  // No container grows inside a region: a sanitizer sees the region's start and end only through
  // the OpenMP runtime, and a vector reallocated by whichever thread runs a `single` block reads
  // what other threads wrote.
  const size_t nt_max = static_cast<size_t>(threads);
  if (grids_.size() < nt_max) grids_.resize(nt_max);
  if (keys_.size() < nt_max * (sampled + nt_max)) {
    keys_.resize(nt_max * (sampled + nt_max));
    kept_index_.resize(nt_max * (sampled + nt_max));
  }
  // count[owner * nt + range]: keys in that list. Owner-major, so a thread's own counts are
  // strided: a row-wise copy would compile to memcpy, which TSan intercepts and then reports
  // against the caller's memset here (the runtime's fork and join are invisible to it).
  std::vector<size_t> count(nt_max * nt_max, 0);
  size_t nt_used = 1;
#pragma omp parallel num_threads(threads)
  {
#ifdef _OPENMP
    const size_t t = static_cast<size_t>(omp_get_thread_num());
    const size_t nt = static_cast<size_t>(omp_get_num_threads());
#else
    const size_t t = 0, nt = 1;
#endif
    const size_t cap = (sampled + nt - 1) / nt;  // the longest range
    if (t == 0) nt_used = nt;
    size_t n[kMaxGridThreads] = {};
    for (size_t s = sampled * t / nt, end = sampled * (t + 1) / nt; s < end; ++s) {
      const TimedPoint& tp = in[s * stride];
      if (!km.Keep(tp)) continue;
      const uint64_t key = km.Key(tp);
      const size_t o = static_cast<size_t>(Owner(key, static_cast<int>(nt)));
      const size_t at = (t * nt + o) * cap + n[o]++;
      keys_[at] = key;
      kept_index_[at] = static_cast<uint32_t>(s * stride);
    }
    for (size_t o = 0; o < nt; ++o) count[o * nt + t] = n[o];
#pragma omp barrier
    // Thread 0 is the calling thread: it sizes every grid for all the keys the grid owns.
    if (t == 0) {
      for (size_t o = 0; o < nt; ++o) {
        size_t owned = 0;
        for (size_t c = 0; c < nt; ++c) owned += count[o * nt + c];
        grids_[o].Begin(sampled / 8 / nt, owned);
      }
    }
#pragma omp barrier
    Grid& g = grids_[t];
    g.Accumulate<true>(km.t_ref, [&](auto&& add, auto&& prefetch) {
      constexpr size_t kAhead = 16;
      for (size_t c = 0; c < nt; ++c) {
        const size_t list = (c * nt + t) * cap;
        const size_t end = list + count[t * nt + c];
        for (size_t j = list; j < end; ++j) {
          if (j + kAhead < end) prefetch(keys_[j + kAhead]);
          const uint32_t i = kept_index_[j];
          add(keys_[j], in[i], i);
        }
      }
    });
  }
  const size_t nt = nt_used;
  size_t voxels = 0, valid = 0;
  for (size_t c = 0; c < nt; ++c) voxels += grids_[c].acc.size();
  for (size_t k = 0; k < nt * nt; ++k) valid += count[k];
  out->resize(voxels);
  // Each grid's first indices ascend: one pointer per other grid finds how many of its voxels
  // came first.
  const int grids = static_cast<int>(nt);
#pragma omp parallel for schedule(static, 1) num_threads(grids)
  for (int gi = 0; gi < grids; ++gi) {
    const size_t t = static_cast<size_t>(gi);
    const Grid& g = grids_[t];
    size_t before[kMaxGridThreads] = {};
    for (size_t j = 0; j < g.acc.size(); ++j) {
      const uint32_t f = g.first[j];
      size_t pos = j;
      for (size_t d = 0; d < nt; ++d) {
        if (d == t) continue;
        const std::vector<uint32_t>& other = grids_[d].first;
        while (before[d] < other.size() && other[before[d]] < f) ++before[d];
        pos += before[d];
      }
      WriteMean(g.acc[j], km.t_ref, &(*out)[pos]);
    }
  }
  stats.valid_points = valid;
  stats.downsampled_points = out->size();
  return stats;
}

}  // namespace ppf
