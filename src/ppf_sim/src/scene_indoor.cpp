// The indoor floor plan: two rooms joined by a long featureless corridor.
#include <algorithm>
#include <cmath>

#include "world_detail.hpp"

namespace ppf::sim::detail {

namespace {

// Indoor: room A (x -6..6, y -5..5), a 60 m plain corridor (x 6..66, 2.2 m wide), room B
// (x 66..78, y -6..6). The corridor walls are deliberately featureless.
void AddWall(Scene& scene, double x0, double y0, double x1, double y1, double z0, double z1,
             float refl) {
  const double len = std::hypot(x1 - x0, y1 - y0);
  scene.Add(MakeBox(0.5 * (x0 + x1), 0.5 * (y0 + y1), std::atan2(y1 - y0, x1 - x0), len / 2, 0.1,
                    z0, z1, refl));
}

}  // namespace

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

}  // namespace ppf::sim::detail
