#include "ppf_core/ppf/sandwich_layer.hpp"

#include <cmath>

#include "ppf_core/detail/omp_team.hpp"

namespace ppf {

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
  // scans").
  const auto classify = [&](long i) {
    const auto& p = points[i];
    const float a = std::abs(nx * p.x() + ny * p.y() + nz * p.z() + d);
    label[i] = a < strict ? 0 : (a < semi ? 1 : 2);
  };
  if (n > 32768 && detail::MayOpenTeam()) {
#pragma omp parallel for schedule(static)
    for (long i = 0; i < n; ++i) classify(i);
  } else {
    for (long i = 0; i < n; ++i) classify(i);
  }
  // Serial compaction keeps the order deterministic; it is a cheap linear pass.
  for (long i = 0; i < n; ++i) {
    if (label[i] == 0) split->strict.push_back(static_cast<int>(i));
  }
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
