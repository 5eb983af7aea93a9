#include "cpgait/model/osim_reader.h"

#include <cctype>
#include <map>
#include <set>
#include <stdexcept>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/xml_document.h"
#include "cpgait/model/expression.h"
#include "cpgait/muscles/degroote_fregly2016.h"
#include "cpgait/muscles/millard2012.h"
#include "cpgait/muscles/rigid_tendon_muscle.h"
#include "cpgait/muscles/schutte1993.h"

namespace cpgait {
namespace {

using pugi::xml_node;

bool is(const xml_node& n, const char* name) { return std::string_view(n.name()) == name; }

// Elements that only matter for display or for OpenSim features that have no effect on the
// mechanics cpgait computes; they are skipped without a warning.
const std::set<std::string> kQuietlySkipped = {
    "FrameGeometry", "attached_geometry", "Appearance", "credits", "publications", "length_units",
    "force_units", "ControllerSet", "ContactGeometrySet", "ProbeSet", "defaults", "ConstraintSet",
    "ComponentSet", "validator", "assembly_accuracy", "gravity", "Ground", "BodySet",
    "JointSet", "MarkerSet", "ForceSet", "components", "visible", "VisibleObject"};

struct Frame {
  int body = 0;
  Pose pose;  // frame in its body
};

Pose compose(const Pose& a, const Pose& b) {
  return {a.rotation * b.rotation, a.rotation * b.translation_m + a.translation_m};
}

class Reader {
 public:
  Reader(const xml::Document& d, const OsimReadOptions& o, OsimReadResult& r) : d_(d), options_(o), r_(r), m_(r.model) {}

  void read() {
    xml_node root = d_.doc().document_element();
    int version = 40000;
    if (is(root, "OpenSimDocument")) {
      version = root.attribute("Version").as_int(40000);
      root = root.child("Model");
    }
    if (!root || !is(root, "Model")) throw InputError(d_.name(), 1, "Model", "not an OpenSim model: no <Model> element");
    model_node_ = root;
    m_.name = root.attribute("name").value();
    m_.source = d_.name();
    if (root.child("gravity")) m_.gravity_m_s2 = d_.vec3(root, "gravity", m_.gravity_m_s2);
    if (version < 30000) warn(root, "document version " + std::to_string(version) + " predates OpenSim 3; reading it as 3.x");

    for (const auto& child : root.children()) {
      if (child.type() != pugi::node_element) continue;
      const std::string n = child.name();
      if (!kQuietlySkipped.count(n)) warn(child, "element <" + n + "> is not used by cpgait");
    }
    if (xml_node cg = root.child("ContactGeometrySet"); cg && cg.child("objects").first_child())
      warn(cg, "contact geometry is not used (contact spheres come from cpgait's own contact file)");

    read_bodies();
    read_joints();
    order_joints();
    read_constraints(root.child("ConstraintSet"));
    read_markers(root.child("MarkerSet"));
    read_forces();
    if (!options_.marker_set_file.empty()) read_marker_set_file(options_.marker_set_file);
  }

 private:
  const xml::Document& d_;
  const OsimReadOptions& options_;
  OsimReadResult& r_;
  Model& m_;
  xml_node model_node_;
  std::map<std::string, Frame> frames_;
  std::vector<xml_node> joint_nodes_;   // in file order
  std::vector<int> joint_child_;        // child body of each joint node
  std::vector<std::pair<millard2012::Parameters, std::shared_ptr<const millard2012::Curves>>> millard_curves_;

  void warn(const xml_node& n, const std::string& msg) {
    r_.warnings.push_back(d_.name() + ":" + std::to_string(d_.line_of(n)) + ": " + n.name() +
                          (n.attribute("name") ? std::string(" '") + n.attribute("name").value() + "'" : "") +
                          ": " + msg);
  }

  void add_body(const xml_node& n, const std::string& name) {
    Body b;
    b.name = name;
    b.mass_kg = d_.number(n, "mass", 0.0);
    if (b.mass_kg < 0) d_.fail(n.child("mass"), "mass must not be negative");
    b.com_m = d_.vec3(n, "mass_center", Eigen::Vector3d::Zero());
    if (n.child("inertia")) {
      const auto v = d_.numbers(n, "inertia");
      if (v.size() != 6) d_.fail(n.child("inertia"), "expected Ixx Iyy Izz Ixy Ixz Iyz");
      b.inertia_kg_m2 << v[0], v[3], v[4], v[3], v[1], v[5], v[4], v[5], v[2];
    } else if (n.child("inertia_xx")) {  // OpenSim 3.x
      const double xx = d_.number(n, "inertia_xx", 0), yy = d_.number(n, "inertia_yy", 0),
                   zz = d_.number(n, "inertia_zz", 0), xy = d_.number(n, "inertia_xy", 0),
                   xz = d_.number(n, "inertia_xz", 0), yz = d_.number(n, "inertia_yz", 0);
      b.inertia_kg_m2 << xx, xy, xz, xy, yy, yz, xz, yz, zz;
    }
    if (m_.body_index(name) >= 0) d_.fail(n, "body name '" + name + "' is used twice");
    read_meshes(n, Pose{}, b.meshes);
    const int index = static_cast<int>(m_.bodies.size());
    m_.bodies.push_back(b);
    frames_["/bodyset/" + name] = {index, Pose{}};
    frames_[name] = {index, Pose{}};
    for (const auto& c : n.child("components").children("PhysicalOffsetFrame")) pending_frames_.push_back(c);
    read_wrap_objects(n, index);
  }
  std::vector<xml_node> pending_frames_;

  // Display geometry: 4.x <attached_geometry><Mesh>, 3.x <VisibleObject> (its geometry_files, or a
  // GeometrySet of DisplayGeometry, each under the VisibleObject's transform and scale).
  void read_meshes(const xml_node& n, const Pose& frame, std::vector<BodyMesh>& out) {
    for (const auto& g : n.child("attached_geometry").children("Mesh")) {
      const std::string file = d_.text(g, "mesh_file");
      if (!file.empty()) out.push_back({file, d_.vec3(g, "scale_factors", Eigen::Vector3d::Ones()), frame});
    }
    const xml_node v = n.child("VisibleObject");
    if (!v) return;
    const auto transform = [&](const xml_node& x) {
      Pose p;
      if (x.child("transform")) {
        const auto t = d_.numbers(x, "transform");
        if (t.size() != 6) d_.fail(x.child("transform"), "expected three rotations (rad) and a translation (m)");
        p.rotation = rotation_from_body_xyz(Eigen::Vector3d(t[0], t[1], t[2]));
        p.translation_m = Eigen::Vector3d(t[3], t[4], t[5]);
      }
      return p;
    };
    const Pose vp = compose(frame, transform(v));
    const Eigen::Vector3d vs = d_.vec3(v, "scale_factors", Eigen::Vector3d::Ones());
    const std::string files = d_.text(v, "geometry_files");  // split_ws views into it
    for (const auto& file : text::split_ws(files)) out.push_back({std::string(file), vs, vp});
    for (const auto& g : v.child("GeometrySet").child("objects").children("DisplayGeometry")) {
      const std::string file = d_.text(g, "geometry_file");
      if (!file.empty()) out.push_back({file, vs.cwiseProduct(d_.vec3(g, "scale_factors", Eigen::Vector3d::Ones())), compose(vp, transform(g))});
    }
  }

