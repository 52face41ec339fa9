// Ground as a regular grid of heights, two triangles per cell (exactly what the ray caster and
// GroundHeight() see, so the trajectory can be put on the same surface the LiDAR measures).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace ppf::sim {

class HeightField {
 public:
  HeightField() = default;
  // nx * ny vertices starting at (x0, y0), spacing `cell`. All heights start at 0.
  HeightField(double x0, double y0, double cell, int nx, int ny);

  float& at(int i, int j) { return h_[static_cast<size_t>(j) * nx_ + i]; }
  float at(int i, int j) const { return h_[static_cast<size_t>(j) * nx_ + i]; }
  // Call after editing heights: rebuilds the per-block bounds used to skip empty space.
  void Finalize();

  double Height(double x, double y) const;
  bool Contains(double x, double y) const;
  // Ray (origin o, unit direction d) against the surface for t in [tmin, tmax]; returns the
  // hit distance and the unit normal.
  bool Intersect(const double o[3], const double d[3], double tmin, double tmax, double* t_hit,
                 double n[3]) const;

  double x0() const { return x0_; }
  double y0() const { return y0_; }
  double cell() const { return cell_; }
  int nx() const { return nx_; }
  int ny() const { return ny_; }
  float reflectivity_low = 0.12f;   // asphalt-like
  float reflectivity_high = 0.25f;  // concrete/grass-like, used above `split_height`
  std::vector<uint8_t> material;    // optional per-cell material (0 = low, 1 = high)

 private:
  bool IntersectCell(int i, int j, const double o[3], const double d[3], double ta, double tb,
                     double* t_hit, double n[3]) const;

  double x0_ = 0, y0_ = 0, cell_ = 1;
  int nx_ = 0, ny_ = 0;
  std::vector<float> h_;
  static constexpr int kBlock = 16;  // cells per block side
  int bx_ = 0, by_ = 0;
  std::vector<float> block_max_;
};

}  // namespace ppf::sim
