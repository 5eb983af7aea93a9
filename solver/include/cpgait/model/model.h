#pragma once
// The immutable musculoskeletal model. Built once by the .osim reader, then shared read-only by every
// thread; all per-evaluation state lives in a Workspace (see kinematics/forward_kinematics.h).
//
// Every joint is stored as OpenSim's CustomJoint SpatialTransform (three body-fixed rotations, then
// three translations along axes fixed in the parent's joint frame F, each a function of one
// coordinate); Pin, Weld, Ball, Free, Slider, Universal and Planar joints are converted to it.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "cpgait/capture/body_xyz.h"
#include "cpgait/capture/function.h"

namespace cpgait {

namespace millard2012 {
struct Curves;  // cpgait/muscles/millard2012.h
}
namespace schutte1993 {
struct Curves;  // cpgait/muscles/schutte1993.h
}
namespace rigid_tendon_muscle {
struct Curves;  // cpgait/muscles/rigid_tendon_muscle.h
}
namespace degroote_fregly2016 {
struct Parameters;  // cpgait/muscles/degroote_fregly2016.h
}
class Expression;  // cpgait/model/expression.h

// A rigid transform: x_parent = rotation * x_child + translation.
struct Pose {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation_m = Eigen::Vector3d::Zero();
};

// A display mesh fixed to a body (what OpenSim draws: a Mesh's mesh_file, a 3.x VisibleObject's
// geometry file). Not used by any computation; the dashboard draws it.
struct BodyMesh {
  std::string file;                                   // as named in the model (found in a Geometry folder)
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();    // per axis, applied to the mesh's vertices
  Pose pose;                                          // of the mesh's frame in the body
};

struct Body {
  std::string name;
  double mass_kg = 0;
  Eigen::Vector3d com_m = Eigen::Vector3d::Zero();          // in the body frame
  Eigen::Matrix3d inertia_kg_m2 = Eigen::Matrix3d::Zero();  // about the COM, in the body frame
  int joint = -1;                                            // the joint whose child this is; -1 for ground
  std::vector<BodyMesh> meshes;  // the body's own attached geometry first (document order), then its offset frames'
};

struct TransformAxis {
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();  // unit, in F
  int coordinate = -1;                              // -1: function is constant
  Function function = Function::constant(0.0);
};

struct Joint {
  std::string name;
  std::string type;  // as in the file: CustomJoint, PinJoint, ...
  int parent_body = 0;
  int child_body = 0;
  Pose parent_offset;  // frame F in the parent body
  Pose child_offset;   // frame M in the child body
  std::array<TransformAxis, 6> axes;  // rotation1..3, translation1..3
  std::vector<int> coordinates;
};

struct Coordinate {
  enum class Motion { kRotational, kTranslational, kCoupled };
  std::string name;
  int joint = -1;
  Motion motion = Motion::kRotational;
  double default_value = 0;  // rad or m
  double range_min = -1e30;
  double range_max = 1e30;
  bool clamped = false;
  bool locked = false;
  bool is_angle() const { return motion != Motion::kTranslational; }
};

struct Marker {
  std::string name;
  int body = 0;
  Eigen::Vector3d location_m = Eigen::Vector3d::Zero();  // in the body frame
  bool fixed = false;
};

struct PathPoint {
  enum class Kind { kFixed, kConditional, kMoving };
  std::string name;
  Kind kind = Kind::kFixed;
  int body = 0;
  Eigen::Vector3d location_m = Eigen::Vector3d::Zero();
  // kConditional: active while range_min <= q[coordinate] <= range_max.
  int coordinate = -1;
  double range_min = 0, range_max = 0;
  // kMoving: location[k] = functions[k](q[moving_coordinates[k]]).
  std::array<int, 3> moving_coordinates{-1, -1, -1};
  std::array<Function, 3> moving_functions{Function::constant(0), Function::constant(0), Function::constant(0)};
};

// A wrapping surface fixed to a body. The shape's own frame W sits at `pose` in the body; a cylinder's
// axis is W's z, centred at W's origin.
struct WrapObject {
  enum class Shape { kCylinder, kSphere, kEllipsoid, kTorus };
  std::string name;
  Shape shape = Shape::kCylinder;
  int body = 0;
  Pose pose;  // W in the body frame
  double radius_m = 1.0;   // cylinder and sphere (OpenSim's default 1 m)
  double length_m = 1.0;   // cylinder: tangent points beyond +-length/2 on both ends mean no wrap
  Eigen::Vector3d dimensions_m = Eigen::Vector3d::Ones();  // ellipsoid radii
  double inner_radius_m = 0.01, outer_radius_m = 0.05;     // torus: its tube's radius, its centre circle's (OpenSim's defaults)
  int quadrant_axis = -1;  // -1: all quadrants; else 0,1,2 = x,y,z of W
  int quadrant_sign = 0;   // +1 or -1 with quadrant_axis
  bool active = true;
};

// One wrapping surface a path may wrap over, between path points start..end (1-based as OpenSim's
// <range>; -1 means the path's first or last point).
struct PathWrap {
  enum class Method { kHybrid, kMidpoint, kAxial };  // how an ellipsoid picks its wrapping plane
  int wrap_object = 0;
  Method method = Method::kHybrid;
  int start_point = -1;
  int end_point = -1;
};

struct Muscle {
  std::string name;
  std::string type;  // Thelen2003Muscle, Millard2012EquilibriumMuscle, ...
  double max_isometric_force_N = 0;
  double optimal_fiber_length_m = 0;
  double tendon_slack_length_m = 0;
  double pennation_angle_at_optimal_rad = 0;
  double sin_pennation_at_optimal = 0;   // its sine, set with it (the muscle functions need it in every evaluation)
  double max_contraction_velocity = 10;  // optimal fiber lengths per second
  double activation_time_constant_s = 0.015;
  double deactivation_time_constant_s = 0.060;
  // Thelen2003 curve parameters (OpenSim defaults when absent).
  double fmax_tendon_strain = 0.04;
  double fmax_muscle_strain = 0.6;
  double kshape_active = 0.45;
  double kshape_passive = 5.0;
  double af = 0.25;
  double flen = 1.4;
  double min_control = 0.01;
  double max_control = 1.0;
  // Millard2012EquilibriumMuscle: its curves and properties (nullptr for other muscle types).
  std::shared_ptr<const millard2012::Curves> millard;
  // Schutte1993Muscle (OpenSim's deprecated Schutte1993Muscle_Deprecated): its curves (nullptr for
  // other muscle types).
  std::shared_ptr<const schutte1993::Curves> schutte;
  // RigidTendonMuscle: its curves; DeGrooteFregly2016Muscle: its parameters (nullptr otherwise).
  std::shared_ptr<const rigid_tendon_muscle::Curves> rigid_tendon;
  std::shared_ptr<const degroote_fregly2016::Parameters> degroote;
  std::vector<PathPoint> path;
  std::vector<PathWrap> wraps;  // in the order OpenSim applies them
};

// OpenSim's CoordinateCouplerConstraint: q[dependent] = scale * function(q[independent]).
struct CoordinateCoupler {
  std::string name;
  int dependent = -1;
  int independent = -1;
  Function function = Function::linear(1.0, 0.0);
  double scale = 1.0;
};

// OpenSim's CoordinateLimitForce: a spring past each end of a coordinate's range, its stiffness
// switched on over `transition` by a quintic step, and damping while either is on. SI units (rad or
// m, N m/rad or N/m); the document's degrees are converted when read.
struct CoordinateLimitForce {
  std::string name;
  int coordinate = -1;
  double upper_stiffness = 0, upper_limit = 0, lower_stiffness = 0, lower_limit = 0, damping = 0, transition = 0;
};

// OpenSim's SpringGeneralizedForce: -stiffness (q - rest_length) - viscosity qdot on one coordinate,
// in the coordinate's own units (rad or m; OpenSim does not convert these from degrees).
struct SpringGeneralizedForce {
  std::string name;
  int coordinate = -1;
  double stiffness = 0, rest_length = 0, viscosity = 0;
};

// OpenSim's ExpressionBasedCoordinateForce: a generalized force on one coordinate given by an
// expression in the coordinate's value q and speed qdot (its own units: rad or m).
struct ExpressionBasedCoordinateForce {
  std::string name;
  int coordinate = -1;
  std::shared_ptr<const Expression> expression;  // over the variables {q, qdot}
};

// OpenSim's PathSpring: tension = stiffness * max(0, L - resting_length) * (1 + dissipation * dL/dt)
// along a path of points and wraps like a muscle's, pulling its ends together.
struct PathSpring {
  std::string name;
  double resting_length_m = 0;
  double stiffness_N_per_m = 0;
  double dissipation_s_per_m = 0;
  std::vector<PathPoint> path;
  std::vector<PathWrap> wraps;
};

// OpenSim's PathActuator: its path (points and wraps as a muscle's). Its tension is control *
// optimal_force, which the actuator reader (cpgait/capture/actuator_set.h) reads with the other actuators.
struct PathActuator {
  std::string name;
  std::vector<PathPoint> path;
  std::vector<PathWrap> wraps;
};

class Model {
 public:
  std::string name;
  std::string source;  // file it was read from
  Eigen::Vector3d gravity_m_s2{0, -9.80665, 0};
  std::vector<Body> bodies;          // bodies[0] is ground
  std::vector<Joint> joints;         // ordered so that a joint's parent body comes before its child
  std::vector<Coordinate> coordinates;
  std::vector<Marker> markers;
  std::vector<Muscle> muscles;
  std::vector<WrapObject> wrap_objects;
  std::vector<CoordinateCoupler> couplers;  // in file order; a dependent coordinate is no coupler's independent one
  std::vector<CoordinateLimitForce> coordinate_limit_forces;
  std::vector<PathSpring> path_springs;
  std::vector<PathActuator> path_actuators;
  std::vector<SpringGeneralizedForce> spring_generalized_forces;
  std::vector<ExpressionBasedCoordinateForce> expression_based_coordinate_forces;

  int num_coordinates() const { return static_cast<int>(coordinates.size()); }
  int body_index(std::string_view name) const;
  int coordinate_index(std::string_view name) const;
  int marker_index(std::string_view name) const;
  int joint_index(std::string_view name) const;
  int muscle_index(std::string_view name) const;
  int wrap_object_index(std::string_view name) const;
  Eigen::VectorXd default_coordinates() const;
  double total_mass_kg() const;
};

// Sets every coupled (dependent) coordinate from its independent one.
template <typename T>
void apply_coordinate_couplers(const Model& model, T* q) {
  for (const auto& c : model.couplers) q[c.dependent] = T(c.scale) * c.function.value(q[c.independent]);
}

// Coordinate values in OpenSim's file units: angles in degrees, translations in metres, one row per
// time, columns named after the coordinates.
Eigen::MatrixXd coordinates_in_file_units(const Model& model, const Eigen::MatrixXd& q);
std::vector<std::string> coordinate_names(const Model& model);


}  // namespace cpgait