  void read_wrap_objects(const xml_node& body_node, int body) {
    for (const auto& w : body_node.child("WrapObjectSet").child("objects").children()) {
      if (w.type() != pugi::node_element) continue;
      WrapObject o;
      o.name = w.attribute("name").value();
      o.body = body;
      const std::string kind = w.name();
      if (kind == "WrapCylinder") o.shape = WrapObject::Shape::kCylinder;
      else if (kind == "WrapSphere") o.shape = WrapObject::Shape::kSphere;
      else if (kind == "WrapEllipsoid") o.shape = WrapObject::Shape::kEllipsoid;
      else if (kind == "WrapTorus") o.shape = WrapObject::Shape::kTorus;
      else d_.fail(w, "unknown wrap object type");
      if (o.name.empty()) d_.fail(w, kind + " without a name");
      if (m_.wrap_object_index(o.name) >= 0) d_.fail(w, "wrap object name '" + o.name + "' is used twice");
      o.pose.translation_m = d_.vec3(w, "translation", Eigen::Vector3d::Zero());
      o.pose.rotation = rotation_from_body_xyz(d_.vec3(w, "xyz_body_rotation", Eigen::Vector3d::Zero()));
      o.active = d_.boolean(w, "active", true);
      o.radius_m = d_.number(w, "radius", 1.0);
      o.length_m = d_.number(w, "length", 1.0);
      o.dimensions_m = d_.vec3(w, "dimensions", Eigen::Vector3d::Ones());
      if (o.radius_m <= 0 || o.length_m < 0 || (o.dimensions_m.array() <= 0).any())
        d_.fail(w, "radius, length and dimensions must be positive");
      std::string quadrant = d_.text(w, "quadrant");
      if (!quadrant.empty() && quadrant[0] == '+') quadrant.erase(0, 1);
      if (quadrant.empty() || quadrant == "all" || quadrant == "ALL" || quadrant == "All") {
        o.quadrant_axis = -1;
      } else if (quadrant.size() <= 2 && std::string("xyzXYZ").find(quadrant.back()) != std::string::npos &&
                 (quadrant.size() == 1 || quadrant[0] == '-')) {
        o.quadrant_axis = (std::tolower(quadrant.back()) - 'x');
        o.quadrant_sign = quadrant[0] == '-' ? -1 : 1;
      } else {
        d_.fail(w.child("quadrant"), "quadrant must be all, x, -x, y, -y, z or -z");
      }
      if (o.shape == WrapObject::Shape::kTorus) {
        o.inner_radius_m = d_.number(w, "inner_radius", o.inner_radius_m);
        o.outer_radius_m = d_.number(w, "outer_radius", o.outer_radius_m);
        // As OpenSim's WrapTorus::extendFinalizeFromProperties.
        if (!(o.inner_radius_m > 0) || !(o.outer_radius_m > o.inner_radius_m))
          d_.fail(w, "a WrapTorus needs 0 < inner_radius < outer_radius");
      }
      m_.wrap_objects.push_back(o);
    }
  }

  void read_bodies() {
    Body ground;
    ground.name = "ground";
    m_.bodies.push_back(ground);
    frames_["/ground"] = {0, Pose{}};
    frames_["ground"] = {0, Pose{}};
    read_wrap_objects(model_node_.child("Ground"), 0);
    for (const auto& n : model_node_.child("BodySet").child("objects").children("Body")) {
      const std::string name = n.attribute("name").value();
      if (name.empty()) d_.fail(n, "Body without a name");
      if (name == "ground") {  // OpenSim 3.x lists ground as a body
        read_wrap_objects(n, 0);
        continue;
      }
      add_body(n, name);
    }
    for (const auto& n : model_node_.child("BodySet").child("objects").children()) {
      if (n.type() == pugi::node_element && !is(n, "Body")) warn(n, "unsupported body type; skipped");
    }
    for (const auto& c : model_node_.child("components").children("PhysicalOffsetFrame")) pending_frames_.push_back(c);
    // Model-level offset frames may refer to each other; resolve until nothing changes.
    for (std::size_t pass = 0; pass <= pending_frames_.size(); ++pass) {
      bool progress = false;
      for (auto& f : pending_frames_) {
        if (!f) continue;
        if (try_add_offset_frame(f, "")) {
          f = xml_node();
          progress = true;
        }
      }
      if (!progress) break;
    }
    for (const auto& f : pending_frames_)
      if (f) warn(f, "offset frame's parent could not be resolved; skipped");
  }

  Pose offset_pose(const xml_node& n, const char* translation, const char* orientation) {
    Pose p;
    p.translation_m = d_.vec3(n, translation, Eigen::Vector3d::Zero());
    p.rotation = rotation_from_body_xyz(d_.vec3(n, orientation, Eigen::Vector3d::Zero()));
    return p;
  }

  // Resolves an OpenSim frame path: absolute (/bodyset/x, /ground, /jointset/j/f), relative to the
  // joint (a frame the joint owns), or a bare body name.
  const Frame* resolve_frame(std::string path, const std::string& joint_scope) {
    if (!joint_scope.empty()) {
      auto it = frames_.find("/jointset/" + joint_scope + "/" + path);
      if (it != frames_.end()) return &it->second;
    }
    while (path.size() > 1 && path.back() == '/') path.pop_back();
    if (path.rfind("../", 0) == 0) path = path.substr(3);
    auto it = frames_.find(path);
    return it == frames_.end() ? nullptr : &it->second;
  }

  bool try_add_offset_frame(const xml_node& n, const std::string& joint_scope) {
    const std::string parent = d_.text(n, "socket_parent");
    const Frame* p = resolve_frame(parent, joint_scope);
    if (!p) return false;
    Frame f{p->body, compose(p->pose, offset_pose(n, "translation", "orientation"))};
    read_meshes(n, f.pose, m_.bodies[static_cast<std::size_t>(f.body)].meshes);
    const std::string name = n.attribute("name").value();
    if (!joint_scope.empty()) frames_["/jointset/" + joint_scope + "/" + name] = f;
    else frames_[name] = f;
    return true;
  }

