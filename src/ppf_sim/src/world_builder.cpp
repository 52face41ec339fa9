// Builds the four scenes around a planned path and turns the path into the C2 trajectory.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <unordered_map>

#include "ppf_sim/path_planner.hpp"
#include "ppf_sim/rng.hpp"
#include "ppf_sim/world.hpp"

namespace ppf::sim {

namespace {

constexpr double kKnotDt = 0.1;

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
  static int64_t Key(int i, int j) {
    return (static_cast<int64_t>(i) << 32) ^ static_cast<int64_t>(static_cast<uint32_t>(j));
  }
  void Insert(double x, double y) { grid_[Key(Cell(x), Cell(y))].emplace_back(x, y); }
  std::unordered_map<int64_t, std::vector<std::pair<double, double>>> grid_;
};

// Points every `step` metres of travel along the moving part of the path.
struct Station {
  double x, y, yaw;
};
std::vector<Station> Stations(const std::vector<PathSample>& path, double step) {
  std::vector<Station> out;
  double acc = step;  // emit the first point
  for (size_t i = 1; i < path.size(); ++i) {
    const PathSample& a = path[i - 1];
    const PathSample& b = path[i];
    const double len = std::hypot(b.x - a.x, b.y - a.y);
    if (len < 1e-9) continue;
    double pos = 0.0;
    while (acc + (len - pos) >= step) {
      pos += step - acc;
      acc = 0.0;
      const double f = pos / len;
      out.push_back({a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), a.yaw + f * (b.yaw - a.yaw)});
    }
    acc += len - pos;
  }
  if (out.empty() && !path.empty()) out.push_back({path[0].x, path[0].y, path[0].yaw});
  return out;
}

struct Wave {
  double kx, ky, amp, phase;
};

