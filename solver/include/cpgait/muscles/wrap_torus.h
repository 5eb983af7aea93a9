#pragma once
// A straight path segment wrapped over a torus, as OpenSim's WrapTorus: the point of the torus's
// centre circle (outer radius, in W's xy plane) closest to the segment's line places a cylinder of
// the inner radius there, its axis along the circle, and the path wraps that cylinder on the side
// facing the torus's centre (a path threaded through the ring). The torus's quadrant picks between
// the closest points found from either end, as OpenSim's does.
//
// In the torus's frame W (centred on the origin, axis z).
#include <Eigen/Core>

#include "cpgait/model/model.h"
#include "cpgait/muscles/wrap_cylinder.h"

namespace cpgait {

SegmentWrap<double> wrap_torus(const WrapObject& torus, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2);

}  // namespace cpgait
