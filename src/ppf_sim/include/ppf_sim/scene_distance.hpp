// Distance from a point to the scene's surfaces: how far a map built from simulated scans lies
// from what the simulator cast its rays at (the map export tests of ppf_offline and ppf_node).
#pragma once

#include <Eigen/Core>

#include "ppf_sim/scene.hpp"

namespace ppf::sim {

// Distance from x to the surface of one primitive (0 inside a blob: foliage returns come from
// within it). Exact for quads, boxes and cylinders; for a blob an upper bound (along the ray
// from its centre).
double DistanceToPrimitive(const Primitive& p, const Eigen::Vector3d& x);

// Distance to the nearest surface of the scene; the ground counts with its vertical distance
// (an upper bound of the true one). Tests every primitive: meant for checks, not for loops over
// millions of points.
double DistanceToScene(const Scene& scene, const Eigen::Vector3d& x);

}  // namespace ppf::sim
