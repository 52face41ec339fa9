// Urban, park and ramps scenes, populated along the driven path and kept off it.
#include <algorithm>
#include <cmath>

#include "world_detail.hpp"

namespace ppf::sim::detail {

void AddTree(Scene& scene, Rng& rng, double x, double y, double g) {
  const double trunk_h = rng.Uniform(1.6, 3.5);
  const double rxy = rng.Uniform(1.5, 3.8), rz = rng.Uniform(1.5, 3.5);
  scene.Add(MakeCylinder(x, y, rng.Uniform(0.12, 0.35), g - 0.3, g + trunk_h + rz * 0.5, 0.3f));
  const bool conifer = rng.Uniform() < 0.25;
  const Eigen::Vector3d radii = conifer ? Eigen::Vector3d(rxy * 0.6, rxy * 0.6, rz * 1.6)
                                        : Eigen::Vector3d(rxy, rxy * rng.Uniform(0.8, 1.2), rz);
  scene.Add(MakeBlob({x, y, g + trunk_h + radii.z() * 0.85}, radii, 0.45f, 0.45f, 0.2f));
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

}  // namespace ppf::sim::detail