  int coordinate_of_axis(const xml_node& ax, const std::vector<std::string>& names, const std::string& joint) {
    // <coordinates> (2.x on), <coordinate> (1.x); the cells below view into `listed`.
    const std::string listed = ax.child("coordinates") ? d_.text(ax, "coordinates") : d_.text(ax, "coordinate");
    const auto cells = text::split_ws(listed);
    if (cells.empty()) return -1;
    if (cells.size() > 1) d_.fail(ax.child("coordinates"), "functions of several coordinates are not supported");
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == cells[0]) return m_.coordinate_index(names[i]);
    d_.fail(ax.child("coordinates"), "coordinate '" + std::string(cells[0]) + "' is not one of joint '" + joint + "'s coordinates");
  }

  Function read_function(const xml_node& f) {
    const std::string kind = f.name();
    if (kind == "Constant") return Function::constant(d_.number(f, "value", 0.0));
    if (kind == "LinearFunction") {
      const auto c = d_.numbers(f, "coefficients");
      if (c.size() != 2) d_.fail(f, "LinearFunction needs 2 coefficients (slope, intercept)");
      return Function::linear(c[0], c[1]);
    }
    if (kind == "PolynomialFunction") return Function::polynomial(d_.numbers(f, "coefficients"));
    // OpenSim 4 registers NaturalCubicSpline and natCubicSpline as other names of SimmSpline
    // (RegisterTypes_osimCommon), so they are read as SimmSplines.
    if (kind == "SimmSpline" || kind == "NaturalCubicSpline" || kind == "natCubicSpline" ||
        kind == "PiecewiseLinearFunction" || kind == "GCVSpline") {
      auto x = d_.numbers(f, "x"), y = d_.numbers(f, "y");
      try {
        if (kind == "PiecewiseLinearFunction") return Function::piecewise_linear(std::move(x), std::move(y));
        if (kind == "GCVSpline") warn(f, "GCVSpline approximated by an interpolating cubic spline");
        return Function::simm_spline(std::move(x), std::move(y));
      } catch (const std::invalid_argument& e) {
        d_.fail(f, e.what());
      }
    }
    if (kind == "MultiplierFunction") {
      const xml_node inner = f.child("function").first_child();
      if (!inner) d_.fail(f, "MultiplierFunction without a <function>");
      return read_function(inner).scaled(d_.number(f, "scale", 1.0));
    }
    d_.fail(f, "unsupported function type");
  }

  // The function of a TransformAxis or moving point location: OpenSim 4 names the element
  // name="function" directly; OpenSim 3 wraps it in <function>.
  xml_node function_node(const xml_node& parent) {
    if (const xml_node w = parent.child("function")) return w.first_child();
    for (const auto& c : parent.children())
      if (c.type() == pugi::node_element && std::string_view(c.attribute("name").value()) == "function") return c;
    return {};
  }

  void set_axis(Joint& j, int slot, const Eigen::Vector3d& axis, int coordinate) {
    j.axes[slot].axis = axis;
    j.axes[slot].coordinate = coordinate;
    j.axes[slot].function = coordinate >= 0 ? Function::linear(1.0, 0.0) : Function::constant(0.0);
  }

  void read_transform_axis(Joint& j, int slot, const xml_node& ax, const std::vector<std::string>& names) {
    Eigen::Vector3d axis = d_.vec3(ax, "axis", j.axes[slot].axis);
    if (axis.norm() < 1e-12) d_.fail(ax.child("axis"), "axis has zero length");
    axis.normalize();
    const int c = coordinate_of_axis(ax, names, j.name);
    j.axes[slot].axis = axis;
    j.axes[slot].coordinate = c;
    const xml_node fn = function_node(ax);
    if (fn) j.axes[slot].function = read_function(fn);
    else j.axes[slot].function = c >= 0 ? Function::linear(1.0, 0.0) : Function::constant(0.0);
    if (c < 0 && !j.axes[slot].function.is_constant())
      j.axes[slot].function = Function::constant(j.axes[slot].function.value(0.0));
  }

