#include "ppf_core/lio/preprocess.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

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

// bucket: 0..15.
uint64_t PackKey(uint64_t biased_x, uint64_t biased_y, uint64_t biased_z, int64_t bucket) {
  return ((biased_x & kKeyAxisMask) << 44) | ((biased_y & kKeyAxisMask) << 24) |
         ((biased_z & kKeyAxisMask) << 4) | static_cast<uint64_t>(bucket);
}

uint64_t Mix(uint64_t key) { return key * 0x9E3779B97F4A7C15ull; }

// The thread owning a voxel in the parallel path: a second multiplier, so that the owner is
// independent of the table slot (the top bits of Mix) and each thread's table fills evenly.
int Owner(uint64_t key, int threads) {
  const uint64_t h = (key * 0xC2B2AE3D27D4EB4Full) >> 32;
  return static_cast<int>((h * static_cast<uint64_t>(threads)) >> 32);
}

// Range filter and voxel key of one point, shared by both paths and by the vector path below,
// which must give the same keys bit for bit: the squared range sums as Eigen's squaredNorm does
// (x^2 + (y^2 + z^2)), and the time bucket is clamped in double before its truncation (a defined
// result for any time, where truncating first was undefined beyond the int64 range).
struct KeyMaker {
  float min_r2, max_r2, inv;
  double t_ref, inv_bucket;
  bool Keep(const TimedPoint& tp) const {
    const float x = tp.p.x(), y = tp.p.y(), z = tp.p.z();
    const float r2 = x * x + (y * y + z * z);
    return r2 >= min_r2 && r2 <= max_r2;
  }
  uint64_t Key(const TimedPoint& tp) const {
    double bucket = (tp.t - t_ref) * inv_bucket;
    bucket = bucket > 0.0 ? bucket : 0.0;  // NaN: 0, as the vector path's max
    bucket = bucket < 15.0 ? bucket : 15.0;
    return PackKey(KeyAxis(tp.p.x() * inv), KeyAxis(tp.p.y() * inv), KeyAxis(tp.p.z() * inv),
                   static_cast<int64_t>(bucket));
  }
};

KeyMaker MakeKeyMaker(double t_begin, const PreprocessOptions& options) {
  return KeyMaker{static_cast<float>(options.min_range * options.min_range),
                  static_cast<float>(options.max_range * options.max_range),
                  static_cast<float>(1.0 / options.voxel_size), t_begin,
                  options.time_bucket_s > 0.0 ? 1.0 / options.time_bucket_s : 0.0};
}

// The grid's first pass over a block: the key and the input offset (s - first) * stride of every
// point pts[s * stride], s in [begin, end), that passes the range filter. Returns the count; keys
// and indices hold end - begin + 4 (the vector path stores a whole lane group before it counts).
using KeyBlockFn = size_t (*)(const KeyMaker& km, const TimedPoint* pts, size_t first, size_t begin,
                              size_t end, size_t stride, uint64_t* keys, uint32_t* indices);

size_t KeyBlockScalar(const KeyMaker& km, const TimedPoint* pts, size_t first, size_t begin,
                      size_t end, size_t stride, uint64_t* keys, uint32_t* indices) {
  size_t n = 0;
  for (size_t s = begin; s < end; ++s) {
    const TimedPoint& tp = pts[s * stride];
    if (!km.Keep(tp)) continue;
    keys[n] = km.Key(tp);
    indices[n++] = static_cast<uint32_t>((s - first) * stride);
  }
  return n;
}

#if defined(__x86_64__) && defined(__GNUC__)
#define PPF_GRID_AVX2 1
static_assert(sizeof(TimedPoint) == 24, "the vector path loads x, y, z, intensity as 4 floats");

// One axis of four keys: BiasedFloor (KeyAxis) of the products, masked to the key's 20 bits.
__attribute__((target("avx2"))) inline __m256i KeyAxis4(__m128 v, __m256d bias, __m256i mask) {
  return _mm256_and_si256(
      _mm256_cvtepi32_epi64(_mm256_cvttpd_epi32(_mm256_add_pd(_mm256_cvtps_pd(v), bias))), mask);
}

