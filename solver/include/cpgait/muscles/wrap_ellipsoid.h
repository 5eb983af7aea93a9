#pragma once
// A straight path segment wrapped over an ellipsoid, as OpenSim's WrapEllipsoid computes it: the
// segment must cut the ellipsoid; the path then runs in the plane through both ends and a surface
// point c1 (found by Frans van der Helm's axis technique, a fan of closest points, or their blend:
// PathWrap's hybrid, midpoint and axial methods), tangent within that plane, with its length over the
// surface summed over 1 mm chords. No closed form exists (an ellipsoid's geodesics are not planar),
// so cpgait follows OpenSim's construction for the same numbers.
//
// In the ellipsoid's frame W (semi-axes along x, y, z, centred on the origin), doubles only: a path
// differentiated through it keeps the tangent points fixed on the ellipsoid's body, which is how
// OpenSim's moment arms treat them.
#include <Eigen/Core>

#include "cpgait/model/model.h"
#include "cpgait/muscles/wrap_cylinder.h"

namespace cpgait {

SegmentWrap<double> wrap_ellipsoid(const WrapObject& ellipsoid, PathWrap::Method method, const Eigen::Vector3d& p1,
                                   const Eigen::Vector3d& p2);

}  // namespace cpgait