  void read_joint(const xml_node& n, int child_hint) {
    Joint j;
    j.type = n.name();
    j.name = n.attribute("name").value();
    if (j.name.empty()) d_.fail(n, "joint without a name");
    // Frames the joint owns (4.x) come first so the sockets can name them.
    for (const auto& f : n.child("frames").children("PhysicalOffsetFrame"))
      if (!try_add_offset_frame(f, j.name)) d_.fail(f, "cannot resolve socket_parent '" + d_.text(f, "socket_parent") + "'");
    if (n.child("socket_parent_frame") || n.child("socket_child_frame")) {
      const Frame* p = resolve_frame(d_.text(n, "socket_parent_frame"), j.name);
      const Frame* c = resolve_frame(d_.text(n, "socket_child_frame"), j.name);
      if (!p) d_.fail(n.child("socket_parent_frame"), "unknown frame '" + d_.text(n, "socket_parent_frame") + "'");
      if (!c) d_.fail(n.child("socket_child_frame"), "unknown frame '" + d_.text(n, "socket_child_frame") + "'");
      j.parent_body = p->body;
      j.parent_offset = p->pose;
      j.child_body = c->body;
      j.child_offset = c->pose;
    } else {  // OpenSim 3.x: <parent_body>, location/orientation_in_parent, location/orientation
      const std::string parent = d_.text(n, "parent_body");
      const Frame* p = resolve_frame(parent, "");
      if (!p) d_.fail(n.child("parent_body"), "unknown parent body '" + parent + "'");
      if (child_hint < 0) d_.fail(n, "joint without a child body");
      j.parent_body = p->body;
      j.parent_offset = compose(p->pose, offset_pose(n, "location_in_parent", "orientation_in_parent"));
      j.child_body = child_hint;
      j.child_offset = offset_pose(n, "location", "orientation");
    }
    if (j.child_body == 0) d_.fail(n, "ground cannot be a joint's child");
    if (m_.bodies[j.child_body].joint >= 0)
      d_.fail(n, "body '" + m_.bodies[j.child_body].name + "' is the child of two joints (closed loops are not supported)");

    // Coordinates: <coordinates> (4.x) or <CoordinateSet><objects> (3.x).
    xml_node coords = n.child("coordinates");
    if (!coords) coords = n.child("CoordinateSet").child("objects");
    std::vector<std::string> names;
    const int joint_index = static_cast<int>(m_.joints.size());
    for (const auto& c : coords.children("Coordinate")) {
      Coordinate co;
      co.name = c.attribute("name").value();
      if (co.name.empty()) d_.fail(c, "Coordinate without a name");
      if (m_.coordinate_index(co.name) >= 0) d_.fail(c, "coordinate name '" + co.name + "' is used twice");
      co.joint = joint_index;
      co.default_value = d_.number(c, "default_value", 0.0);
      if (c.child("range")) {
        const auto r = d_.numbers(c, "range");
        if (r.size() != 2 || r[0] > r[1]) d_.fail(c.child("range"), "expected min max with min <= max");
        co.range_min = r[0];
        co.range_max = r[1];
      }
      co.clamped = d_.boolean(c, "clamped", false);
      co.locked = d_.boolean(c, "locked", false);
      if (c.child("prescribed") && d_.boolean(c, "prescribed", false)) warn(c, "prescribed coordinate motion is ignored");
      const std::string mt = d_.text(c, "motion_type");
      if (mt == "translational") co.motion = Coordinate::Motion::kTranslational;
      names.push_back(co.name);
      j.coordinates.push_back(m_.num_coordinates());
      m_.coordinates.push_back(co);
    }
    auto coord = [&](std::size_t i) {
      if (i >= j.coordinates.size())
        d_.fail(n, j.type + " needs " + std::to_string(i + 1) + " coordinates, found " + std::to_string(j.coordinates.size()));
      return j.coordinates[i];
    };
    const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(), Z = Eigen::Vector3d::UnitZ();
    // Default layout: rotations about X, Y, Z and translations along X, Y, Z, all constant zero.
    for (int s = 0; s < 6; ++s) set_axis(j, s, s % 3 == 0 ? X : (s % 3 == 1 ? Y : Z), -1);
    const std::string& t = j.type;
    if (t == "CustomJoint" && !n.child("SpatialTransform") && n.child("TransformAxisSet")) {
      // Documents before 10901: a TransformAxisSet whose rotations, in file order, become rotation1..
      // and whose translations become translation1.., as OpenSim's CustomJoint converts it.
      int next_rotation = 0, next_translation = 3;
      for (const auto& ax : n.child("TransformAxisSet").child("objects").children("TransformAxis")) {
        const bool rotation = d_.boolean(ax, "is_rotation", false);
        int& next = rotation ? next_rotation : next_translation;
        if (next >= (rotation ? 3 : 6)) d_.fail(ax, "more than three rotation or translation axes");
        read_transform_axis(j, next++, ax, names);
      }
    } else if (t == "CustomJoint") {
      const xml_node st = n.child("SpatialTransform");
      if (!st) d_.fail(n, "CustomJoint without a SpatialTransform");
      static const char* kSlots[6] = {"rotation1", "rotation2", "rotation3", "translation1", "translation2", "translation3"};
      for (const auto& ax : st.children("TransformAxis")) {
        const std::string an = ax.attribute("name").value();
        int slot = -1;
        for (int s = 0; s < 6; ++s)
          if (an == kSlots[s]) slot = s;
        if (slot < 0) d_.fail(ax, "TransformAxis name must be rotation1..3 or translation1..3");
        read_transform_axis(j, slot, ax, names);
      }
    } else if (t == "PinJoint") {
      set_axis(j, 0, Z, coord(0));
      set_axis(j, 2, X, -1);
      set_axis(j, 1, Y, -1);
    } else if (t == "SliderJoint") {
      set_axis(j, 3, X, coord(0));
    } else if (t == "WeldJoint") {
    } else if (t == "BallJoint" || t == "GimbalJoint") {
      for (int s = 0; s < 3; ++s) set_axis(j, s, s == 0 ? X : (s == 1 ? Y : Z), coord(s));
    } else if (t == "FreeJoint") {
      for (int s = 0; s < 6; ++s) set_axis(j, s, s % 3 == 0 ? X : (s % 3 == 1 ? Y : Z), coord(s));
    } else if (t == "UniversalJoint") {
      set_axis(j, 0, X, coord(0));
      set_axis(j, 1, Y, coord(1));
    } else if (t == "PlanarJoint") {
      set_axis(j, 0, Z, coord(0));
      set_axis(j, 1, X, -1);
      set_axis(j, 2, Y, -1);
      set_axis(j, 3, X, coord(1));
      set_axis(j, 4, Y, coord(2));
    } else {
      d_.fail(n, "unsupported joint type");
    }
    // Motion type: rotational if any rotation axis uses the coordinate, unless the file says.
    for (int ci : j.coordinates) {
      bool rot = false, trans = false;
      for (int s = 0; s < 6; ++s)
        if (j.axes[s].coordinate == ci) (s < 3 ? rot : trans) = true;
      auto& co = m_.coordinates[ci];
      if (d_.text(coords.find_child_by_attribute("Coordinate", "name", co.name.c_str()), "motion_type").empty())
        co.motion = rot ? (trans ? Coordinate::Motion::kCoupled : Coordinate::Motion::kRotational)
                        : (trans ? Coordinate::Motion::kTranslational : Coordinate::Motion::kRotational);
      if (!rot && !trans) warn(n, "coordinate '" + co.name + "' moves no axis of its joint");
    }
    m_.bodies[j.child_body].joint = joint_index;
    m_.joints.push_back(std::move(j));
  }

  void read_joints() {
    // OpenSim 4: <JointSet>; OpenSim 3: <joint> inside each child body.
    for (const auto& n : model_node_.child("JointSet").child("objects").children())
      if (n.type() == pugi::node_element) read_joint(n, -1);
    for (const auto& b : model_node_.child("BodySet").child("objects").children("Body")) {
      // 3.x wraps the joint in <Joint>; some 2.x documents spell it <joint>.
      for (const char* wrapper : {"Joint", "joint"})
        for (const auto& n : b.child(wrapper).children()) {
          if (n.type() != pugi::node_element) continue;
          read_joint(n, m_.body_index(b.attribute("name").value()));
        }
    }
    for (std::size_t i = 1; i < m_.bodies.size(); ++i)
      if (m_.bodies[i].joint < 0) throw InputError(d_.name(), 0, m_.bodies[i].name, "body '" + m_.bodies[i].name + "' has no joint connecting it to the model");
  }

