#include "ppf_core/ppf/ipca.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <Eigen/Eigenvalues>

namespace ppf {
namespace {

// A pass over a downsampled scan is cheaper serially than a fork/join once the cores are shared
// (a barrier waiting for a preempted thread costs a scheduler slice; docs/decisions.md,
// "Parallel moments only for full scans"). Parallel only for large inputs (full-resolution
// scans).
constexpr long kParallelPoints = 32768;

// First and second moments of a point subset, about a reference point to avoid cancellation.
struct Moments {
  int count = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
};

// x86-64 builds get an AVX2 copy of the band test (4 doubles per instruction), chosen at load
// time on CPUs that have it. Only AVX2, not FMA: a fused multiply-add rounds differently, and a
// point on the band's edge would change sides.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__linux__)
#define PPF_IPCA_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define PPF_IPCA_CLONES
#endif

// in[i] = whether |n.p_i + d| < delta, the same double expression as the summing loop used to
// test; branch-free, so it vectorises.
PPF_IPCA_CLONES void BandMask(const Eigen::Vector3f* points, long n, double nx, double ny,
                              double nz, double pd, double delta, uint8_t* in) {
  for (long i = 0; i < n; ++i) {
    const double px = points[i].x(), py = points[i].y(), pz = points[i].z();
    in[i] = std::abs(nx * px + ny * py + nz * pz + pd) < delta ? 1 : 0;
  }
}

// Moments of the points with |n.p + d| < delta (all points if plane == nullptr).
Moments Accumulate(const std::vector<Eigen::Vector3f>& points, const Plane* plane, double delta,
                   const Eigen::Vector3d& ref) {
  const long n = static_cast<long>(points.size());
  const double nx = plane ? plane->n.x() : 0.0, ny = plane ? plane->n.y() : 0.0,
               nz = plane ? plane->n.z() : 0.0, pd = plane ? plane->d : 0.0;
  const bool all = plane == nullptr;
  int count = 0;
  double sx = 0, sy = 0, sz = 0, sxx = 0, sxy = 0, sxz = 0, syy = 0, syz = 0, szz = 0;
  if (n > kParallelPoints) {
#pragma omp parallel for schedule(static) \
    reduction(+ : count, sx, sy, sz, sxx, sxy, sxz, syy, syz, szz)
    for (long i = 0; i < n; ++i) {
      const double px = points[i].x(), py = points[i].y(), pz = points[i].z();
      if (!all && !(std::abs(nx * px + ny * py + nz * pz + pd) < delta)) continue;
      const double x = px - ref.x(), y = py - ref.y(), z = pz - ref.z();
      ++count;
      sx += x, sy += y, sz += z;
      sxx += x * x, sxy += x * y, sxz += x * z, syy += y * y, syz += y * z, szz += z * z;
    }
  } else {
    // Most points of a scan lie off any one plane: the band test runs over all of them in a
    // vectorised pass, and the sums, in the same order as a single pass would make them, only
    // over the points in the band.
    std::vector<uint8_t> in;
    if (!all) {
      in.resize(static_cast<size_t>(n));
      BandMask(points.data(), n, nx, ny, nz, pd, delta, in.data());
    }
    for (long i = 0; i < n; ++i) {
      if (!all && in[static_cast<size_t>(i)] == 0) continue;
      const double x = static_cast<double>(points[i].x()) - ref.x(),
                   y = static_cast<double>(points[i].y()) - ref.y(),
                   z = static_cast<double>(points[i].z()) - ref.z();
      ++count;
      sx += x, sy += y, sz += z;
      sxx += x * x, sxy += x * y, sxz += x * z, syy += y * y, syz += y * z, szz += z * z;
    }
  }
  Moments m;
  m.count = count;
  m.sum << sx, sy, sz;
  m.outer << sxx, sxy, sxz, sxy, syy, syz, sxz, syz, szz;
  return m;
}

// Plane of least squared orthogonal distance for the moments; empty if degenerate (the two
// smallest eigenvalues are both ~0: the points lie on a line or coincide).
std::optional<Plane> PlaneFromMoments(const Moments& m, const Eigen::Vector3d& ref) {
  if (m.count < 3) return std::nullopt;
  const Eigen::Vector3d mean = m.sum / m.count;
  const Eigen::Matrix3d cov = m.outer / m.count - mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  if (eig.info() != Eigen::Success) return std::nullopt;
  const Eigen::Vector3d ev = eig.eigenvalues();  // ascending
  if (!(ev[1] > 1e-10 * std::max(1.0, ev[2]))) return std::nullopt;
  const Eigen::Vector3d n = eig.eigenvectors().col(0).normalized();
  if (!n.allFinite()) return std::nullopt;
  const Eigen::Vector3d centroid = mean + ref;
  return Plane{n, -n.dot(centroid)};
}

}  // namespace

bool IpcaCountsOscillate(const std::vector<int>& c) {
  const size_t k = c.size();
  if (k < 4) return false;
  return c[k - 1] == c[k - 3] && c[k - 2] == c[k - 4] && c[k - 1] != c[k - 2];
}

IpcaResult RefinePlaneIpca(const std::vector<Eigen::Vector3f>& points, const Plane& initial,
                           double delta, int max_iterations, int min_inliers) {
  IpcaResult result;
  result.plane = initial;
  const int least = std::max(3, min_inliers);
  if (points.empty()) return result;
  const Eigen::Vector3d ref = points.front().cast<double>();

  Moments m = Accumulate(points, &initial, delta, ref);
  result.num_inliers = m.count;
  result.inlier_counts.push_back(m.count);
  for (int it = 0; it < max_iterations; ++it) {
    if (m.count < least) return result;
    std::optional<Plane> next = PlaneFromMoments(m, ref);
    if (!next) return result;
    // Keep the orientation of the initial plane: guesses and tracks compare signed offsets.
    if (next->n.dot(result.plane.n) < 0.0) *next = next->Flipped();
    const int previous = m.count;
    m = Accumulate(points, &*next, delta, ref);
    result.plane = *next;
    result.num_inliers = m.count;
    result.iterations = it + 1;
    result.inlier_counts.push_back(m.count);
    if (IpcaCountsOscillate(result.inlier_counts)) {
      result.oscillated = true;
      return result;
    }
    if (m.count == previous) break;  // the inlier set no longer changes
  }
  result.success = result.num_inliers >= least;
  return result;
}

std::optional<Plane> FitPlaneLeastSquares(const std::vector<Eigen::Vector3f>& points) {
  if (points.size() < 3) return std::nullopt;
  const Eigen::Vector3d ref = points.front().cast<double>();
  return PlaneFromMoments(Accumulate(points, nullptr, 0.0, ref), ref);
}

}  // namespace ppf
