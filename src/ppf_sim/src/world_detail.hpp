// Internal pieces of BuildWorld: keeping objects off the path, terrain, scene populators and
// motion styles. Not installed.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "ppf_sim/height_field.hpp"
#include "ppf_sim/path_planner.hpp"
#include "ppf_sim/rng.hpp"
#include "ppf_sim/scene.hpp"
#include "ppf_sim/trajectory.hpp"

namespace ppf::sim::detail {

// Dense path points in a hash grid, for "keep this object off the path" checks.
class PathIndex {
 public:
  explicit PathIndex(const std::vector<PathSample>& path) {
    for (size_t i = 0; i < path.size(); ++i) {
      const PathSample& a = path[i];
      const PathSample& b = path[std::min(i + 1, path.size() - 1)];
      const double len = std::hypot(b.x - a.x, b.y - a.y);
      const int n = std::max(1, static_cast<int>(std::ceil(len / 0.5)));
      for (int k = 0; k < n; ++k) {
        const double f = static_cast<double>(k) / n;
        Insert(a.x + f * (b.x - a.x), a.y + f * (b.y - a.y));
      }
    }
  }
  // Clearance of an oriented rectangle (centre, yaw, half sizes) to the path.
  bool RectClear(double cx, double cy, double yaw, double hx, double hy, double clearance) const {
    const double r = std::hypot(hx, hy) + clearance;
    const double c = std::cos(yaw), s = std::sin(yaw);
    const int i0 = Cell(cx - r), i1 = Cell(cx + r), j0 = Cell(cy - r), j1 = Cell(cy + r);
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        auto it = grid_.find(Key(i, j));
        if (it == grid_.end()) continue;
        for (const auto& p : it->second) {
          const double dx = p.first - cx, dy = p.second - cy;
          const double lx = std::max(std::abs(c * dx + s * dy) - hx, 0.0);
          const double ly = std::max(std::abs(-s * dx + c * dy) - hy, 0.0);
          if (lx * lx + ly * ly < clearance * clearance) return false;
        }
      }
    }
    return true;
  }
  bool PointClear(double x, double y, double clearance) const {
    return RectClear(x, y, 0.0, 0.0, 0.0, clearance);
  }

 private:
  static constexpr double kCell = 4.0;
  static int Cell(double v) { return static_cast<int>(std::floor(v / kCell)); }
  // Shifted as unsigned: cells west of the origin have negative i, and left-shifting a negative
  // signed value is undefined before C++20 (UBSan in scripts/sanitize.sh asan).
  static int64_t Key(int i, int j) {
    return static_cast<int64_t>((uint64_t{static_cast<uint32_t>(i)} << 32) |
                                uint64_t{static_cast<uint32_t>(j)});
  }
  void Insert(double x, double y) { grid_[Key(Cell(x), Cell(y))].emplace_back(x, y); }
  std::unordered_map<int64_t, std::vector<std::pair<double, double>>> grid_;
};

// Points every `step` metres of travel along the moving part of the path.
struct Station {
  double x, y, yaw;
};
std::vector<Station> Stations(const std::vector<PathSample>& path, double step);

// Pose of something `offset` metres to the left (side = +1) or right (-1) of a station.
inline void Beside(const Station& st, int side, double offset, double along, double* x, double* y) {
  const double c = std::cos(st.yaw), s = std::sin(st.yaw);
  *x = st.x + along * c - side * offset * s;
  *y = st.y + along * s + side * offset * c;
}

// Ground raster over the path's bounding box plus `margin`, shaped per scene (slopes, curbs,
// uneven lawn, flat yard) with per-cell materials.
HeightField MakeTerrain(const std::vector<PathSample>& path, const std::string& scene, Rng& rng,
                        double margin);

void AddTree(Scene& scene, Rng& rng, double x, double y, double g);
void PopulateUrban(Scene& scene, const std::vector<PathSample>& path, const PathIndex& idx,
                   const HeightField& hf, Rng& rng);
void PopulatePark(Scene& scene, const std::vector<PathSample>& path, const PathIndex& idx,
                  const HeightField& hf, Rng& rng);
void PopulateRamps(Scene& scene, const std::vector<PathSample>& path, const PathIndex& idx,
                   const HeightField& hf, Rng& rng);

// The indoor floor plan's walking loop (repeated until `min_length` metres) and its scene.
std::vector<std::pair<double, double>> IndoorPolyline(double min_length);
void PopulateIndoor(Scene& scene, const PathIndex& idx, Rng& rng);

// Shakes: hand-held (fast rotations scaled to a peak rate, gait bob) or car (suspension).
std::vector<Shake> HandheldShakes(Rng& rng, double max_rate_deg);
std::vector<Shake> CarShakes(Rng& rng);

}  // namespace ppf::sim::detail