  // Reorders joints so that each joint's parent body is placed by an earlier joint.
  void order_joints() {
    std::vector<int> order;
    std::vector<bool> placed(m_.bodies.size(), false);
    placed[0] = true;
    while (order.size() < m_.joints.size()) {
      bool progress = false;
      for (int i = 0; i < static_cast<int>(m_.joints.size()); ++i) {
        const Joint& j = m_.joints[i];
        if (placed[j.child_body] || !placed[j.parent_body]) continue;
        placed[j.child_body] = true;
        order.push_back(i);
        progress = true;
      }
      if (!progress) throw InputError(d_.name(), 0, "JointSet", "joints do not form a tree rooted at ground");
    }
    std::vector<Joint> sorted;
    std::vector<int> new_index(m_.joints.size());
    for (std::size_t k = 0; k < order.size(); ++k) {
      new_index[order[k]] = static_cast<int>(k);
      sorted.push_back(std::move(m_.joints[order[k]]));
    }
    m_.joints = std::move(sorted);
    for (auto& b : m_.bodies)
      if (b.joint >= 0) b.joint = new_index[b.joint];
    for (auto& c : m_.coordinates) c.joint = new_index[c.joint];
  }

  void read_constraints(const xml_node& set) {
    for (const auto& n : set.child("objects").children()) {
      if (n.type() != pugi::node_element) continue;
      if (!is(n, "CoordinateCouplerConstraint")) {
        warn(n, "this kinematic constraint type is not supported; it is ignored");
        continue;
      }
      // 3.x: isDisabled; 4.x: isEnforced.
      if (d_.boolean(n, "isDisabled", false) || !d_.boolean(n, "isEnforced", true)) continue;
      CoordinateCoupler c;
      c.name = n.attribute("name").value();
      const std::string independent = d_.text(n, "independent_coordinate_names");
      const auto names = text::split_ws(independent);
      if (names.size() != 1) d_.fail(n.child("independent_coordinate_names"), "a coupler of exactly one independent coordinate is supported");
      c.independent = m_.coordinate_index(names[0]);
      c.dependent = m_.coordinate_index(d_.text(n, "dependent_coordinate_name"));
      if (c.independent < 0) d_.fail(n.child("independent_coordinate_names"), "unknown coordinate '" + std::string(names[0]) + "'");
      if (c.dependent < 0 || c.dependent == c.independent)
        d_.fail(n.child("dependent_coordinate_name"), "unknown or independent coordinate '" + d_.text(n, "dependent_coordinate_name") + "'");
      xml_node fn;
      for (const auto& f : n.child("coupled_coordinates_function").children())
        if (f.type() == pugi::node_element) {
          fn = f;
          break;
        }
      if (!fn) d_.fail(n, "CoordinateCouplerConstraint without a coupled_coordinates_function");
      c.function = read_function(fn);
      c.scale = d_.number(n, "scale_factor", 1.0);
      for (const auto& other : m_.couplers)
        if (other.dependent == c.dependent || other.dependent == c.independent || other.independent == c.dependent)
          d_.fail(n, "coupler chains and coordinates coupled twice are not supported");
      warn(n, "IK, static optimization, CMC and forward dynamics keep the coupled coordinate on its function (ID, "
              "as OpenSim's, ignores constraints)");
      m_.couplers.push_back(std::move(c));
    }
  }

  // A component's frame: socket_parent_frame (4.x) or <body> (3.x).
  const Frame& frame_of(const xml_node& n) {
    std::string path = d_.text(n, "socket_parent_frame");
    if (path.empty()) path = d_.text(n, "body");
    const Frame* f = resolve_frame(path, "");
    if (!f) d_.fail(n, "unknown frame or body '" + path + "'");
    return *f;
  }

  int coordinate_from_path(const xml_node& n, const char* socket, const char* legacy) {
    std::string path = d_.text(n, socket);
    if (path.empty()) path = d_.text(n, legacy);
    const std::string name = path.substr(path.find_last_of('/') + 1);
    const int c = m_.coordinate_index(name);
    if (c < 0) d_.fail(n, "unknown coordinate '" + path + "'");
    return c;
  }

  void read_markers(const xml_node& set) {
    for (const auto& n : set.child("objects").children()) {
      if (n.type() != pugi::node_element) continue;
      if (!is(n, "Marker")) {
        warn(n, "unsupported marker type; skipped");
        continue;
      }
      Marker mk;
      mk.name = n.attribute("name").value();
      if (mk.name.empty()) d_.fail(n, "Marker without a name");
      const Frame& f = frame_of(n);
      mk.body = f.body;
      mk.location_m = f.pose.rotation * d_.vec3(n, "location", Eigen::Vector3d::Zero()) + f.pose.translation_m;
      mk.fixed = d_.boolean(n, "fixed", false);
      if (int i = m_.marker_index(mk.name); i >= 0) m_.markers[i] = mk;
      else m_.markers.push_back(mk);
    }
  }