HeightField MakeTerrain(const std::vector<PathSample>& path, const std::string& scene, Rng& rng,
                        double margin) {
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (const auto& p : path) {
    x0 = std::min(x0, p.x);
    y0 = std::min(y0, p.y);
    x1 = std::max(x1, p.x);
    y1 = std::max(y1, p.y);
  }
  const double cell = 0.25;
  x0 -= margin;
  y0 -= margin;
  x1 += margin;
  y1 += margin;
  const int nx = static_cast<int>(std::ceil((x1 - x0) / cell)) + 1;
  const int ny = static_cast<int>(std::ceil((y1 - y0) / cell)) + 1;
  HeightField hf(x0, y0, cell, nx, ny);

  std::vector<Wave> waves;
  auto add_waves = [&](int n, double lmin, double lmax, double amin, double amax) {
    for (int k = 0; k < n; ++k) {
      const double lambda = rng.Uniform(lmin, lmax), dir = rng.Uniform(0, 2 * M_PI);
      waves.push_back({2 * M_PI / lambda * std::cos(dir), 2 * M_PI / lambda * std::sin(dir),
                       rng.Uniform(amin, amax), rng.Uniform(0, 2 * M_PI)});
    }
  };
  double vertex_noise = 0.0;
  double road_half = 0.0, raise = 0.0;
  if (scene == "urban") {
    add_waves(3, 150.0, 400.0, 0.3, 1.5);  // slopes of a few percent
    road_half = 6.0;                       // curb at 6 m from the lane centre
    raise = 0.15;                          // curb height
    hf.reflectivity_low = 0.10f;           // asphalt
    hf.reflectivity_high = 0.28f;          // pavement
  } else if (scene == "park") {
    add_waves(3, 80.0, 250.0, 0.3, 1.2);
    add_waves(5, 4.0, 20.0, 0.05, 0.25);   // uneven lawn
    vertex_noise = 0.02;
    road_half = 1.5;                       // gravel path
    hf.reflectivity_low = 0.2f;
    hf.reflectivity_high = 0.4f;           // grass is bright in the near infrared
  } else {                                 // ramps: a flat paved yard
    hf.reflectivity_low = 0.15f;
    hf.reflectivity_high = 0.15f;
  }
  // Distance to the path near it (road/curb/material), stamped from dense path points.
  std::vector<float> dist(static_cast<size_t>(nx) * ny, 1e9f);
  if (road_half > 0) {
    const double reach = road_half + 1.0;
    const int rc = static_cast<int>(std::ceil(reach / cell));
    for (size_t s = 0; s < path.size(); ++s) {
      const PathSample& a = path[s];
      const PathSample& b = path[std::min(s + 1, path.size() - 1)];
      const int n = std::max(1, static_cast<int>(std::ceil(std::hypot(b.x - a.x, b.y - a.y) / 0.5)));
      for (int k = 0; k < n; ++k) {
        const double px = a.x + (b.x - a.x) * k / n, py = a.y + (b.y - a.y) * k / n;
        const int ci = static_cast<int>((px - x0) / cell), cj = static_cast<int>((py - y0) / cell);
        for (int j = std::max(0, cj - rc); j <= std::min(ny - 1, cj + rc); ++j) {
          for (int i = std::max(0, ci - rc); i <= std::min(nx - 1, ci + rc); ++i) {
            const float d = static_cast<float>(std::hypot(x0 + i * cell - px, y0 + j * cell - py));
            float& slot = dist[static_cast<size_t>(j) * nx + i];
            slot = std::min(slot, d);
          }
        }
      }
    }
  }
  Rng noise_rng(rng.NextBits());
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const double x = x0 + i * cell, y = y0 + j * cell;
      double h = 0.0;
      for (const Wave& w : waves) h += w.amp * std::sin(w.kx * x + w.ky * y + w.phase);
      if (raise > 0 && dist[static_cast<size_t>(j) * nx + i] > road_half) h += raise;
      if (vertex_noise > 0) h += vertex_noise * noise_rng.Normal();
      hf.at(i, j) = static_cast<float>(h);
    }
  }
  if (road_half > 0) {
    hf.material.assign(static_cast<size_t>(nx - 1) * (ny - 1), 1);
    for (int j = 0; j + 1 < ny; ++j)
      for (int i = 0; i + 1 < nx; ++i)
        if (dist[static_cast<size_t>(j) * nx + i] <= road_half)
          hf.material[static_cast<size_t>(j) * (nx - 1) + i] = 0;
  }
  hf.Finalize();
  return hf;
}

void AddTree(Scene& scene, Rng& rng, double x, double y, double g) {
  const double trunk_h = rng.Uniform(1.6, 3.5);
  const double rxy = rng.Uniform(1.5, 3.8), rz = rng.Uniform(1.5, 3.5);
  scene.Add(MakeCylinder(x, y, rng.Uniform(0.12, 0.35), g - 0.3, g + trunk_h + rz * 0.5, 0.3f));
  const bool conifer = rng.Uniform() < 0.25;
  const Eigen::Vector3d radii = conifer ? Eigen::Vector3d(rxy * 0.6, rxy * 0.6, rz * 1.6)
                                        : Eigen::Vector3d(rxy, rxy * rng.Uniform(0.8, 1.2), rz);
  scene.Add(MakeBlob({x, y, g + trunk_h + radii.z() * 0.85}, radii, 0.45f, 0.45f, 0.2f));
}

// Pose of something `offset` metres to the left (side = +1) or right (-1) of a station.
void Beside(const Station& st, int side, double offset, double along, double* x, double* y) {
  const double c = std::cos(st.yaw), s = std::sin(st.yaw);
  *x = st.x + along * c - side * offset * s;
  *y = st.y + along * s + side * offset * c;
}

