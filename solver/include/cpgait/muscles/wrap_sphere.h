#pragma once
// A straight path segment wrapped over a sphere, as OpenSim's WrapSphere: the segment must cut the
// sphere; the path runs over the great circle in the plane of its ends and the centre, tangent at
// both points (a geodesic, so holding the tangent points on the sphere's body differentiates it
// exactly), the short way round unless the quadrant constraint sends it the long way.
//
// In the sphere's frame W (centred on the origin).
#include <Eigen/Core>

#include "cpgait/model/model.h"
#include "cpgait/muscles/wrap_cylinder.h"

namespace cpgait {

SegmentWrap<double> wrap_sphere(const WrapObject& sphere, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2);

}  // namespace cpgait
