#include "cpgait/muscles/muscle_path.h"

namespace cpgait {

// dL/dq by segments: for a straight segment from point a (on body A) to b (on body B) with unit
// direction e, dL/dq_c = e . (dx_b/dq_c - dx_a/dq_c). A coordinate moving both bodies moves the
// segment rigidly (e . (w x d) = 0 for d along e), so only the joints between A and B, below their
// common ancestor, contribute: +e . (w_c x x_b + v_c) on B's side, -e . (w_c x x_a + v_c) on A's, plus
// a moving point's own motion along its body's axes.
namespace {

// A moving point's own motion along its body's axes: own(c, axis, df) for each coordinate c that
// moves it, the point moving by axis (ground) * df per unit of q_c.
template <typename Own>
void for_each_own_coordinate(const PathPoint& p, const KinematicsWorkspace<double>& ws, const double* q, Own&& own) {
  if (p.kind != PathPoint::Kind::kMoving) return;
  const auto& R = ws.body_in_ground[p.body].rotation;
  for (int a = 0; a < 3; ++a)
    if (const int c = p.moving_coordinates[a]; c >= 0) own(c, R.col(a), p.moving_functions[a].derivative(q[c]));
}

// The path's length and dL/dq from its current vertices.
template <typename PathOwner>
double length_and_gradient(const Model& model, const PathOwner& owner, const double* q, const KinematicsWorkspace<double>& ws,
                           const MotionSubspace& S, const std::vector<int>& depth, std::vector<PathVertex<double>>& path,
                           Eigen::RowVectorXd& dL_dq) {
  auto parent = [&](int body) { return model.joints[model.bodies[body].joint].parent_body; };
  auto add_chain = [&](int body, const Eigen::Vector3d& x, const Eigen::Vector3d& e, double sign, double* row) {
    const Joint& j = model.joints[model.bodies[body].joint];
    for (int c : j.coordinates) row[c] += sign * e.dot(point_velocity_column(S, c, x));
  };
  auto add_moving = [&](const PathPoint& p, const Eigen::Vector3d& e, double sign, double* row) {
    for_each_own_coordinate(p, ws, q, [&](int c, const auto& axis, double df) { row[c] += sign * e.dot(axis) * df; });
  };
  current_path(model, owner, q, ws, path);
  dL_dq.setZero(model.num_coordinates());
  double length = 0;
  // A wrap's surface stretch moves with the surface's body, and the path is a geodesic there, so
  // its tangent points count as points fixed on that body (their sliding changes the length only
  // to second order).
  for (std::size_t i = 0; i + 1 < path.size(); ++i) {
    const PathVertex<double>& u = path[i];
    const PathVertex<double>& v = path[i + 1];
    if (u.wrap >= 0 && v.wrap == u.wrap) {
      length += u.surface_length_m;
      continue;
    }
    const Eigen::Vector3d d = v.x_ground - u.x_ground;
    const double n = d.norm();
    length += n;
    if (n == 0) continue;
    const Eigen::Vector3d e = d / n;
    for (int b = v.body, a = u.body; a != b;) {
      if (depth[b] >= depth[a]) {
        add_chain(b, v.x_ground, e, +1.0, dL_dq.data());
        b = parent(b);
      } else {
        add_chain(a, u.x_ground, e, -1.0, dL_dq.data());
        a = parent(a);
      }
    }
    if (v.point) add_moving(*v.point, e, +1.0, dL_dq.data());
    if (u.point) add_moving(*u.point, e, -1.0, dL_dq.data());
  }
  return length;
}

// Depth of each body in the tree (ground 0), for the walk to the common ancestor.
std::vector<int> body_depths(const Model& model) {
  std::vector<int> depth(model.bodies.size(), 0);
  for (const Joint& j : model.joints) depth[j.child_body] = depth[j.parent_body] + 1;  // parents come first
  return depth;
}

}  // namespace

std::vector<int> spanned_coordinates(const Model& model, const Muscle& muscle) {
  const std::vector<int> depth = body_depths(model);
  auto parent = [&](int body) { return model.joints[model.bodies[body].joint].parent_body; };
  std::vector<int> bodies;
  for (const PathPoint& p : muscle.path) bodies.push_back(p.body);
  for (const PathWrap& w : muscle.wraps) bodies.push_back(model.wrap_objects[w.wrap_object].body);
  std::vector<char> spanned(model.num_coordinates(), 0);
  if (!bodies.empty()) {
    // Each body's chain up to the common ancestor of all of them (length_and_gradient's walk per
    // segment stays below it).
    int top = bodies.front();
    for (int b : bodies) {
      int a = top;
      while (a != b) {
        if (depth[b] >= depth[a]) b = parent(b);
        else a = parent(a);
      }
      top = a;
    }
    for (int b : bodies)
      for (; b != top; b = parent(b))
        for (int c : model.joints[model.bodies[b].joint].coordinates) spanned[c] = 1;
  }
  for (const PathPoint& p : muscle.path)
    if (p.kind == PathPoint::Kind::kMoving)
      for (int c : p.moving_coordinates)
        if (c >= 0) spanned[c] = 1;
  std::vector<int> out;
  for (int c = 0; c < model.num_coordinates(); ++c)
    if (spanned[c]) out.push_back(c);
  return out;
}

void muscle_path_geometry(const Model& model, const double* q, const double* qd, const KinematicsWorkspace<double>& ws,
                          const MotionSubspace& S, MusclePathGeometry& out) {
  const std::vector<int> depth = body_depths(model);
  Eigen::RowVectorXd dL_dq(model.num_coordinates());
  const Eigen::Map<const Eigen::VectorXd> qdot(qd, model.num_coordinates());
  std::vector<PathVertex<double>> path;
  for (std::size_t m = 0; m < model.muscles.size(); ++m) {
    out.length_m[m] = length_and_gradient(model, model.muscles[m], q, ws, S, depth, path, dL_dq);
    out.moment_arm_m.row(m) = -dL_dq;
    out.lengthening_speed_m_s[m] = dL_dq.dot(qdot);
  }
}

namespace {
bool moves_on_its_body(const PathVertex<double>& p) { return p.point && p.point->kind == PathPoint::Kind::kMoving; }
}  // namespace

double current_path_segments(const std::vector<PathVertex<double>>& path, std::vector<StretchingSegment>& segments) {
  segments.clear();
  double length = 0;
  for (std::size_t i = 0; i + 1 < path.size(); ++i) {
    const PathVertex<double>& u = path[i];
    const PathVertex<double>& v = path[i + 1];
    if (u.wrap >= 0 && v.wrap == u.wrap) {
      length += u.surface_length_m;
      continue;
    }
    const Eigen::Vector3d d = v.x_ground - u.x_ground;
    const double n = d.norm();
    length += n;
    // A segment fixed on one body keeps its length whatever the coordinates do.
    if (n > 0 && (u.body != v.body || moves_on_its_body(u) || moves_on_its_body(v)))
      segments.push_back({static_cast<int>(i), static_cast<int>(i + 1), d, n});
  }
  return length;
}

double current_path_lengthening_speed(const std::vector<PathVertex<double>>& path,
                                      const std::vector<StretchingSegment>& segments, const double* q, const double* qd,
                                      const KinematicsWorkspace<double>& ws,
                                      const std::vector<SpatialVector>& body_velocity) {
  auto velocity = [&](const PathVertex<double>& p) -> Eigen::Vector3d {
    const SpatialVector& V = body_velocity[p.body];
    Eigen::Vector3d v = V.tail<3>() + V.head<3>().cross(p.x_ground);
    if (moves_on_its_body(p))
      for_each_own_coordinate(*p.point, ws, q, [&](int c, const auto& axis, double df) { v += axis * (df * qd[c]); });
    return v;
  };
  // A vertex between two segments: its velocity once.
  double speed = 0;
  int last = -1;
  Eigen::Vector3d v_last;
  for (const StretchingSegment& s : segments) {
    const Eigen::Vector3d v_u = s.u == last ? v_last : velocity(path[s.u]);
    v_last = velocity(path[s.v]);
    last = s.v;
    speed += s.d.dot(v_last - v_u) / s.n;
  }
  return speed;
}

void add_path_tension(const std::vector<PathVertex<double>>& path, const std::vector<StretchingSegment>& segments,
                      const double* q, const KinematicsWorkspace<double>& ws, double tension_N,
                      std::vector<SpatialVector>& body_wrench, double* tau) {
  auto apply = [&](const PathVertex<double>& p, const Eigen::Vector3d& f) {
    body_wrench[p.body].head<3>() += p.x_ground.cross(f);
    body_wrench[p.body].tail<3>() += f;
    if (moves_on_its_body(p))
      for_each_own_coordinate(*p.point, ws, q, [&](int c, const auto& axis, double df) { tau[c] += f.dot(axis) * df; });
  };
  for (const StretchingSegment& s : segments) {
    const Eigen::Vector3d f = (tension_N / s.n) * s.d;  // pulls u towards v, v towards u
    apply(path[s.u], f);
    apply(path[s.v], -f);
  }
}

namespace {

template <typename PathOwner>
void owner_path_geometry(const Model& model, const PathOwner& owner, const double* q, const double* qd,
                         const KinematicsWorkspace<double>& ws, const MotionSubspace& S, double& length_m,
                         double& lengthening_speed_m_s, Eigen::RowVectorXd& dL_dq) {
  std::vector<PathVertex<double>> path;
  length_m = length_and_gradient(model, owner, q, ws, S, body_depths(model), path, dL_dq);
  lengthening_speed_m_s = qd ? dL_dq.dot(Eigen::Map<const Eigen::VectorXd>(qd, model.num_coordinates())) : 0.0;
}

}  // namespace

void path_geometry(const Model& model, const PathSpring& spring, const double* q, const double* qd,
                   const KinematicsWorkspace<double>& ws, const MotionSubspace& S, double& length_m,
                   double& lengthening_speed_m_s, Eigen::RowVectorXd& dL_dq) {
  owner_path_geometry(model, spring, q, qd, ws, S, length_m, lengthening_speed_m_s, dL_dq);
}

void path_geometry(const Model& model, const PathActuator& actuator, const double* q, const double* qd,
                   const KinematicsWorkspace<double>& ws, const MotionSubspace& S, double& length_m,
                   double& lengthening_speed_m_s, Eigen::RowVectorXd& dL_dq) {
  owner_path_geometry(model, actuator, q, qd, ws, S, length_m, lengthening_speed_m_s, dL_dq);
}

}  // namespace cpgait
