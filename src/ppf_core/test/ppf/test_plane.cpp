#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "ppf_core/ppf/plane.hpp"

namespace ppf {
namespace {

Eigen::Isometry3d SomePose(double yaw, double pitch, double roll, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = t;
  return T;
}

Plane SomePlane() { return *Plane::FromCoefficients(Eigen::Vector4d(0.3, -0.5, 0.8, -4.2)); }

TEST(PpfPlane, TheoremOneRoundTripRestoresThePlane) {
  const Eigen::Isometry3d T_b_a = SomePose(0.7, -0.2, 0.4, {12.0, -3.0, 1.5});
  const Plane f_a = SomePlane();
  const Plane f_b = TransformPlane(T_b_a, f_a);
  const Plane back = TransformPlane(T_b_a.inverse(), f_b);
  EXPECT_LT((back.n - f_a.n).norm(), 1e-12);
  EXPECT_NEAR(back.d, f_a.d, 1e-12);
  EXPECT_NEAR(f_b.n.norm(), 1.0, 1e-12);  // rigid motion keeps the normal unit length
}

TEST(PpfPlane, PointsMovedByTLieOnTheTransformedPlane) {
  const Eigen::Isometry3d T_b_a = SomePose(-1.1, 0.3, 0.05, {-4.0, 7.0, 0.2});
  const Plane f_a = SomePlane();
  const Plane f_b = TransformPlane(T_b_a, f_a);
  // Points on f_a: foot of the origin plus in-plane offsets.
  const Eigen::Vector3d foot = -f_a.d * f_a.n;
  const Eigen::Vector3d u = f_a.n.unitOrthogonal(), v = f_a.n.cross(u);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> uni(-30.0, 30.0);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d p_a = foot + uni(rng) * u + uni(rng) * v;
    ASSERT_NEAR(f_a.SignedDistance(p_a), 0.0, 1e-10);
    EXPECT_NEAR(f_b.SignedDistance(T_b_a * p_a), 0.0, 1e-10);
  }
  // Signed distances of off-plane points are preserved, too (metric in every frame).
  const Eigen::Vector3d off = foot + 0.37 * f_a.n;
  EXPECT_NEAR(f_b.SignedDistance(T_b_a * off), 0.37, 1e-10);
}

TEST(PpfPlane, ClosedFormEqualsInverseTransposeMatrix) {
  const Eigen::Isometry3d T = SomePose(2.0, 0.5, -0.7, {1.0, 2.0, 3.0});
  const Plane f = SomePlane();
  const Eigen::Vector4d general = T.matrix().inverse().transpose() * f.Coefficients();
  const Plane closed = TransformPlane(T, f);
  EXPECT_LT((general - closed.Coefficients()).norm(), 1e-12);
}

TEST(PpfPlane, FromPointsRejectsCollinearAndCoincidentSamples) {
  const Eigen::Vector3d a(1, 2, 3), b(2, 4, 6), c(3, 6, 9);  // collinear
  EXPECT_FALSE(Plane::FromPoints(a, b, c, 1e-6).has_value());
  EXPECT_FALSE(Plane::FromPoints(a, a, a, 0.0).has_value());  // coincident, even with 0 guard
  EXPECT_FALSE(Plane::FromPoints(a, a, b, 0.0).has_value());
  const auto p = Plane::FromPoints({0, 0, 1}, {1, 0, 1}, {0, 1, 1}, 1e-6);
  ASSERT_TRUE(p.has_value());
  EXPECT_NEAR(std::abs(p->n.z()), 1.0, 1e-12);
  EXPECT_NEAR(p->Distance(Eigen::Vector3d(5, -3, 1)), 0.0, 1e-12);
}

TEST(PpfPlane, FromCoefficientsNormalisesAndRejectsBadInput) {
  const auto p = Plane::FromCoefficients(Eigen::Vector4d(0, 0, 2, -4));
  ASSERT_TRUE(p.has_value());
  EXPECT_NEAR(p->n.z(), 1.0, 1e-15);
  EXPECT_NEAR(p->d, -2.0, 1e-15);
  EXPECT_FALSE(Plane::FromCoefficients(Eigen::Vector4d(0, 0, 0, 1)).has_value());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(Plane::FromCoefficients(Eigen::Vector4d(nan, 0, 1, 0)).has_value());
}

TEST(PpfPlane, AngleIgnoresOrientation) {
  const Plane a{Eigen::Vector3d::UnitZ(), 0.0};
  EXPECT_NEAR(PlaneAngle(a, a.Flipped()), 0.0, 1e-12);
  const Plane b{Eigen::Vector3d(std::sin(0.1), 0, std::cos(0.1)), 0.0};
  EXPECT_NEAR(PlaneAngle(a, b), 0.1, 1e-9);
}

}  // namespace
}  // namespace ppf

namespace ppf {
namespace {

PlaneMoments MomentsOf(const std::vector<Eigen::Vector3d>& pts) {
  PlaneMoments m;
  m.count = static_cast<double>(pts.size());
  for (const auto& p : pts) m.centroid += p / m.count;
  for (const auto& p : pts) m.scatter += (p - m.centroid) * (p - m.centroid).transpose();
  return m;
}

TEST(PlaneMoments, MergeAndTransformEqualTheMomentsOfAllPoints) {
  // Two patches of the tilted plane 0.1x - 0.2y + z = 3 with noise, in some frame A.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::vector<Eigen::Vector3d> a, b, all;
  for (int i = 0; i < 400; ++i) {
    const double x = u(rng) + (i < 200 ? -6.0 : 6.0), y = u(rng);
    const Eigen::Vector3d p(x, y, 3.0 - 0.1 * x + 0.2 * y + noise(rng));
    (i < 200 ? a : b).push_back(p);
    all.push_back(p);
  }
  PlaneMoments merged = MomentsOf(a);
  merged.Merge(MomentsOf(b));
  const PlaneMoments whole = MomentsOf(all);
  EXPECT_DOUBLE_EQ(merged.count, 400.0);
  EXPECT_TRUE(merged.centroid.isApprox(whole.centroid, 1e-12));
  EXPECT_TRUE(merged.scatter.isApprox(whole.scatter, 1e-10));

  const auto plane = merged.FitPlane();
  ASSERT_TRUE(plane.has_value());
  const Eigen::Vector3d truth_n = Eigen::Vector3d(0.1, -0.2, 1.0).normalized();
  EXPECT_LT(std::acos(std::min(1.0, std::abs(plane->n.dot(truth_n)))), 0.2 * M_PI / 180.0);

  // Moments moved to frame B equal the moments of the moved points.
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(4, -1, 2);
  std::vector<Eigen::Vector3d> moved;
  for (const auto& p : all) moved.push_back(T * p);
  const PlaneMoments in_b = whole.Transformed(T);
  const PlaneMoments truth_b = MomentsOf(moved);
  EXPECT_TRUE(in_b.centroid.isApprox(truth_b.centroid, 1e-12));
  EXPECT_TRUE(in_b.scatter.isApprox(truth_b.scatter, 1e-10));
}

TEST(PlaneMoments, TooFewOrCollinearPointsFitNoPlane) {
  EXPECT_FALSE(MomentsOf({{0, 0, 0}, {1, 0, 0}}).FitPlane().has_value());
  EXPECT_FALSE(MomentsOf({{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}}).FitPlane().has_value());
  PlaneMoments empty;
  empty.Merge(MomentsOf({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}));
  EXPECT_DOUBLE_EQ(empty.count, 3.0);
  EXPECT_TRUE(empty.FitPlane().has_value());
}

}  // namespace
}  // namespace ppf