// Four points per step: the range test in float and the three axis floors in double, as the
// scalar path computes them (the products in float, widened exactly, the bias added in double),
// truncated to int32 instead of int64. The two agree while |v| < 2^30 voxels; a group with a kept
// point beyond that (or a NaN product) takes the scalar path. Only AVX2, not FMA: a fused
// multiply-add would round the squared range differently.
__attribute__((target("avx2"))) size_t KeyBlockAvx2(const KeyMaker& km, const TimedPoint* pts,
                                                    size_t first, size_t begin, size_t end,
                                                    size_t stride, uint64_t* keys,
                                                    uint32_t* indices) {
  const __m128 inv = _mm_set1_ps(km.inv);
  const __m128 min_r2 = _mm_set1_ps(km.min_r2);
  const __m128 max_r2 = _mm_set1_ps(km.max_r2);
  const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  const __m128 limit = _mm_set1_ps(1073741824.f);  // 2^30
  const __m256d bias = _mm256_set1_pd(kKeyBias);
  const __m256d t_ref = _mm256_set1_pd(km.t_ref);
  const __m256d inv_bucket = _mm256_set1_pd(km.inv_bucket);
  const __m256d zero = _mm256_setzero_pd();
  const __m256d last_bucket = _mm256_set1_pd(15.0);
  const __m256i axis_mask = _mm256_set1_epi64x(static_cast<int64_t>(kKeyAxisMask));
  alignas(32) uint64_t lane_keys[4];
  size_t n = 0;
  size_t s = begin;
  for (; s + 4 <= end; s += 4) {
    const TimedPoint* p0 = pts + s * stride;
    const TimedPoint* p1 = p0 + stride;
    const TimedPoint* p2 = p1 + stride;
    const TimedPoint* p3 = p2 + stride;
    __m128 x = _mm_loadu_ps(p0->p.data());  // x, y, z, intensity
    __m128 y = _mm_loadu_ps(p1->p.data());
    __m128 z = _mm_loadu_ps(p2->p.data());
    __m128 w = _mm_loadu_ps(p3->p.data());
    _MM_TRANSPOSE4_PS(x, y, z, w);
    const __m128 r2 = _mm_add_ps(_mm_mul_ps(x, x), _mm_add_ps(_mm_mul_ps(y, y), _mm_mul_ps(z, z)));
    const int keep =
        _mm_movemask_ps(_mm_and_ps(_mm_cmpge_ps(r2, min_r2), _mm_cmple_ps(r2, max_r2)));
    if (keep == 0) continue;
    const __m128 vx = _mm_mul_ps(x, inv);
    const __m128 vy = _mm_mul_ps(y, inv);
    const __m128 vz = _mm_mul_ps(z, inv);
    const __m128 far = _mm_or_ps(_mm_or_ps(_mm_cmpnlt_ps(_mm_and_ps(vx, abs_mask), limit),
                                           _mm_cmpnlt_ps(_mm_and_ps(vy, abs_mask), limit)),
                                 _mm_cmpnlt_ps(_mm_and_ps(vz, abs_mask), limit));
    if (_mm_movemask_ps(far) & keep) {
      _mm256_zeroupper();  // before SSE code: see the return
      n += KeyBlockScalar(km, pts, first, s, s + 4, stride, keys + n, indices + n);
      continue;
    }
    __m256d bucket =
        _mm256_mul_pd(_mm256_sub_pd(_mm256_set_pd(p3->t, p2->t, p1->t, p0->t), t_ref), inv_bucket);
    bucket = _mm256_min_pd(_mm256_max_pd(bucket, zero), last_bucket);  // as KeyMaker::Key
    const __m256i key =
        _mm256_or_si256(_mm256_or_si256(_mm256_slli_epi64(KeyAxis4(vx, bias, axis_mask), 44),
                                        _mm256_slli_epi64(KeyAxis4(vy, bias, axis_mask), 24)),
                        _mm256_or_si256(_mm256_slli_epi64(KeyAxis4(vz, bias, axis_mask), 4),
                                        _mm256_cvtepi32_epi64(_mm256_cvttpd_epi32(bucket))));
    _mm256_store_si256(reinterpret_cast<__m256i*>(lane_keys), key);
    const uint32_t at = static_cast<uint32_t>((s - first) * stride);
    for (uint32_t j = 0; j < 4; ++j) {  // branch-free compaction
      keys[n] = lane_keys[j];
      indices[n] = at + j * static_cast<uint32_t>(stride);
      n += static_cast<size_t>((keep >> j) & 1);
    }
  }
  // GCC leaves the upper halves of the ymm registers set here (it does insert the vzeroupper in
  // its target_clones copies), and the SSE code after it (the scalar tail, de-skew) would run
  // with a false dependency on them until some AVX library call cleared them
  // (docs/profiles.md, thirty-second pass).
  _mm256_zeroupper();
  return n + KeyBlockScalar(km, pts, first, s, end, stride, keys + n, indices + n);
}
#endif

