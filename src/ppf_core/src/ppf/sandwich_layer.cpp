#include "ppf_core/ppf/sandwich_layer.hpp"

#include <algorithm>
#include <cmath>

#include "ppf_core/detail/omp_team.hpp"

namespace ppf {

namespace {

// x86-64 builds get an AVX2 copy of the labelling loop (8 points per instruction), chosen at load
// time on CPUs that have it. Only AVX2, not FMA: a fused multiply-add rounds differently, and a
// point on the band's edge would change sides.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__linux__)
#define PPF_SANDWICH_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define PPF_SANDWICH_CLONES
#endif

// label[i] for points [begin, end): a plain function of plain values, so that the loop keeps
// them in registers and vectorises (a lambda's by-reference captures are reloaded from memory
// after every label store, which may alias them). !(a < x) counts a NaN distance as an outlier,
// as the chained comparison did.
PPF_SANDWICH_CLONES void LabelRange(const Eigen::Vector3f* points, long begin, long end, float nx,
                                    float ny, float nz, float d, float strict, float semi,
                                    uint8_t* label) {
  for (long i = begin; i < end; ++i) {
    const float a = std::abs(nx * points[i].x() + ny * points[i].y() + nz * points[i].z() + d);
    label[i] =
        static_cast<uint8_t>(static_cast<int>(!(a < strict)) + static_cast<int>(!(a < semi)));
  }
}

}  // namespace

void LabelSandwich(const std::vector<Eigen::Vector3f>& points, const Plane& plane, double delta,
                   double semi_factor, std::vector<uint8_t>* labels, SandwichSplit* split) {
  split->strict.clear();
  split->semi.clear();
  split->outliers.clear();
  const long n = static_cast<long>(points.size());
  labels->resize(points.size());
  uint8_t* label = labels->data();
  const float nx = static_cast<float>(plane.n.x()), ny = static_cast<float>(plane.n.y()),
              nz = static_cast<float>(plane.n.z()), d = static_cast<float>(plane.d);
  const float strict = static_cast<float>(delta);
  const float semi = static_cast<float>(delta * (semi_factor > 1.0 ? semi_factor : 1.0));
  // Parallel only for full-resolution scans (docs/decisions.md, "Parallel moments only for full
  // scans"), in blocks of points.
  constexpr long kBlock = 4096;
  if (n > 32768 && detail::MayOpenTeam()) {
#pragma omp parallel for schedule(static)
    for (long b = 0; b < n; b += kBlock) {
      LabelRange(points.data(), b, std::min(n, b + kBlock), nx, ny, nz, d, strict, semi, label);
    }
  } else {
    LabelRange(points.data(), 0, n, nx, ny, nz, d, strict, semi, label);
  }
  // Serial compaction keeps the order deterministic: every position is written, and the count
  // advances past the strict ones only (no branch on the label).
  split->strict.resize(static_cast<size_t>(n));
  int* strict_out = split->strict.data();
  size_t k = 0;
  for (long i = 0; i < n; ++i) {
    strict_out[k] = static_cast<int>(i);
    k += label[i] == 0 ? 1 : 0;
  }
  split->strict.resize(k);
}

void CompleteSandwich(const std::vector<uint8_t>& labels, SandwichSplit* split) {
  split->semi.clear();
  split->outliers.clear();
  const long n = static_cast<long>(labels.size());
  for (long i = 0; i < n; ++i) {
    if (labels[i] == 1) {
      split->semi.push_back(static_cast<int>(i));
    } else if (labels[i] == 2) {
      split->outliers.push_back(static_cast<int>(i));
    }
  }
}

void SplitSandwich(const std::vector<Eigen::Vector3f>& points, const Plane& plane, double delta,
                   double semi_factor, SandwichSplit* split) {
  std::vector<uint8_t> labels;
  LabelSandwich(points, plane, delta, semi_factor, &labels, split);
  CompleteSandwich(labels, split);
}

}  // namespace ppf