void PopulateUrban(Scene& scene, const std::vector<PathSample>& path, const PathIndex& idx,
                   const HeightField& hf, Rng& rng) {
  const auto st = Stations(path, 1.0);
  const int n = static_cast<int>(st.size());
  for (int side = -1; side <= 1; side += 2) {
    // Buildings: blocks of facades with gaps (side streets, lots).
    for (int k = rng.UniformInt(0, 5); k < n;) {
      const double len = rng.Uniform(8.0, 30.0), depth = rng.Uniform(8.0, 20.0);
      const double off = rng.Uniform(9.0, 14.0), height = rng.Uniform(6.0, 30.0);
      const int mid = std::min(n - 1, k + static_cast<int>(len / 2));
      double cx, cy;
      Beside(st[mid], side, off + depth / 2, 0.0, &cx, &cy);
      if (hf.Contains(cx, cy) && idx.RectClear(cx, cy, st[mid].yaw, len / 2, depth / 2, 8.0)) {
        const double g = hf.Height(cx, cy);
        const float refl = static_cast<float>(rng.Uniform(0.25, 0.6));
        scene.Add(MakeBox(cx, cy, st[mid].yaw, len / 2, depth / 2, g - 2.0, g + height, refl));
        // Facade relief (balconies, cornices): thin slabs sticking out of the street side.
        const int bands = rng.UniformInt(0, 3);
        for (int b = 0; b < bands; ++b) {
          double bx, by;
          Beside(st[mid], side, off - 0.25, 0.0, &bx, &by);
          const double z = g + rng.Uniform(3.0, std::max(3.5, height - 1.0));
          scene.Add(MakeBox(bx, by, st[mid].yaw, len / 2 * rng.Uniform(0.3, 0.95), 0.35, z,
                            z + rng.Uniform(0.2, 1.0), refl));
        }
      }
      k += static_cast<int>(len + (rng.Uniform() < 0.25 ? rng.Uniform(10.0, 20.0)
                                                         : rng.Uniform(0.0, 4.0)));
    }
    // Poles (street lights, signs) just behind the curb.
    for (int k = rng.UniformInt(0, 10); k < n; k += rng.UniformInt(15, 30)) {
      double x, y;
      Beside(st[k], side, 6.6, 0.0, &x, &y);
      if (!hf.Contains(x, y) || !idx.PointClear(x, y, 5.5)) continue;
      const double g = hf.Height(x, y);
      const double r = rng.Uniform(0.07, 0.15);
      scene.Add(MakeCylinder(x, y, r, g - 0.2, g + rng.Uniform(4.0, 9.0), 0.5f));
      if (rng.Uniform() < 0.4) {  // a retro-reflective sign
        scene.Add(MakeBox(x, y, st[k].yaw + M_PI / 2, 0.3, 0.03, g + 2.2, g + 2.8, 0.95f));
      }
    }
    // Trees on the pavement.
    for (int k = rng.UniformInt(0, 10); k < n; k += rng.UniformInt(10, 25)) {
      double x, y;
      Beside(st[k], side, rng.Uniform(7.5, 8.5), 0.0, &x, &y);
      if (!hf.Contains(x, y) || !idx.PointClear(x, y, 6.5)) continue;
      AddTree(scene, rng, x, y, hf.Height(x, y));
    }
    // Parked cars along the curb.
    for (int k = rng.UniformInt(0, 6); k < n; k += rng.UniformInt(6, 12)) {
      if (rng.Uniform() < 0.4) continue;
      double x, y;
      Beside(st[k], side, 4.6, 0.0, &x, &y);
      const double yaw = st[k].yaw + rng.Uniform(-0.05, 0.05);
      if (!hf.Contains(x, y) || !idx.RectClear(x, y, yaw, 2.3, 0.95, 2.8)) continue;
      const double g = hf.Height(x, y);
      const float refl = static_cast<float>(rng.Uniform(0.15, 0.7));
      scene.Add(MakeBox(x, y, yaw, 2.25, 0.9, g + 0.3, g + 0.95, refl));
      double cx, cy;
      Beside({x, y, yaw}, 0, 0.0, -0.3, &cx, &cy);
      scene.Add(MakeBox(cx, cy, yaw, 1.2, 0.8, g + 0.95, g + 1.5, 0.1f));  // dark windows
    }
  }
}

