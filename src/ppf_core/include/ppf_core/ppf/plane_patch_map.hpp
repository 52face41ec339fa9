// Plane patch map: where the skeleton planes were, in the world, so skeleton residuals are
// anchored to the map instead of to the previous scan.
//
// Why (docs/decisions.md, "Map-anchored skeleton residuals"): the paper matches the
// skeleton points of scan n to the window planes fitted in scan n-1. Nothing then remembers where
// a surface was before scan n-1, so the registration is scan-to-scan for every direction the
// planes constrain. A large, gently curved surface (a road over a hill) is the worst case: each
// scan aligns its ground to the previous scan's tangent plane and the error is passed on, so the
// estimate keeps the first scan's ground slope ("flat earth"), the error all in height, roll and
// pitch. Averaging several scans' fits per track made it worse: the error is a bias, not noise.
//
// The fix keeps PPF's cost model: skeleton points still need no kNN search and never enter the
// kNN map. After each update the skeleton points, in the world, are accumulated into a coarse
// grid (cell_size, 2 m) of plane patches: per cell and surface orientation the moments (count,
// centroid, scatter) of the points seen there, frozen after max_points (first observations anchor
// the map, like the kNN map's points). A skeleton point's residual is then its distance to the
// patch of its cell whose normal agrees with its own plane's: one hash lookup instead of a kNN
// search and a PCA per point. A patch is a few hundred bytes for hundreds of downsampled
// points.
//
// A patch gives residuals only once its own points fix its normal (PCA over points that span the
// cell in two directions). Before that (one scan line crossing the cell: typical for ground seen
// from afar) the only normal at hand is that of the scan's large plane, which is the scan-wide
// tangent again: borrowing it brought the flat-earth bias back, so such patches give no residual.
#pragma once

#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "ppf_core/ppf/plane.hpp"

namespace ppf {

struct PlanePatchMapOptions {
  double cell_size = 2.0;        // metres; the ground curves by < 2 mm over 2 m on a 3 % bend
  int max_patches_per_cell = 3;  // e.g. floor and wall in a corner cell, road and kerb top
  // A point joins the patch whose normal is within same_surface_deg of its plane's normal and
  // whose centroid is within same_surface_offset along that normal (parallel surfaces, such as a
  // road and the pavement 15 cm above it, are separate patches).
  double same_surface_deg = 20.0;
  double same_surface_offset = 0.1;
  int min_points = 10;  // a patch with fewer points gives no residual
  // ... nor one whose points do not spread at least this fraction of the cell (standard deviation
  // along the second principal axis): a single scan line fixes no normal.
  double min_spread_ratio = 0.11;
  int max_points = 50;        // then it is frozen: later observations do not move it
  size_t max_cells = 200000;  // hard bound (oldest cells are dropped first)
};

class PlanePatchMap {
 public:
  struct Patch {
    Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero();  // of the inserting planes' normals
    // normal_sum.normalized(), kept with it: Insert compares it with every point's normal.
    Eigen::Vector3d normal_dir = Eigen::Vector3d::Zero();
    PlaneMoments moments;
    Plane plane;          // the PCA plane of the moments; meaningful only if usable
    bool usable = false;  // >= min_points spanning two directions, PCA normal near normal_sum
    uint64_t changed = 0;  // insert generation whose points changed it: refit at FinishInsert
  };

  explicit PlanePatchMap(const PlanePatchMapOptions& options = PlanePatchMapOptions());

  const PlanePatchMapOptions& options() const { return options_; }

  // The cell of a caller's last Insert: a plane's points come in scan order, mostly several in
  // one cell, and with a hint they look it up once. Valid for one map until its next
  // FinishInsert, RemoveFarFrom or Clear (cells are only added in between, and an element of the
  // hash map stays where it is): a hint lives in the loop that inserts one scan.
  class InsertHint;

  // Adds a skeleton point (world) of a plane with world normal n_world (unit). Call
  // FinishInsert() after a scan's points so the touched patches' planes are refitted once.
  void Insert(const Eigen::Vector3d& p_world, const Eigen::Vector3d& n_world);
  void Insert(const Eigen::Vector3d& p_world, const Eigen::Vector3d& n_world, InsertHint* hint);
  void FinishInsert();

  // The usable patch at p_world whose normal is within acos(min_cos) of n_world and whose plane
  // is nearest to p_world, or nullptr.
  const Patch* Find(const Eigen::Vector3d& p_world, const Eigen::Vector3d& n_world,
                    double min_cos) const;

  // Drops cells whose centre is farther than radius from center (called with the sensor position).
  void RemoveFarFrom(const Eigen::Vector3d& center, double radius);
  void Clear();

  size_t num_cells() const { return cells_.size(); }
  size_t num_patches() const { return num_patches_; }

 private:
  struct Cell {
    std::vector<Patch> patches;
    uint64_t last_insert = 0;  // insert generation, for the max_cells bound
    uint64_t changed = 0;      // generation whose points changed one of its patches
  };
  uint64_t KeyOf(const Eigen::Vector3d& p) const;
  void Refit(Patch* patch) const;

  PlanePatchMapOptions options_;
  double inv_cell_ = 0.5;
  // cos(same_surface_deg), computed once: Insert and Refit test it for every point and patch.
  double same_surface_cos_ = 1.0;
  std::unordered_map<uint64_t, Cell> cells_;
  std::vector<uint64_t> touched_;  // cells with a changed patch since the last FinishInsert
  uint64_t generation_ = 0;
  size_t num_patches_ = 0;

 public:
  class InsertHint {
    friend class PlanePatchMap;
    Cell* cell_ = nullptr;
    uint64_t key_ = 0;
  };
};

}  // namespace ppf