  // A muscle's, path spring's or path actuator's GeometryPath: its points and wraps.
  template <typename PathOwner>
  void read_path(const xml_node& muscle, PathOwner& mu) {
    // Documents before 20000 keep the points in the muscle itself: MusclePointSet, MuscleWrapSet.
    const bool legacy = !muscle.child("GeometryPath") && muscle.child("MusclePointSet");
    const xml_node gp = legacy ? muscle : muscle.child("GeometryPath");
    if (!gp) d_.fail(muscle, std::string(muscle.name()) + " without a GeometryPath");
    for (const auto& p : gp.child(legacy ? "MusclePointSet" : "PathPointSet").child("objects").children()) {
      if (p.type() != pugi::node_element) continue;
      PathPoint pp;
      pp.name = p.attribute("name").value();
      const Frame& f = frame_of(p);
      pp.body = f.body;
      // Points are stored in the body frame, so a point on an offset frame is mapped here once.
      auto to_body = [&](const Eigen::Vector3d& v) { return Eigen::Vector3d(f.pose.rotation * v + f.pose.translation_m); };
      pp.location_m = to_body(d_.vec3(p, "location", Eigen::Vector3d::Zero()));
      const std::string kind = p.name();
      if (kind == "PathPoint" || kind == "MusclePoint") {
        pp.kind = PathPoint::Kind::kFixed;
      } else if (kind == "ConditionalPathPoint" || kind == "ConditionalViaPoint" || kind == "MuscleViaPoint") {
        pp.kind = PathPoint::Kind::kConditional;
        pp.coordinate = coordinate_from_path(p, "socket_coordinate", "coordinate");
        const auto r = d_.numbers(p, "range");
        if (r.size() != 2) d_.fail(p, "ConditionalPathPoint needs <range>min max</range>");
        pp.range_min = r[0];
        pp.range_max = r[1];
      } else if (kind == "MovingPathPoint" || kind == "MovingMusclePoint") {
        pp.kind = PathPoint::Kind::kMoving;
        if (!f.pose.rotation.isIdentity() || !f.pose.translation_m.isZero())
          d_.fail(p, "MovingPathPoint on an offset frame is not supported");
        static const char* kLoc[3] = {"x_location", "y_location", "z_location"};
        static const char* kSock[3] = {"socket_x_coordinate", "socket_y_coordinate", "socket_z_coordinate"};
        static const char* kLegacy[3] = {"x_coordinate", "y_coordinate", "z_coordinate"};
        for (int a = 0; a < 3; ++a) {
          const xml_node loc = p.child(kLoc[a]);
          if (!loc || !loc.first_child()) {
            pp.moving_functions[a] = Function::constant(pp.location_m[a]);
            continue;
          }
          pp.moving_functions[a] = read_function(loc.first_child());
          pp.moving_coordinates[a] = coordinate_from_path(p, kSock[a], kLegacy[a]);
        }
      } else {
        warn(p, "unsupported path point type; treated as a fixed point");
      }
      mu.path.push_back(pp);
    }
    if (mu.path.size() < 2) d_.fail(gp, "a muscle path needs at least 2 points");
    for (const auto& w : gp.child(legacy ? "MuscleWrapSet" : "PathWrapSet").child("objects").children()) {
      if (w.type() != pugi::node_element) continue;
      if (!is(w, "PathWrap") && !is(w, "MuscleWrap")) d_.fail(w, "expected <PathWrap>");
      const std::string object = d_.text(w, "wrap_object");
      const int index = m_.wrap_object_index(object);
      if (index < 0) d_.fail(w.child("wrap_object"), "unknown wrap object '" + object + "'");
      PathWrap pw;
      pw.wrap_object = index;
      if (w.child("range")) {
        const auto r = d_.numbers(w, "range");
        if (r.size() != 2) d_.fail(w.child("range"), "expected two path point numbers (1-based, -1 for the ends)");
        pw.start_point = static_cast<int>(r[0]);
        pw.end_point = static_cast<int>(r[1]);
      }
      const std::string method = d_.text(w, "method");
      if (method == "midpoint") pw.method = PathWrap::Method::kMidpoint;
      else if (method == "axial") pw.method = PathWrap::Method::kAxial;
      else if (!method.empty() && method != "hybrid")
        d_.fail(w.child("method"), "method must be hybrid, midpoint or axial");
      mu.wraps.push_back(pw);
    }
  }

  void read_forces() {
    for (const auto& n : model_node_.child("ForceSet").child("objects").children()) {
      if (n.type() != pugi::node_element) continue;
      const std::string type = n.name();
      // The model's actuators reach SO, CMC and the Forward tool through the actuator set reader
      // (capture/actuator_set.h), which reads them from the same ForceSet (a PathActuator's path is read below).
      if (type == "CoordinateActuator" || type == "PointActuator" || type == "TorqueActuator") continue;
      if (type == "CoordinateLimitForce") {
        read_coordinate_limit_force(n);
        continue;
      }
      if (type == "PathSpring") {
        read_path_spring(n);
        continue;
      }
      if (type == "PathActuator") {
        // Its path here; its optimal force and control range with the other actuators.
        PathActuator pa;
        pa.name = n.attribute("name").value();
        read_path(n, pa);
        if (applies_force(n)) m_.path_actuators.push_back(std::move(pa));
        continue;
      }
      if (type == "ExpressionBasedCoordinateForce") {
        read_expression_based_coordinate_force(n);
        continue;
      }
      if (type == "SpringGeneralizedForce") {
        read_spring_generalized_force(n);
        continue;
      }
      const bool schutte = type == "Schutte1993Muscle" || type == "Schutte1993Muscle_Deprecated";
      if (type != "Thelen2003Muscle" && type != "Millard2012EquilibriumMuscle" && !schutte && type != "RigidTendonMuscle" &&
          type != "DeGrooteFregly2016Muscle") {
        warn(n, "force type not supported yet; ignored");
        continue;
      }
      Muscle mu;
      mu.name = n.attribute("name").value();
      mu.type = type;
      mu.max_isometric_force_N = d_.number(n, "max_isometric_force", 0.0, true);
      mu.optimal_fiber_length_m = d_.number(n, "optimal_fiber_length", 0.0, true);
      mu.tendon_slack_length_m = d_.number(n, "tendon_slack_length", 0.0, true);
      // 1.x names: pennation_angle, Vmax.
      mu.pennation_angle_at_optimal_rad = d_.number(n, n.child("pennation_angle_at_optimal") ? "pennation_angle_at_optimal" : "pennation_angle", 0.0);
      mu.sin_pennation_at_optimal = std::sin(mu.pennation_angle_at_optimal_rad);
      mu.max_contraction_velocity = d_.number(n, n.child("max_contraction_velocity") ? "max_contraction_velocity" : "Vmax", 10.0);
      if (mu.max_isometric_force_N <= 0 || mu.optimal_fiber_length_m <= 0 || mu.tendon_slack_length_m < 0)
        d_.fail(n, "max_isometric_force and optimal_fiber_length must be positive");
      if (type == "Thelen2003Muscle") {
        mu.activation_time_constant_s = d_.number(n, "activation_time_constant", 0.015);
        mu.deactivation_time_constant_s = d_.number(n, "deactivation_time_constant", 0.05);
        mu.fmax_tendon_strain = d_.number(n, "FmaxTendonStrain", 0.04);
        mu.fmax_muscle_strain = d_.number(n, "FmaxMuscleStrain", 0.6);
        mu.kshape_active = d_.number(n, "KshapeActive", 0.45);
        mu.kshape_passive = d_.number(n, "KshapePassive", 5.0);
        mu.af = d_.number(n, "Af", 0.25);
        mu.flen = d_.number(n, "Flen", 1.4);
      } else if (schutte) {
        read_schutte(n, mu);
      } else if (type == "RigidTendonMuscle") {
        rigid_tendon_muscle::Curves c = rigid_tendon_muscle::default_curves();
        function_property(n, "active_force_length_curve", c.active_force_length);
        function_property(n, "passive_force_length_curve", c.passive_force_length);
        function_property(n, "force_velocity_curve", c.force_velocity);
        mu.rigid_tendon = std::make_shared<const rigid_tendon_muscle::Curves>(std::move(c));
      } else if (type == "DeGrooteFregly2016Muscle") {
        read_degroote(n, mu);
      } else {
        read_millard(n, mu);
      }
      mu.min_control = d_.number(n, "min_control", mu.min_control);
      mu.max_control = d_.number(n, "max_control", mu.max_control);
      read_path(n, mu);
      m_.muscles.push_back(std::move(mu));
    }
  }