void PopulatePark(Scene& scene, const std::vector<PathSample>& path, const PathIndex& idx,
                  const HeightField& hf, Rng& rng) {
  const double x0 = hf.x0() + 40, y0 = hf.y0() + 40;
  const double x1 = hf.x0() + (hf.nx() - 1) * hf.cell() - 40;
  const double y1 = hf.y0() + (hf.ny() - 1) * hf.cell() - 40;
  const double area = std::max(0.0, (x1 - x0) * (y1 - y0));
  const int trees = static_cast<int>(area / 220.0);
  for (int k = 0; k < trees; ++k) {
    const double x = rng.Uniform(x0, x1), y = rng.Uniform(y0, y1);
    if (!idx.PointClear(x, y, 3.0)) continue;
    AddTree(scene, rng, x, y, hf.Height(x, y));
  }
  const int bushes = static_cast<int>(area / 300.0);
  for (int k = 0; k < bushes; ++k) {
    const double x = rng.Uniform(x0, x1), y = rng.Uniform(y0, y1);
    const Eigen::Vector3d r(rng.Uniform(0.5, 1.6), rng.Uniform(0.5, 1.6), rng.Uniform(0.4, 1.0));
    if (!idx.RectClear(x, y, 0.0, r.x(), r.y(), 1.2)) continue;
    scene.Add(MakeBlob({x, y, hf.Height(x, y) + r.z() * 0.5}, r, 0.45f, 0.3f, 0.1f));
  }
  const auto st = Stations(path, 1.0);
  const int n = static_cast<int>(st.size());
  for (int k = rng.UniformInt(0, 20); k < n; k += rng.UniformInt(25, 45)) {  // lamp posts
    double x, y;
    const int side = rng.Uniform() < 0.5 ? -1 : 1;
    Beside(st[k], side, 3.0, 0.0, &x, &y);
    if (!idx.PointClear(x, y, 2.5)) continue;
    const double g = hf.Height(x, y);
    scene.Add(MakeCylinder(x, y, 0.07, g - 0.2, g + 4.5, 0.5f));
  }
  for (int k = rng.UniformInt(10, 40); k < n; k += rng.UniformInt(50, 90)) {  // benches
    double x, y;
    const int side = rng.Uniform() < 0.5 ? -1 : 1;
    Beside(st[k], side, 2.6, 0.0, &x, &y);
    if (!idx.RectClear(x, y, st[k].yaw, 0.9, 0.3, 1.8)) continue;
    const double g = hf.Height(x, y);
    scene.Add(MakeBox(x, y, st[k].yaw, 0.9, 0.25, g + 0.4, g + 0.47, 0.35f));
    double bx, by;
    Beside({x, y, st[k].yaw}, side, 0.25, 0.0, &bx, &by);
    scene.Add(MakeBox(bx, by, st[k].yaw, 0.9, 0.03, g + 0.5, g + 0.9, 0.35f));
  }
  for (int k = rng.UniformInt(30, 80); k < n; k += rng.UniformInt(150, 250)) {  // a kiosk
    double x, y;
    const int side = rng.Uniform() < 0.5 ? -1 : 1;
    Beside(st[k], side, 9.0, 0.0, &x, &y);
    if (!idx.RectClear(x, y, st[k].yaw, 2.5, 2.0, 4.0)) continue;
    const double g = hf.Height(x, y);
    scene.Add(MakeBox(x, y, st[k].yaw, 2.5, 2.0, g - 0.5, g + 2.8, 0.4f));
  }
}