KeyBlockFn BestKeyBlock() {
#ifdef PPF_GRID_AVX2
  static const KeyBlockFn fn = __builtin_cpu_supports("avx2") ? KeyBlockAvx2 : KeyBlockScalar;
  return fn;
#else
  return KeyBlockScalar;
#endif
}

// Points keyed per block: its keys stay in L1 until the grid adds them, and the slot of a key a
// few points ahead is prefetched (the slot load misses the cache on most points).
constexpr size_t kKeyBlock = 512;
constexpr size_t kPrefetchAhead = 16;

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
  // Both paths know the keys ahead (a key block, the owner lists): they prefetch the slot of a
  // later key.
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
  const KeyMaker km = MakeKeyMaker(t_begin, options);

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
  const KeyBlockFn key_block = BestKeyBlock();
  const TimedPoint* points = in.data();
  uint64_t keys[kKeyBlock + 4];
  uint32_t indices[kKeyBlock + 4];
  // Inlined into Accumulate, so that its probe loop keeps the table's locals in registers.
  const auto for_each = [&](auto&& add, auto&& prefetch) __attribute__((always_inline)) {
    for (size_t b = 0; b < sampled; b += kKeyBlock) {
      const size_t n =
          key_block(km, points, b, b, std::min(sampled, b + kKeyBlock), stride, keys, indices);
      valid += n;
      const size_t offset = b * stride;
      for (size_t j = 0; j < n; ++j) {
        if (j + kPrefetchAhead < n) prefetch(keys[j + kPrefetchAhead]);
        const size_t i = offset + indices[j];
        add(keys[j], points[i], i);
      }
    }
  };
  g.Accumulate<false>(km.t_ref, for_each);
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
  const KeyMaker km = MakeKeyMaker(t_begin, options);
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
  const KeyBlockFn key_block = BestKeyBlock();
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
    uint64_t block_keys[kKeyBlock + 4];
    uint32_t block_indices[kKeyBlock + 4];
    for (size_t b = sampled * t / nt, end = sampled * (t + 1) / nt; b < end; b += kKeyBlock) {
      const size_t kept = key_block(km, in.data(), b, b, std::min(end, b + kKeyBlock), stride,
                                    block_keys, block_indices);
      for (size_t j = 0; j < kept; ++j) {
        const uint64_t key = block_keys[j];
        const size_t o = static_cast<size_t>(Owner(key, static_cast<int>(nt)));
        const size_t at = (t * nt + o) * cap + n[o]++;
        keys_[at] = key;
        kept_index_[at] = static_cast<uint32_t>(b * stride + block_indices[j]);
      }
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
      for (size_t c = 0; c < nt; ++c) {
        const size_t list = (c * nt + t) * cap;
        const size_t end = list + count[t * nt + c];
        for (size_t j = list; j < end; ++j) {
          if (j + kPrefetchAhead < end) prefetch(keys_[j + kPrefetchAhead]);
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

namespace detail {

bool GridKeysHaveVectorPath() { return BestKeyBlock() != KeyBlockScalar; }

size_t GridKeys(bool vector, const std::vector<TimedPoint>& in, size_t begin, size_t end,
                size_t stride, double t_begin, const PreprocessOptions& options, uint64_t* keys,
                uint32_t* indices) {
  const KeyBlockFn fn = vector ? BestKeyBlock() : KeyBlockScalar;
  return fn(MakeKeyMaker(t_begin, options), in.data(), begin, begin, end, stride, keys, indices);
}

}  // namespace detail

}  // namespace ppf