  // A property holding a function (its one element child) into f; false when the document has none.
  bool function_property(const xml_node& n, const char* name, Function& f) {
    for (const auto& e : n.child(name).children())
      if (e.type() == pugi::node_element) {
        f = read_function(e);
        return true;
      }
    return false;
  }

  // Schutte1993Muscle's curves, each a function inside its property (OpenSim's defaults where absent;
  // without a passive curve OpenSim uses its exponential).
  void read_schutte(const xml_node& n, Muscle& mu) {
    schutte1993::Curves c = schutte1993::default_curves();
    function_property(n, "tendon_force_length_curve", c.tendon_force_length);
    function_property(n, "active_force_length_curve", c.active_force_length);
    c.exponential_passive = !function_property(n, "passive_force_length_curve", c.passive_force_length);
    c.damping = d_.number(n, "damping", c.damping);
    c.time_scale_s = d_.number(n, "time_scale", c.time_scale_s);
    c.activation1 = d_.number(n, "activation1", c.activation1);
    c.activation2 = d_.number(n, "activation2", c.activation2);
    if (!(c.time_scale_s > 0))
      throw InputError(d_.name(), d_.line_of(n.child("time_scale") ? n.child("time_scale") : n), "time_scale",
                       "muscle " + mu.name + ": time_scale must be positive");
    mu.schutte = std::make_shared<const schutte1993::Curves>(std::move(c));
  }

  // DeGrooteFregly2016Muscle's properties, with OpenSim's defaults (its activation time constants
  // differ from the other muscles': 0.015 and 0.060 s).
  void read_degroote(const xml_node& n, Muscle& mu) {
    degroote_fregly2016::Parameters p;
    mu.activation_time_constant_s = d_.number(n, "activation_time_constant", 0.015);
    mu.deactivation_time_constant_s = d_.number(n, "deactivation_time_constant", 0.060);
    read_numbers(n, {{"active_force_width_scale", &p.active_force_width_scale},
                     {"fiber_damping", &p.fiber_damping},
                     {"passive_fiber_strain_at_one_norm_force", &p.passive_fiber_strain_at_one_norm_force},
                     {"tendon_strain_at_one_norm_force", &p.tendon_strain_at_one_norm_force}});
    p.ignore_passive_fiber_force = d_.boolean(n, "ignore_passive_fiber_force", false);
    p.ignore_tendon_compliance = d_.boolean(n, "ignore_tendon_compliance", false);
    if (p.active_force_width_scale < 1) d_.fail(n.child("active_force_width_scale"), "active_force_width_scale must be at least 1");
    if (p.fiber_damping < 0) d_.fail(n.child("fiber_damping"), "fiber_damping must not be negative");
    if (p.passive_fiber_strain_at_one_norm_force <= 0)
      d_.fail(n.child("passive_fiber_strain_at_one_norm_force"), "passive_fiber_strain_at_one_norm_force must be positive");
    if (p.tendon_strain_at_one_norm_force <= 0)
      d_.fail(n.child("tendon_strain_at_one_norm_force"), "tendon_strain_at_one_norm_force must be positive");
    mu.degroote = std::make_shared<const degroote_fregly2016::Parameters>(p);
  }

  void read_path_spring(const xml_node& n) {
    PathSpring ps;
    ps.name = n.attribute("name").value();
    ps.resting_length_m = d_.number(n, "resting_length", 0.0, true);
    ps.stiffness_N_per_m = d_.number(n, "stiffness", 0.0, true);
    ps.dissipation_s_per_m = d_.number(n, "dissipation", 0.0, true);
    // As OpenSim (PathSpring::extendFinalizeFromProperties): none may be negative.
    for (const auto& [field, value] : {std::pair<const char*, double>{"resting_length", ps.resting_length_m},
                                       {"stiffness", ps.stiffness_N_per_m}, {"dissipation", ps.dissipation_s_per_m}})
      if (!(value >= 0)) d_.fail(n.child(field), std::string("a PathSpring's ") + field + " cannot be negative");
    read_path(n, ps);
    if (applies_force(n)) m_.path_springs.push_back(std::move(ps));
  }

  void read_spring_generalized_force(const xml_node& n) {
    SpringGeneralizedForce f;
    f.name = n.attribute("name").value();
    f.coordinate = force_coordinate(n);
    read_numbers(n, {{"stiffness", &f.stiffness}, {"rest_length", &f.rest_length}, {"viscosity", &f.viscosity}});
    if (applies_force(n)) m_.spring_generalized_forces.push_back(f);
  }

  void read_expression_based_coordinate_force(const xml_node& n) {
    ExpressionBasedCoordinateForce f;
    f.name = n.attribute("name").value();
    f.coordinate = force_coordinate(n);
    const std::string text = n.child("expression") ? d_.text(n, "expression") : "0.0";  // OpenSim's default
    try {
      f.expression = std::make_shared<const Expression>(text, std::vector<std::string>{"q", "qdot"});
    } catch (const ExpressionError& e) {
      d_.fail(n.child("expression"), std::string("expression '") + text + "': " + e.what());
    }
    if (applies_force(n)) m_.expression_based_coordinate_forces.push_back(std::move(f));
  }

  // The coordinate a coordinate force names in its <coordinate>; an unknown one names the force.
  int force_coordinate(const xml_node& n) {
    const std::string coord = d_.text(n, "coordinate");
    const int c = m_.coordinate_index(coord);
    if (c < 0)
      d_.fail(n.child("coordinate") ? n.child("coordinate") : n,
              std::string(n.name()) + " '" + n.attribute("name").value() + "': unknown coordinate '" + coord + "'");
    return c;
  }

  // A force's isDisabled (3.x) or appliesForce (4.x) switch.
  bool applies_force(const xml_node& n) const { return !d_.boolean(n, "isDisabled", false) && d_.boolean(n, "appliesForce", true); }

