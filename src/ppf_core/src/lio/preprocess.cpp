#include "ppf_core/lio/preprocess.hpp"

#include <algorithm>
#include <cmath>

namespace ppf {
namespace {

// 20 bits per axis (+-2^19 voxels, +-262 km at 0.5 m: the scan is in the sensor frame) and
// 4 bits of time bucket.
uint64_t PackKey(int64_t x, int64_t y, int64_t z, int64_t bucket) {
  constexpr int64_t kBias = int64_t{1} << 19;
  constexpr uint64_t kMask = (uint64_t{1} << 20) - 1;
  return ((static_cast<uint64_t>(x + kBias) & kMask) << 44) |
         ((static_cast<uint64_t>(y + kBias) & kMask) << 24) |
         ((static_cast<uint64_t>(z + kBias) & kMask) << 4) |
         static_cast<uint64_t>(std::clamp<int64_t>(bucket, 0, 15));
}

uint64_t Mix(uint64_t key) { return key * 0x9E3779B97F4A7C15ull; }

// floor() for the voxel index of a range-filtered (finite, bounded) coordinate: truncation, one
// less for negative non-integers. Equal to std::floor there (the truncation of a float is a float),
// without the rounding-mode sequence the compiler emits for floorf on baseline x86-64.
int64_t FloorToInt(float v) {
  const int64_t i = static_cast<int64_t>(v);
  return i - (v < static_cast<float>(i) ? 1 : 0);
}

}  // namespace

void VoxelGridDownsampler::Reserve(size_t expected_voxels) {
  size_t capacity = 1024;
  while (capacity < 2 * expected_voxels) capacity <<= 1;
  if (capacity <= table_.size()) return;
  // Re-insert the voxels of the current call: Run() grows the table mid-scan when needed.
  std::vector<Slot> old;
  old.swap(table_);
  table_.assign(capacity, Slot());
  const int shift = 64 - __builtin_ctzll(capacity);
  for (const Slot& s : old) {
    if (s.generation != generation_) continue;
    for (size_t h = Mix(s.key) >> shift;; h = (h + 1) & (capacity - 1)) {
      if (table_[h].generation != generation_) {
        table_[h] = s;
        break;
      }
    }
  }
}

PreprocessStats VoxelGridDownsampler::Run(const std::vector<TimedPoint>& in, double t_begin,
                                          const PreprocessOptions& options,
                                          std::vector<TimedPoint>* out) {
  PreprocessStats stats;
  out->clear();
  const size_t stride = static_cast<size_t>(std::max(1, options.point_stride));
  const float min_r2 = static_cast<float>(options.min_range * options.min_range);
  const float max_r2 = static_cast<float>(options.max_range * options.max_range);
  auto keep = [&](const TimedPoint& tp) {
    const float r2 = tp.p.squaredNorm();
    return r2 >= min_r2 && r2 <= max_r2;
  };

  if (!(options.voxel_size > 1e-3)) {
    out->reserve(in.size() / stride + 1);
    for (size_t i = 0; i < in.size(); i += stride) {
      if (keep(in[i])) out->push_back(in[i]);
    }
    stats.valid_points = stats.downsampled_points = out->size();
    return stats;
  }

  if (++generation_ == 0) {  // wrapped after 2^32 scans: forget every stamp once
    table_.assign(table_.size(), Slot());
    generation_ = 1;
  }
  acc_.clear();
  Reserve(in.size() / stride / 8);
  const float inv = static_cast<float>(1.0 / options.voxel_size);
  const double t_ref = t_begin;
  const double inv_bucket = options.time_bucket_s > 0.0 ? 1.0 / options.time_bucket_s : 0.0;
  size_t mask = table_.size() - 1;
  int shift = 64 - __builtin_ctzll(table_.size());
  size_t valid = 0;
  for (size_t i = 0; i < in.size(); i += stride) {
    const TimedPoint& tp = in[i];
    if (!keep(tp)) continue;
    ++valid;
    const uint64_t key =
        PackKey(FloorToInt(tp.p.x() * inv), FloorToInt(tp.p.y() * inv), FloorToInt(tp.p.z() * inv),
                static_cast<int64_t>((tp.t - t_ref) * inv_bucket));
    size_t h = Mix(key) >> shift;
    while (table_[h].generation == generation_ && table_[h].key != key) h = (h + 1) & mask;
    Slot& slot = table_[h];
    uint32_t index = slot.index;
    if (slot.generation != generation_) {
      index = static_cast<uint32_t>(acc_.size());
      slot = Slot{key, generation_, index};
      acc_.emplace_back();
      if (2 * acc_.size() > table_.size()) {
        Reserve(acc_.size() * 2);  // moves slots, not indices
        mask = table_.size() - 1;
        shift = 64 - __builtin_ctzll(table_.size());
      }
    }
    Accumulator& acc = acc_[index];
    acc.x += tp.p.x();
    acc.y += tp.p.y();
    acc.z += tp.p.z();
    acc.dt += tp.t - t_ref;
    acc.intensity += tp.intensity;
    ++acc.count;
  }
  stats.valid_points = valid;
  out->resize(acc_.size());
  for (size_t i = 0; i < acc_.size(); ++i) {
    const Accumulator& a = acc_[i];
    const double inv_n = 1.0 / a.count;
    TimedPoint& tp = (*out)[i];
    tp.p = Eigen::Vector3f(static_cast<float>(a.x * inv_n), static_cast<float>(a.y * inv_n),
                           static_cast<float>(a.z * inv_n));
    tp.intensity = static_cast<float>(a.intensity * inv_n);
    tp.t = t_ref + a.dt * inv_n;
  }
  stats.downsampled_points = out->size();
  return stats;
}

}  // namespace ppf