void PopulateRamps(Scene& scene, const std::vector<PathSample>& path, const PathIndex& idx,
                   const HeightField& hf, Rng& rng) {
  const auto st = Stations(path, 1.0);
  const int n = static_cast<int>(st.size());
  for (int k = rng.UniformInt(0, 8); k < n; k += rng.UniformInt(8, 18)) {
    const int side = rng.Uniform() < 0.5 ? -1 : 1;
    const double alpha = rng.Uniform(3.0, 12.0) * M_PI / 180.0;  // included angle with ground
    const double len = rng.Uniform(8.0, 16.0), width = rng.Uniform(5.0, 10.0);
    const double plat = rng.Uniform(4.0, 10.0);
    const double run = len * std::cos(alpha), rise = len * std::sin(alpha);
    const bool along = rng.Uniform() < 0.5;  // slope rising along the path or away from it
    const double c = std::cos(st[k].yaw), s = std::sin(st[k].yaw);
    const Eigen::Vector2d fwd(c, s), left(-s, c);
    const double off = rng.Uniform(4.0, 9.0);
    Eigen::Vector2d slope_dir, edge_dir, base;
    const Eigen::Vector2d here(st[k].x, st[k].y);
    if (along) {
      slope_dir = rng.Uniform() < 0.5 ? fwd : Eigen::Vector2d(-fwd);
      edge_dir = left;
      base = here + side * (off + width / 2) * left;
    } else {
      slope_dir = side * left;
      edge_dir = fwd;
      base = here + off * slope_dir;
    }
    const double total = run + plat;
    const Eigen::Vector2d centre = base + slope_dir * (total / 2);
    const double yaw = std::atan2(slope_dir.y(), slope_dir.x());
    if (!hf.Contains(centre.x(), centre.y()) ||
        !idx.RectClear(centre.x(), centre.y(), yaw, total / 2, width / 2, 2.5)) {
      continue;
    }
    const double g = hf.Height(base.x(), base.y());
    const Eigen::Vector2d qc = base + slope_dir * (run / 2);
    const Eigen::Vector3d u(slope_dir.x() * std::cos(alpha), slope_dir.y() * std::cos(alpha),
                            std::sin(alpha));
    const float refl = static_cast<float>(rng.Uniform(0.15, 0.35));
    scene.Add(MakeQuad({qc.x(), qc.y(), g + rise / 2}, u, len / 2,
                       {edge_dir.x(), edge_dir.y(), 0.0}, width / 2, refl));
    const Eigen::Vector2d pc = base + slope_dir * (run + plat / 2);
    scene.Add(MakeBox(pc.x(), pc.y(), yaw, plat / 2, width / 2, g - 0.5, g + rise, refl));
  }
  for (int k = rng.UniformInt(0, 20); k < n; k += rng.UniformInt(35, 60)) {  // sparse poles
    double x, y;
    Beside(st[k], rng.Uniform() < 0.5 ? -1 : 1, 4.0, 0.0, &x, &y);
    if (!hf.Contains(x, y) || !idx.PointClear(x, y, 3.0)) continue;
    const double g = hf.Height(x, y);
    scene.Add(MakeCylinder(x, y, 0.1, g - 0.2, g + 6.0, 0.5f));
  }
}

// Indoor: room A (x -6..6, y -5..5), a 60 m plain corridor (x 6..66, 2.2 m wide), room B
// (x 66..78, y -6..6). The corridor walls are deliberately featureless.
void AddWall(Scene& scene, double x0, double y0, double x1, double y1, double z0, double z1,
             float refl) {
  const double len = std::hypot(x1 - x0, y1 - y0);
  scene.Add(MakeBox(0.5 * (x0 + x1), 0.5 * (y0 + y1), std::atan2(y1 - y0, x1 - x0), len / 2, 0.1,
                    z0, z1, refl));
}

std::vector<std::pair<double, double>> IndoorPolyline(double min_length) {
  std::vector<std::pair<double, double>> pts = {{1.0, -2.5}};
  const std::vector<std::pair<double, double>> cycle = {
      {3.5, -2.5}, {3.5, 2.5},  {-2.0, 2.5},  {-2.0, 0.4},  {6.0, 0.4},
      {66.0, 0.4}, {70.0, 3.5}, {75.0, 3.5},  {75.0, -3.5}, {70.0, -3.5},
      {66.0, -0.4}, {6.0, -0.4}, {-2.0, -0.4}, {-3.5, -2.5}};
  double length = 0.0;
  while (length < min_length) {
    for (const auto& p : cycle) {
      length += std::hypot(p.first - pts.back().first, p.second - pts.back().second);
      pts.push_back(p);
    }
  }
  return pts;
}