  // Stiffness per degree and limits in degrees for rotational coordinates, converted to SI here.
  void read_coordinate_limit_force(const xml_node& n) {
    CoordinateLimitForce f;
    f.name = n.attribute("name").value();
    f.coordinate = force_coordinate(n);
    const double w = m_.coordinates[f.coordinate].is_angle() ? M_PI / 180.0 : 1.0;
    f.upper_limit = w * d_.number(n, "upper_limit", 0.0, true);
    f.lower_limit = w * d_.number(n, "lower_limit", 0.0, true);
    f.upper_stiffness = d_.number(n, "upper_stiffness", 0.0, true) / w;
    f.lower_stiffness = d_.number(n, "lower_stiffness", 0.0, true) / w;
    f.damping = d_.number(n, "damping", 0.0) / w;
    f.transition = w * d_.number(n, "transition", 0.0, true);
    if (f.transition <= 0) d_.fail(n.child("transition"), "CoordinateLimitForce '" + f.name + "': transition must be positive");
    if (f.upper_stiffness < 0 || f.lower_stiffness < 0 || f.damping < 0)
      d_.fail(n, "CoordinateLimitForce '" + f.name + "': stiffnesses and damping must not be negative");
    if (f.lower_limit > f.upper_limit) d_.fail(n.child("lower_limit"), "CoordinateLimitForce '" + f.name + "': lower_limit is above upper_limit");
    if (applies_force(n)) m_.coordinate_limit_forces.push_back(f);
  }

  // Each named child's number into its field; an absent or empty one leaves the field's default.
  void read_numbers(const xml_node& parent, std::initializer_list<std::pair<const char*, double*>> fields) {
    for (const auto& [name, field] : fields) *field = d_.number(parent, name, *field);
  }

  std::optional<double> optional_number(const xml_node& parent, const char* child) {
    const xml_node c = parent.child(child);
    if (!c || d_.numbers_of(c).empty()) return std::nullopt;  // OpenSim's empty optional property
    return d_.number(parent, child, 0.0);
  }

  // Millard2012EquilibriumMuscle's properties and curves; 3.x documents keep the activation time
  // constants in a MuscleFirstOrderActivationDynamicModel child.
  void read_millard(const xml_node& n, Muscle& mu) {
    const xml_node act = n.child("MuscleFirstOrderActivationDynamicModel");
    mu.activation_time_constant_s = d_.number(act ? act : n, "activation_time_constant", 0.01);
    mu.deactivation_time_constant_s = d_.number(act ? act : n, "deactivation_time_constant", 0.04);
    millard2012::Parameters p;
    p.fiber_damping = d_.number(n, "fiber_damping", p.fiber_damping);
    p.minimum_activation = d_.number(act ? act : n, "minimum_activation", p.minimum_activation);
    const xml_node pen = n.child("MuscleFixedWidthPennationModel");
    p.maximum_pennation_angle_rad = d_.number(pen ? pen : n, "maximum_pennation_angle", p.maximum_pennation_angle_rad);
    p.ignore_tendon_compliance = d_.boolean(n, "ignore_tendon_compliance", false);
    mu.min_control = p.minimum_activation;  // OpenSim's default; the document's min_control, read next, wins
    auto& a = p.active_force_length;
    read_numbers(n.child("ActiveForceLengthCurve"), {{"min_norm_active_fiber_length", &a.min_norm_active_fiber_length},
                                                     {"transition_norm_fiber_length", &a.transition_norm_fiber_length},
                                                     {"max_norm_active_fiber_length", &a.max_norm_active_fiber_length},
                                                     {"shallow_ascending_slope", &a.shallow_ascending_slope},
                                                     {"minimum_value", &a.minimum_value}});
    auto& v = p.force_velocity;
    read_numbers(n.child("ForceVelocityCurve"), {{"concentric_slope_at_vmax", &v.concentric_slope_at_vmax},
                                                 {"concentric_slope_near_vmax", &v.concentric_slope_near_vmax},
                                                 {"isometric_slope", &v.isometric_slope},
                                                 {"eccentric_slope_at_vmax", &v.eccentric_slope_at_vmax},
                                                 {"eccentric_slope_near_vmax", &v.eccentric_slope_near_vmax},
                                                 {"max_eccentric_velocity_force_multiplier", &v.max_eccentric_velocity_force_multiplier},
                                                 {"concentric_curviness", &v.concentric_curviness},
                                                 {"eccentric_curviness", &v.eccentric_curviness}});
    const xml_node fpe = n.child("FiberForceLengthCurve");
    auto& f = p.fiber_force_length;
    f.strain_at_zero_force = d_.number(fpe, "strain_at_zero_force", f.strain_at_zero_force);
    f.strain_at_one_norm_force = d_.number(fpe, "strain_at_one_norm_force", f.strain_at_one_norm_force);
    f.stiffness_at_low_force = optional_number(fpe, "stiffness_at_low_force");
    f.stiffness_at_one_norm_force = optional_number(fpe, "stiffness_at_one_norm_force");
    f.curviness = optional_number(fpe, "curviness");
    const xml_node fse = n.child("TendonForceLengthCurve");
    auto& t = p.tendon_force_length;
    t.strain_at_one_norm_force = d_.number(fse, "strain_at_one_norm_force", t.strain_at_one_norm_force);
    t.stiffness_at_one_norm_force = optional_number(fse, "stiffness_at_one_norm_force");
    t.norm_force_at_toe_end = optional_number(fse, "norm_force_at_toe_end");
    t.curviness = optional_number(fse, "curviness");
    try {
      // Muscles with the same parameters share their curves (and their lookup tables' cache lines).
      for (const auto& [q, curves] : millard_curves_)
        if (q == p) mu.millard = curves;
      if (!mu.millard) {
        mu.millard = std::make_shared<const millard2012::Curves>(millard2012::make_curves(p));
        millard_curves_.emplace_back(p, mu.millard);
      }
    } catch (const std::invalid_argument& e) {
      d_.fail(n, std::string("muscle '") + mu.name + "': " + e.what());
    }
  }

  void read_marker_set_file(const std::string& path) {
    const auto md = xml::Document::load_file(path);
    xml_node set = md.doc().document_element();
    if (is(set, "OpenSimDocument")) set = set.child("MarkerSet");
    if (!set || !is(set, "MarkerSet")) throw InputError(path, 1, "MarkerSet", "not a marker set: no <MarkerSet>");
    // Markers in the separate file are read with that file's line numbers.
    Reader sub(md, options_, r_);
    sub.frames_ = frames_;
    sub.read_markers(set);
  }
};

}  // namespace

OsimReadResult parse_osim(std::string content, const std::string& name, const OsimReadOptions& options) {
  if (content.size() > options.max_bytes)
    throw InputError(name, 0, "", "model is over the limit of " + std::to_string(options.max_bytes) + " bytes");
  const auto d = xml::Document::load_string(std::move(content), name);
  OsimReadResult r;
  Reader(d, options, r).read();
  return r;
}

OsimReadResult read_osim(const std::string& path, const OsimReadOptions& options) {
  return parse_osim(text::read_file(path, options.max_bytes), path, options);
}

}  // namespace cpgait
