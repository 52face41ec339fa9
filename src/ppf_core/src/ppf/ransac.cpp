#include "ppf_core/ppf/ransac.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "ppf_core/detail/omp_team.hpp"

namespace ppf {
namespace {

// Hypotheses scored per parallel batch. Fixed (not tied to the thread count) so the sequence of
// samples and the adaptive stop are identical for any number of threads.
constexpr int kBatch = 16;
// Below this many point evaluations a parallel region costs more than it saves: serial scoring
// runs at ~1 ns per point, and a fork/join on a shared 2-core machine can cost a scheduler slice.
constexpr long kParallelWork = 262144;

struct Hypothesis {
  Eigen::Vector3f n;
  float d;
};

// Structure-of-arrays copy of the points: the scoring loop below then vectorises (4-8 points per
// instruction); with Vector3f's 12-byte stride it does not.
struct SoaPoints {
  std::vector<float> x, y, z;
  // Every stride-th point of pts (all of them for stride 1).
  SoaPoints(const std::vector<Eigen::Vector3f>& pts, size_t stride) {
    const size_t m = (pts.size() + stride - 1) / stride;
    x.resize(m);
    y.resize(m);
    z.resize(m);
    for (size_t i = 0, j = 0; j < m; i += stride, ++j) {
      x[j] = pts[i].x();
      y[j] = pts[i].y();
      z[j] = pts[i].z();
    }
  }
  // The points of pts that SoaPoints(pts, stride) leaves out, in order (none for stride 1).
  static SoaPoints Complement(const std::vector<Eigen::Vector3f>& pts, size_t stride) {
    SoaPoints out;
    const size_t m = pts.size() - (pts.size() + stride - 1) / stride;
    out.x.resize(m);
    out.y.resize(m);
    out.z.resize(m);
    // Sized first and written through local pointers: push_back stored each vector's end back
    // to memory on every point.
    float* x = out.x.data();
    float* y = out.y.data();
    float* z = out.z.data();
    const Eigen::Vector3f* p = pts.data();
    size_t j = 0;
    for (size_t begin = 0; begin < pts.size(); begin += stride) {
      // The points after the subset's point `begin`, up to the next one.
      const size_t end = std::min(pts.size(), begin + stride);
      for (size_t i = begin + 1; i < end; ++i, ++j) {
        x[j] = p[i].x();
        y[j] = p[i].y();
        z[j] = p[i].z();
      }
    }
    return out;
  }