void PopulateIndoor(Scene& scene, const PathIndex& idx, Rng& rng) {
  const float wall = 0.5f, floor = 0.3f, ceil = 0.6f;
  // Room A
  AddWall(scene, -6, -5, -6, 5, 0, 3.0, wall);
  AddWall(scene, -6, -5, 6, -5, 0, 3.0, wall);
  AddWall(scene, -6, 5, 6, 5, 0, 3.0, wall);
  AddWall(scene, 6, -5, 6, -1.2, 0, 3.0, wall);
  AddWall(scene, 6, 1.2, 6, 5, 0, 3.0, wall);
  AddWall(scene, 6, -1.2, 6, 1.2, 2.8, 3.0, wall);
  // Corridor
  AddWall(scene, 6, -1.2, 66, -1.2, 0, 2.8, wall);
  AddWall(scene, 6, 1.2, 66, 1.2, 0, 2.8, wall);
  // Room B
  AddWall(scene, 66, -6, 66, -1.2, 0, 3.2, wall);
  AddWall(scene, 66, 1.2, 66, 6, 0, 3.2, wall);
  AddWall(scene, 66, -1.2, 66, 1.2, 2.8, 3.2, wall);
  AddWall(scene, 78, -6, 78, 6, 0, 3.2, wall);
  AddWall(scene, 66, -6, 78, -6, 0, 3.2, wall);
  AddWall(scene, 66, 6, 78, 6, 0, 3.2, wall);
  const Eigen::Vector3d ex = Eigen::Vector3d::UnitX(), ey = Eigen::Vector3d::UnitY();
  scene.Add(MakeQuad({36, 0, 0}, ex, 42.5, ey, 6.5, floor));
  scene.Add(MakeQuad({0, 0, 3.0}, ex, 6, ey, 5, ceil));
  scene.Add(MakeQuad({36, 0, 2.8}, ex, 30, ey, 1.2, ceil));
  scene.Add(MakeQuad({72, 0, 3.2}, ex, 6, ey, 6, ceil));
  // Furniture: desks, cabinets and columns, kept off the walking path.
  struct Room {
    double x0, y0, x1, y1;
    int items;
  };
  for (const Room& room : {Room{-5.5, -4.5, 5.5, 4.5, 14}, Room{66.5, -5.5, 77.5, 5.5, 18}}) {
    int left = room.items;
    for (int k = 0; k < room.items * 4 && left > 0; ++k) {
      const int type = rng.UniformInt(0, 2);
      const double yaw = rng.UniformInt(0, 3) * M_PI / 2 + rng.Uniform(-0.1, 0.1);
      double hx = 0.8, hy = 0.4, z1 = 0.75;
      if (type == 1) {
        hx = 0.9;
        hy = 0.22;
        z1 = rng.Uniform(1.2, 2.1);
      } else if (type == 2) {
        hx = hy = 0.3;
        z1 = 3.3;
      }
      const double x = rng.Uniform(room.x0 + hx, room.x1 - hx);
      const double y = rng.Uniform(room.y0 + hx, room.y1 - hx);
      if (!idx.RectClear(x, y, yaw, hx, hy, 0.9)) continue;
      if (type == 2) {
        scene.Add(MakeCylinder(x, y, 0.3, 0.0, 3.3, 0.5f));
      } else {
        scene.Add(MakeBox(x, y, yaw, hx, hy, 0.0, z1, static_cast<float>(rng.Uniform(0.2, 0.7))));
      }
      --left;
    }
  }
}

