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

// The band kept between passes (Near), beyond delta, in multiples of delta: wider keeps more
// points per pass and lets a plane move farther before a pass over all points is needed. Only
// the cost depends on it, never the result.
constexpr double kNearWidthInDeltas = 4.0;

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

// in[i] = 2 if |n.p_i + d| < delta (BandMask's test), 1 if only < wide, 0 otherwise.
PPF_IPCA_CLONES void BandLevels(const Eigen::Vector3f* points, long n, double nx, double ny,
                                double nz, double pd, double delta, double wide, uint8_t* in) {
  for (long i = 0; i < n; ++i) {
    const double px = points[i].x(), py = points[i].y(), pz = points[i].z();
    const double a = std::abs(nx * px + ny * py + nz * pz + pd);
    in[i] = static_cast<uint8_t>(static_cast<int>(a < delta) + static_cast<int>(a < wide));
  }
}

// Moments of the points with in[i] == level (every point if in is null), summed in input order.
Moments SumLevel(const std::vector<Eigen::Vector3f>& points, const uint8_t* in, uint8_t level,
                 const Eigen::Vector3d& ref) {
  const long n = static_cast<long>(points.size());
  int count = 0;
  double sx = 0, sy = 0, sz = 0, sxx = 0, sxy = 0, sxz = 0, syy = 0, syz = 0, szz = 0;
  for (long i = 0; i < n; ++i) {
    if (in != nullptr && in[i] != level) continue;
    const double x = static_cast<double>(points[i].x()) - ref.x(),
                 y = static_cast<double>(points[i].y()) - ref.y(),
                 z = static_cast<double>(points[i].z()) - ref.z();
    ++count;
    sx += x, sy += y, sz += z;
    sxx += x * x, sxy += x * y, sxz += x * z, syy += y * y, syz += y * z, szz += z * z;
  }
  Moments m;
  m.count = count;
  m.sum << sx, sy, sz;
  m.outer << sxx, sxy, sxz, sxy, syy, syz, sxz, syz, szz;
  return m;
}

// Moments of the points with |n.p + d| < delta (all points if plane == nullptr).
Moments Accumulate(const std::vector<Eigen::Vector3f>& points, const Plane* plane, double delta,
                   const Eigen::Vector3d& ref) {
  const long n = static_cast<long>(points.size());
  const double nx = plane ? plane->n.x() : 0.0, ny = plane ? plane->n.y() : 0.0,
               nz = plane ? plane->n.z() : 0.0, pd = plane ? plane->d : 0.0;
  const bool all = plane == nullptr;
  if (n <= kParallelPoints) {
    // Most points of a scan lie off any one plane: the band test runs over all of them in a
    // vectorised pass, and the sums, in the same order as a single pass would make them, only
    // over the points in the band.
    if (all) return SumLevel(points, nullptr, 0, ref);
    std::vector<uint8_t> in(static_cast<size_t>(n));
    BandMask(points.data(), n, nx, ny, nz, pd, delta, in.data());
    return SumLevel(points, in.data(), 1, ref);
  }
  int count = 0;
  double sx = 0, sy = 0, sz = 0, sxx = 0, sxy = 0, sxz = 0, syy = 0, syz = 0, szz = 0;
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
  Moments m;
  m.count = count;
  m.sum << sx, sy, sz;
  m.outer << sxx, sxy, sxz, sxy, syy, syz, sxz, syz, szz;
  return m;
}

// The points within delta + width of a plane, kept between the passes of one refinement
// (RefinePlaneIpca): a later plane that moved less than `width` anywhere within the points' reach
// has no strict inlier outside them, so its pass visits these only, copied in input order: it sums
// the same points in the same order as a pass over all points.
struct Near {
  std::vector<Eigen::Vector3f> points;
  Plane plane;  // the plane they lie near
  double width = 0.0;
};

// Accumulate over all points (the serial path), also collecting `near` around `plane`.
Moments AccumulateAndCollect(const std::vector<Eigen::Vector3f>& points, const Plane& plane,
                             double delta, const Eigen::Vector3d& ref, double width,
                             std::vector<uint8_t>* in, Near* near) {
  const long n = static_cast<long>(points.size());
  in->resize(static_cast<size_t>(n));
  BandLevels(points.data(), n, plane.n.x(), plane.n.y(), plane.n.z(), plane.d, delta, delta + width,
             in->data());
  const Moments m = SumLevel(points, in->data(), 2, ref);
  near->points.resize(static_cast<size_t>(n));
  Eigen::Vector3f* out = near->points.data();
  const uint8_t* level = in->data();
  size_t k = 0;
  for (long i = 0; i < n; ++i) {
    out[k] = points[i];
    k += level[i] != 0 ? 1 : 0;
  }
  near->points.resize(k);
  near->plane = plane;
  near->width = width;
  return m;
}

// Accumulate over `near`'s points only, with BandMask's test.
Moments AccumulateNear(const Near& near, const Plane& plane, double delta,
                       const Eigen::Vector3d& ref, std::vector<uint8_t>* in) {
  const long n = static_cast<long>(near.points.size());
  in->resize(static_cast<size_t>(n));
  BandMask(near.points.data(), n, plane.n.x(), plane.n.y(), plane.n.z(), plane.d, delta,
           in->data());
  return SumLevel(near.points, in->data(), 1, ref);
}

// Whether `plane` moved less than near.width from near.plane at every point within max_norm of
// the origin: |(n - n0).p + (d - d0)| <= |n - n0| max_norm + |d - d0|, with a margin far above
// the rounding of the distances.
bool NearHolds(const Near& near, const Plane& plane, double max_norm) {
  const double moved =
      (plane.n - near.plane.n).norm() * max_norm + std::abs(plane.d - near.plane.d);
  return moved + 1e-6 < near.width;
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
                           double delta, int max_iterations, int min_inliers, double max_norm) {
  IpcaResult result;
  result.plane = initial;
  const int least = std::max(3, min_inliers);
  if (points.empty()) return result;
  const Eigen::Vector3d ref = points.front().cast<double>();

  // With a bound on the points' reach, a pass over all points also keeps those near its plane,
  // and a later plane close to that one sums only them (same sums); the parallel path (full
  // scans) always passes over all points.
  const bool use_near = max_norm > 0.0 && std::isfinite(max_norm) &&
                        static_cast<long>(points.size()) <= kParallelPoints;
  const double near_width = kNearWidthInDeltas * delta;
  Near near;
  std::vector<uint8_t> in;
  const auto pass = [&](const Plane& plane) {
    if (!use_near) return Accumulate(points, &plane, delta, ref);
    // near.width is set by the first collecting pass.
    if (near.width > 0.0 && NearHolds(near, plane, max_norm)) {
      return AccumulateNear(near, plane, delta, ref, &in);
    }
    return AccumulateAndCollect(points, plane, delta, ref, near_width, &in, &near);
  };

  Moments m = pass(initial);
  result.num_inliers = m.count;
  result.inlier_counts.push_back(m.count);
  for (int it = 0; it < max_iterations; ++it) {
    if (m.count < least) return result;
    std::optional<Plane> next = PlaneFromMoments(m, ref);
    if (!next) return result;
    // Keep the orientation of the initial plane: guesses and tracks compare signed offsets.
    if (next->n.dot(result.plane.n) < 0.0) *next = next->Flipped();
    const int previous = m.count;
    m = pass(*next);
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