 private:
  SoaPoints() = default;
};

// Pre-test: most hypotheses (three points on different surfaces) have a small fraction of the
// support of the best plane so far, or of the least support a plane needs (min_inliers). Each is
// first counted on a strided subset (every kPretestMaxStride-th point at most, at least
// kPretestMinSubset points) and only counted in full if its subset count projects to at least half
// that reference. The rejection is trusted only when the reference's expected subset count is at
// least kPretestMinExpected, so a hypothesis as good as the reference is rejected only by a rare
// sampling fluctuation (and one merely equal to the best would not replace it anyway).
constexpr size_t kPretestMaxStride = 8;
constexpr size_t kPretestMinSubset = 256;
constexpr long kPretestMinExpected = 16;

// x86-64 builds get an AVX2 copy of the counting loops (8 points per instruction instead of SSE2's
// 4), chosen at load time on CPUs that have it. Only AVX2, not FMA: a fused multiply-add rounds
// differently, and a point on the band's edge would change sides.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__linux__)
#define PPF_RANSAC_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define PPF_RANSAC_CLONES
#endif

// Inliers of h among points [begin, end).
PPF_RANSAC_CLONES int CountRangeSoa(const SoaPoints& p, const Hypothesis& h, float delta,
                                    size_t begin, size_t end) {
  const float nx = h.n.x(), ny = h.n.y(), nz = h.n.z(), d = h.d;
  const float* x = p.x.data();
  const float* y = p.y.data();
  const float* z = p.z.data();
  int count = 0;
  for (size_t i = begin; i < end; ++i) {
    const float dist = nx * x[i] + ny * y[i] + nz * z[i] + d;
    count += (std::abs(dist) < delta) ? 1 : 0;
  }
  return count;
}

int CountInliersSoa(const SoaPoints& p, const Hypothesis& h, float delta) {
  return CountRangeSoa(p, h, delta, 0, p.x.size());
}

// Inliers of each of h[0, nh) among all points of p: four hypotheses per pass over the points,
// so each point's loads and the loop's own instructions serve four counts (a pre-test subset is
// a few hundred points, where those are a large part of a count). The same float expression
// per point and hypothesis as CountRangeSoa, so the same counts.
PPF_RANSAC_CLONES void CountManySoa(const SoaPoints& p, const Hypothesis* h, int nh, float delta,
                                    int* counts) {
  const float* x = p.x.data();
  const float* y = p.y.data();
  const float* z = p.z.data();
  const size_t n = p.x.size();
  int b = 0;
  for (; b + 4 <= nh; b += 4) {
    const float nx0 = h[b].n.x(), ny0 = h[b].n.y(), nz0 = h[b].n.z(), d0 = h[b].d;
    const float nx1 = h[b + 1].n.x(), ny1 = h[b + 1].n.y(), nz1 = h[b + 1].n.z(), d1 = h[b + 1].d;
    const float nx2 = h[b + 2].n.x(), ny2 = h[b + 2].n.y(), nz2 = h[b + 2].n.z(), d2 = h[b + 2].d;
    const float nx3 = h[b + 3].n.x(), ny3 = h[b + 3].n.y(), nz3 = h[b + 3].n.z(), d3 = h[b + 3].d;
    int c0 = 0, c1 = 0, c2 = 0, c3 = 0;
    for (size_t i = 0; i < n; ++i) {
      const float xi = x[i], yi = y[i], zi = z[i];
      c0 += (std::abs(nx0 * xi + ny0 * yi + nz0 * zi + d0) < delta) ? 1 : 0;
      c1 += (std::abs(nx1 * xi + ny1 * yi + nz1 * zi + d1) < delta) ? 1 : 0;
      c2 += (std::abs(nx2 * xi + ny2 * yi + nz2 * zi + d2) < delta) ? 1 : 0;
      c3 += (std::abs(nx3 * xi + ny3 * yi + nz3 * zi + d3) < delta) ? 1 : 0;
    }
    counts[b] = c0;
    counts[b + 1] = c1;
    counts[b + 2] = c2;
    counts[b + 3] = c3;
  }
  for (; b < nh; ++b) counts[b] = CountRangeSoa(p, h[b], delta, 0, n);
}

// Scores of hypotheses with no exact count; both below any count, so neither becomes the best.
constexpr int kPretestRejected = -1;  // the pre-test on the subset rejected it
constexpr int kAbandoned = -2;        // its full count stopped early (CountInliersAbove)

// A full count that stops as soon as h can no longer have more than `floor` inliers: it could
// not replace the best hypothesis then, so its exact count does not matter (returns kAbandoned).
// A hypothesis that can still exceed `floor` is counted exactly, so the result is the same as
// with every count complete.
constexpr size_t kCountBlock = 512;

int CountInliersAbove(const SoaPoints& p, const Hypothesis& h, float delta, int floor) {
  const size_t n = p.x.size();
  int count = 0;
  for (size_t begin = 0; begin < n; begin += kCountBlock) {
    const size_t end = std::min(n, begin + kCountBlock);
    count += CountRangeSoa(p, h, delta, begin, end);
    if (static_cast<long>(count) + static_cast<long>(n - end) <= floor) return kAbandoned;
  }
  return count;
}

}  // namespace

int RansacIterationsNeeded(double inlier_ratio, double confidence, int max_iterations) {
  max_iterations = std::max(1, max_iterations);
  if (!(inlier_ratio > 0.0)) return max_iterations;
  if (inlier_ratio >= 1.0) return 1;
  const double w3 = inlier_ratio * inlier_ratio * inlier_ratio;
  const double denom = std::log1p(-w3);  // log(1 - w^3), accurate for tiny w^3
  if (!(denom < 0.0)) return max_iterations;
  const double k = std::log(1.0 - std::clamp(confidence, 0.0, 1.0 - 1e-12)) / denom;
  if (!std::isfinite(k) || k >= max_iterations) return max_iterations;
  return std::max(1, static_cast<int>(std::ceil(k)));
}

int CountPlaneInliers(const std::vector<Eigen::Vector3f>& points, const Plane& plane,
                      double delta) {
  const float nx = static_cast<float>(plane.n.x()), ny = static_cast<float>(plane.n.y()),
              nz = static_cast<float>(plane.n.z()), d = static_cast<float>(plane.d);
  const float fdelta = static_cast<float>(delta);
  const long n = static_cast<long>(points.size());
  const auto inlier = [&](long i) {
    const auto& p = points[i];
    return (std::abs(nx * p.x() + ny * p.y() + nz * p.z() + d) < fdelta) ? 1 : 0;
  };
  int count = 0;
  if (n > kParallelWork / 8 && detail::MayOpenTeam()) {
#pragma omp parallel for reduction(+ : count) schedule(static)
    for (long i = 0; i < n; ++i) count += inlier(i);
  } else {
    for (long i = 0; i < n; ++i) count += inlier(i);
  }
  return count;
}

RansacResult FitPlaneRansac(const std::vector<Eigen::Vector3f>& points, const RansacParams& params,
                            SplitMix64* rng) {
  RansacResult result;
  const size_t n = points.size();
  if (n < 3 || n > std::numeric_limits<uint32_t>::max()) return result;
  const int max_iterations = std::max(1, params.max_iterations);
  const int max_degenerate = std::max(1, params.max_degenerate_samples);
  const float delta = static_cast<float>(params.delta);
  const int min_inliers = std::max(3, params.min_inliers);

  const size_t stride = std::clamp<size_t>(n / kPretestMinSubset, 1, kPretestMaxStride);
  // The pre-test's subset and the other points: a full count is the subset's count (which the
  // pre-test has made already) plus the others', so no point is counted twice.
  const SoaPoints subset(points, stride > 1 ? stride : n);  // unused when stride is 1
  const SoaPoints rest = stride > 1 ? SoaPoints::Complement(points, stride) : SoaPoints(points, 1);
  const long m = static_cast<long>(subset.x.size());
  int needed = max_iterations;
  int best_count = -1;
  Hypothesis best{Eigen::Vector3f::UnitZ(), 0.0f};
  Hypothesis batch[kBatch];
  int batch_count[kBatch];

  while (result.iterations < needed && result.degenerate_samples < max_degenerate) {
    // Draw the batch serially: the sample sequence must not depend on the thread schedule.
    int filled = 0;
    const int want = std::min(kBatch, needed - result.iterations);
    while (filled < want && result.degenerate_samples < max_degenerate) {
      const uint32_t i0 = rng->Below(static_cast<uint32_t>(n));
      const uint32_t i1 = rng->Below(static_cast<uint32_t>(n));
      const uint32_t i2 = rng->Below(static_cast<uint32_t>(n));
      std::optional<Plane> plane;
      if (i0 != i1 && i1 != i2 && i0 != i2) {
        plane = Plane::FromPoints(points[i0].cast<double>(), points[i1].cast<double>(),
                                  points[i2].cast<double>(), params.min_sample_area);
      }
      if (!plane) {
        ++result.degenerate_samples;
        continue;
      }
      batch[filled].n = plane->n.cast<float>();
      batch[filled].d = static_cast<float>(plane->d);
      ++filled;
    }
    if (filled == 0) break;

    // The reference is fixed during the batch, so the pre-test decisions do not depend on threads.
    const long reference = std::max<long>(best_count, min_inliers);
    const bool pretest = stride > 1 && reference * m >= kPretestMinExpected * static_cast<long>(n);
    const bool parallel = static_cast<long>(n) * filled > kParallelWork && detail::MayOpenTeam();
    // Serially the batch's pre-test counts are made together, four hypotheses per pass.
    int sub_count[kBatch];
    if (pretest && !parallel) CountManySoa(subset, batch, filled, delta, sub_count);
    const auto score = [&](int b) {
      int sub = 0;
      if (pretest) {
        sub = parallel ? CountInliersSoa(subset, batch[b], delta) : sub_count[b];
        if (2 * static_cast<long>(sub) * static_cast<long>(n) < reference * m) {
          batch_count[b] = kPretestRejected;
          return;
        }
      } else if (stride > 1) {
        sub = CountInliersSoa(subset, batch[b], delta);
      }
      // Abandoned exactly when the whole count could not exceed best_count either.
      const int others = CountInliersAbove(rest, batch[b], delta, best_count - sub);
      batch_count[b] = others == kAbandoned ? kAbandoned : sub + others;
    };
    if (parallel) {
#pragma omp parallel for schedule(static)
      for (int b = 0; b < filled; ++b) score(b);
    } else {
      for (int b = 0; b < filled; ++b) score(b);
    }

    for (int b = 0; b < filled; ++b) {
      ++result.iterations;
      if (batch_count[b] == kPretestRejected) ++result.pretest_rejected;
      if (batch_count[b] == kAbandoned) ++result.count_abandoned;
      if (batch_count[b] > best_count) {
        best_count = batch_count[b];
        best = batch[b];
        needed = RansacIterationsNeeded(static_cast<double>(best_count) / static_cast<double>(n),
                                        params.confidence, max_iterations);
      }
    }
  }

  if (best_count < 0) return result;  // only degenerate samples, or none passed the pre-test
  result.num_inliers = best_count;
  result.plane.n = best.n.cast<double>().normalized();
  result.plane.d = static_cast<double>(best.d);
  result.success = best_count >= min_inliers;
  return result;
}

}  // namespace ppf