std::vector<Shake> HandheldShakes(Rng& rng, double max_rate_deg) {
  struct Raw {
    int ch;
    double amp, f;
  };
  const Raw raw[] = {{2, 0.30, 0.8}, {2, 0.08, 1.9}, {1, 0.15, 1.1}, {1, 0.04, 2.3},
                     {0, 0.10, 0.7}, {0, 0.03, 2.7}};
  std::vector<Shake> out;
  double peak[3] = {0, 0, 0};
  for (const Raw& r : raw) {
    Shake s{r.ch, r.amp, r.f * rng.Uniform(0.85, 1.15), rng.Uniform(0, 2 * M_PI)};
    peak[r.ch] += s.amp * 2 * M_PI * s.freq_hz;
    out.push_back(s);
  }
  const double norm = std::sqrt(peak[0] * peak[0] + peak[1] * peak[1] + peak[2] * peak[2]);
  const double scale = max_rate_deg * M_PI / 180.0 / norm;
  for (Shake& s : out) s.amp *= scale;
  out.push_back({5, 0.025, 1.8 * rng.Uniform(0.9, 1.1), rng.Uniform(0, 2 * M_PI)});  // gait bob
  out.push_back({3, 0.015, 0.9, rng.Uniform(0, 2 * M_PI)});
  out.push_back({4, 0.015, 0.9, rng.Uniform(0, 2 * M_PI)});
  return out;
}

std::vector<Shake> CarShakes(Rng& rng) {
  return {{0, 0.004, 1.3 * rng.Uniform(0.9, 1.1), rng.Uniform(0, 2 * M_PI)},
          {1, 0.005, 1.7 * rng.Uniform(0.9, 1.1), rng.Uniform(0, 2 * M_PI)},
          {5, 0.008, 2.1 * rng.Uniform(0.9, 1.1), rng.Uniform(0, 2 * M_PI)}};
}

}  // namespace

std::vector<std::string> SceneNames() { return {"urban", "indoor", "park", "ramps"}; }

MotionKind DefaultMotion(const std::string& scene) {
  return scene == "indoor" ? MotionKind::kHandheld : MotionKind::kCar;
}

World BuildWorld(const WorldOptions& opt) {
  const auto names = SceneNames();
  if (std::find(names.begin(), names.end(), opt.scene) == names.end()) {
    throw std::invalid_argument("unknown scene '" + opt.scene + "' (urban, indoor, park, ramps)");
  }
  World world;
  world.motion = opt.motion_is_default ? DefaultMotion(opt.scene) : opt.motion;
  const bool handheld = world.motion == MotionKind::kHandheld;
  double speed = opt.speed;
  if (speed <= 0.0) {
    if (handheld) speed = 1.3;
    else if (opt.scene == "park") speed = 5.0;
    else if (opt.scene == "indoor") speed = 1.0;
    else if (opt.scene == "ramps") speed = 8.0;
    else speed = 10.0;
  }
  world.speed = speed;
  Rng rng(opt.seed, 0x5CE7Eu);
  const int n_samples = static_cast<int>(std::ceil((opt.duration + 3.0) / kKnotDt)) + 4;
  // The spline reaches 2 knots back and the suspension filter 3 more: start moving late enough
  // that the curve is exactly constant until static_time + 0.1 s.
  const double move_time = opt.static_time + 6 * kKnotDt;

  std::vector<PathSample> path;
  if (opt.scene == "indoor") {
    path = FollowPolyline(IndoorPolyline(speed * (opt.duration + 5.0) + 20.0), 0.8, speed,
                          handheld ? 0.6 : 0.4, kKnotDt, n_samples, move_time);
    SmoothYaw(path, kKnotDt, handheld ? 0.3 : 1.0);
  } else {
    KinematicLimits lim;
    lim.cruise_speed = speed;
    if (handheld) {
      lim.accel = 0.7;
      lim.lateral_accel = 1.0;
      lim.max_curvature = 0.5;
      lim.curvature_rate = 0.5;
      lim.straight_min = 10;
      lim.straight_max = 40;
      lim.world_radius = 40;
    } else if (opt.scene == "park") {
      lim.max_curvature = 1.0 / 6.0;
      lim.straight_min = 20;
      lim.straight_max = 80;
      lim.world_radius = 100;
    }
    path = PlanOpenPath(lim, kKnotDt, n_samples, move_time, rng);
    if (handheld) SmoothYaw(path, kKnotDt, 0.3);
  }
  const PathIndex idx(path);

  std::vector<Eigen::Vector3d> pos(path.size()), euler(path.size());
  if (opt.scene == "indoor") {
    PopulateIndoor(world.scene, idx, rng);
    const double z = handheld ? 1.3 : 0.9;
    for (size_t i = 0; i < path.size(); ++i) {
      pos[i] = {path[i].x, path[i].y, z};
      euler[i] = {0.0, 0.0, path[i].yaw};
    }
  } else {
    HeightField hf = MakeTerrain(path, opt.scene, rng, 130.0);
    if (opt.scene == "urban") PopulateUrban(world.scene, path, idx, hf, rng);
    if (opt.scene == "park") PopulatePark(world.scene, path, idx, hf, rng);
    if (opt.scene == "ramps") PopulateRamps(world.scene, path, idx, hf, rng);
    const double mount = handheld ? 1.3 : 1.6;
    for (size_t i = 0; i < path.size(); ++i) {
      const PathSample& p = path[i];
      double roll = 0.0, pitch = 0.0;
      if (!handheld) {
        // The body follows the ground under the wheels (1.4 m half wheelbase, 0.8 m half track).
        const double c = std::cos(p.yaw), s = std::sin(p.yaw);
        const double hf_front = hf.Height(p.x + 1.4 * c, p.y + 1.4 * s);
        const double hf_back = hf.Height(p.x - 1.4 * c, p.y - 1.4 * s);
        const double hf_left = hf.Height(p.x - 0.8 * s, p.y + 0.8 * c);
        const double hf_right = hf.Height(p.x + 0.8 * s, p.y - 0.8 * c);
        pitch = -std::atan2(hf_front - hf_back, 2.8);
        roll = std::atan2(hf_left - hf_right, 1.6);
      }
      // Wheels average the ground: the mean of the contact points, not the height at the centre.
      const double c = std::cos(p.yaw), s = std::sin(p.yaw);
      double ground = hf.Height(p.x, p.y);
      if (!handheld) {
        ground = 0.25 * (hf.Height(p.x + 1.4 * c, p.y + 1.4 * s) +
                         hf.Height(p.x - 1.4 * c, p.y - 1.4 * s) +
                         hf.Height(p.x - 0.8 * s, p.y + 0.8 * c) +
                         hf.Height(p.x + 0.8 * s, p.y - 0.8 * c));
      }
      pos[i] = {p.x, p.y, ground + mount};
      euler[i] = {roll, pitch, p.yaw};
    }
    // Suspension: low-pass height and attitude over +-0.3 s so small bumps do not become
    // large accelerations (the shakes add the vibration back in a controlled way).
    const int w = 3;
    const auto raw_pos = pos;
    const auto raw_euler = euler;
    for (int i = 0; i < static_cast<int>(pos.size()); ++i) {
      double z = 0, r = 0, pt = 0;
      int cnt = 0;
      for (int k = std::max(0, i - w); k <= std::min(static_cast<int>(pos.size()) - 1, i + w); ++k) {
        z += raw_pos[k].z();
        r += raw_euler[k].x();
        pt += raw_euler[k].y();
        ++cnt;
      }
      pos[i].z() = z / cnt;
      euler[i].x() = r / cnt;
      euler[i].y() = pt / cnt;
    }
    world.scene.SetGround(std::move(hf));
  }
  world.scene.Build(4.0);
  world.trajectory = Trajectory(kKnotDt, std::move(pos), std::move(euler));
  world.trajectory.SetShakes(handheld ? HandheldShakes(rng, opt.max_rate_deg) : CarShakes(rng),
                             opt.static_time + 0.1, 1.5);
  return world;
}

}  // namespace ppf::sim
