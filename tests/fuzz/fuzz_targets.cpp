#include "fuzz/fuzz_targets.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>

#include <nlohmann/json.hpp>

#include "c3d_writer.h"
#include "cpgait/capture/actuator_set.h"
#include "cpgait/capture/analyze_setup.h"
#include "cpgait/capture/c3d.h"
#include "cpgait/capture/cmc_setup.h"
#include "cpgait/capture/external_loads.h"
#include "cpgait/capture/ground_reactions.h"
#include "cpgait/capture/id_setup.h"
#include "cpgait/capture/ik_setup.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/marker_file.h"
#include "cpgait/capture/scale_setup.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/trc.h"
#include "cpgait/capture/json_input.h"
#include "cpgait/cpg/cpg_fit.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/dynamics/passive_generalized_forces.h"
#include "cpgait/kinematics/motion_subspace.h"
#include "cpgait/muscles/muscle_path.h"
#include "cpgait/fixtures/synthetic_trial.h"
#include "cpgait/fixtures/tag_footage.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/video/calibration_board.h"
#include "cpgait/video/camera.h"
#include "cpgait/video/tag_set.h"
#include "mesh_files.h"
#include "zip_archive.h"
#include "zip_writer.h"
#include "pipeline.h"
#include "server.h"

namespace cpgait::testing {
namespace {

namespace fs = std::filesystem;

const Model& walker() {
  static const Model m = read_osim(std::string(fixtures::fixtures_dir()) + "/models/walker.osim").model;
  return m;
}

// A folder of this process's own for the readers that take a path, removed at exit.
const fs::path& scratch_dir() {
  struct Scratch {
    fs::path dir;
    Scratch() {
      const fs::path base = fs::is_directory("/dev/shm") ? fs::path("/dev/shm") : fs::temp_directory_path();
      dir = base / ("cpgait-fuzz-" + std::to_string(::getpid()));
      fs::create_directories(dir);
    }
    ~Scratch() {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  };
  static const Scratch scratch;
  return scratch.dir;
}

// Every setup and ForceSet reader on the same bytes: each refuses what is not its kind.
void read_setup_xml(std::string_view bytes) {
  const std::string path = (scratch_dir() / "setup.xml").string();
  {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  auto each = [](auto&& read) {
    try {
      read();
    } catch (const InputError&) {
    }
  };
  each([&] { read_ik_setup(path); });
  each([&] { read_ik_tasks(path); });
  each([&] { read_id_setup(path); });
  each([&] { read_analyze_setup(path); });
  each([&] { read_cmc_setup(path); });
  each([&] { read_cmc_tasks(path); });
  each([&] {
    // Its bounds are evaluated as CMC evaluates them, at and around the nodes.
    const ControlSetSpec set = read_control_set(path);
    for (const ControlBounds& b : set.controls)
      for (const std::vector<double>* times : {&b.min_node_times_s, &b.max_node_times_s})
        for (double t : *times)
          for (double at : {t - 0.5, t, t + 1e-3}) (void)(b.min_at(at) + b.max_at(at));
  });
  each([&] { read_forward_setup(path); });
  each([&] { read_actuators(path); });
}

// The service in-process on a scratch data folder, no workers. The input's first line is the path
// posted to (/api/v1/trials or /api/v1/models), the rest the multipart body.
void post_upload(std::string_view bytes) {
  static services::InProcessServer server([] {
    services::ServerOptions o;
    o.data_dir = (scratch_dir() / "data").string();
    o.workers = 0;
    return o;
  }());
  const std::size_t eol = bytes.find('\n');
  std::string path(bytes.substr(0, eol));
  const std::string_view body = eol == std::string_view::npos ? std::string_view() : bytes.substr(eol + 1);
  if (path.empty() || path.find_first_of(" \r") != std::string::npos) path = "/api/v1/trials";
  const std::string request = "POST " + path + " HTTP/1.1\r\nHost: fuzz\r\nContent-Type: multipart/form-data; boundary=" +
                              "cpgaitfuzz\r\nContent-Length: " + std::to_string(body.size()) + "\r\n\r\n" + std::string(body);
  const std::string response = server.handle(request);
  const int status = response.size() > 12 && response.rfind("HTTP/1.1 ", 0) == 0 ? std::atoi(response.c_str() + 9) : 0;
  const std::size_t head_end = response.find("\r\n\r\n");
  const nlohmann::json reply =
      head_end == std::string::npos ? nlohmann::json() : nlohmann::json::parse(response.substr(head_end + 4), nullptr, false);
  if (status < 200 || status >= 500 || reply.is_discarded()) {
    std::fprintf(stderr, "upload answered %d: %s\n", status, response.substr(0, 600).c_str());
    std::abort();
  }
  // What was accepted is deleted again, so the scratch folder stays small.
  if (status == 202) server.handle("DELETE /api/v1/trials/" + reply.value("id", std::string()) + " HTTP/1.1\r\nHost: fuzz\r\n\r\n");
  if (status == 201) fs::remove_all(scratch_dir() / "data" / "models" / reply.value("id", std::string("-")));
}

std::string multipart(const std::string& path, const std::vector<std::pair<std::string, std::pair<std::string, std::string>>>& parts) {
  std::string body = path + "\n";
  for (const auto& [name, file] : parts)
    body += "--cpgaitfuzz\r\nContent-Disposition: form-data; name=\"" + name + "\"; filename=\"" + file.first + "\"\r\n\r\n" +
            file.second + "\r\n";
  return body + "--cpgaitfuzz--\r\n";
}

}  // namespace

const std::vector<std::string>& fuzz_target_names() {
  static const std::vector<std::string> names = {"trc",         "storage",     "c3d",           "osim",         "external_loads",
                                                 "ik_tasks_json", "scale_setup", "setup_xml",   "video_json",   "contact_set_json",
                                                 "cpg_model_json", "pipeline_options", "upload", "mesh", "zip"};
  return names;
}

void fuzz_one(std::string_view target, std::string_view bytes) {
  try {
    if (target == "trc") {
      parse_trc(bytes, "fuzz.trc");
    } else if (target == "storage") {
      parse_storage(bytes, "fuzz.sto");
    } else if (target == "c3d") {
      const C3dFile f = parse_c3d(bytes, "fuzz.c3d");
      ground_reactions(f, c3d_to_opensim(f, C3dVertical::kAuto));
    } else if (target == "osim") {
      // Read, then evaluated at its default pose as every stage evaluates it: paths (wraps
      // included) and passive forces (expressions included).
      const Model m = parse_osim(std::string(bytes), "fuzz.osim").model;
      Eigen::VectorXd q(m.num_coordinates()), qd = Eigen::VectorXd::Zero(m.num_coordinates()), tau = qd;
      for (int c = 0; c < m.num_coordinates(); ++c) q[c] = m.coordinates[c].default_value;
      KinematicsWorkspace<double> ws(m);
      MotionSubspace S(m);
      MusclePathGeometry g(m);
      forward_kinematics(m, q.data(), ws);
      motion_subspace(m, q.data(), ws, S);
      muscle_path_geometry(m, q.data(), qd.data(), ws, S, g);
      add_passive_generalized_forces(m, q.data(), qd.data(), ws, S, tau.data());
    } else if (target == "external_loads") {
      parse_external_loads(std::string(bytes), "fuzz.xml");
    } else if (target == "ik_tasks_json") {
      parse_ik_tasks_json(std::string(bytes), "fuzz.json");
    } else if (target == "scale_setup") {
      parse_scale_setup(std::string(bytes), "fuzz.xml");
    } else if (target == "setup_xml") {
      read_setup_xml(bytes);
    } else if (target == "video_json") {
      const std::string text(bytes);
      for (auto* read : {+[](const std::string& t) { video::parse_calibration_json(t, "fuzz.json"); },
                         +[](const std::string& t) { video::parse_tag_set_json(t, "fuzz.json"); },
                         +[](const std::string& t) { video::parse_aprilgrid_spec(t, "fuzz.json"); }}) {
        try {
          read(text);
        } catch (const InputError&) {
        }
      }
    } else if (target == "contact_set_json") {
      parse_contact_set_json(std::string(bytes), "fuzz.json", walker());
    } else if (target == "cpg_model_json") {
      const std::string text(bytes);
      CpgModel::from_json(parse_json_input(text, "fuzz.json"), "fuzz.json");
    } else if (target == "pipeline_options") {
      services::PipelineOptions::parse(std::string(bytes), "fuzz.json");
    } else if (target == "upload") {
      post_upload(bytes);
    } else if (target == "mesh") {
      // The same bytes as each kind of mesh file a model may name.
      const std::string content(bytes);
      for (const char* name : {"fuzz.vtp", "fuzz.stl", "fuzz.obj"}) {
        try {
          services::parse_mesh(content, name);
        } catch (const InputError&) {
        }
      }
    } else if (target == "zip") {
      services::ZipReadOptions o;
      o.max_total_bytes = std::size_t{1} << 24;  // a bomb stops here rather than exhausting the fuzzer
      services::read_zip(bytes, "fuzz.zip", o);
    } else {
      std::fprintf(stderr, "no fuzz target '%.*s'\n", static_cast<int>(target.size()), target.data());
      std::abort();
    }
  } catch (const InputError&) {
  }
}

std::map<std::string, std::vector<std::string>> fuzz_made_inputs() {
  const MarkerTrial trial = fixtures::synthesize_trial(walker(), {}).markers;
  const std::string trc = format_trc(trial, "mm");
  fixtures::SyntheticTrialOptions short_trial;  // uploads are fuzzed faster with a short trial
  short_trial.duration_s = 0.2;
  const std::string short_trc = format_trc(fixtures::synthesize_trial(walker(), short_trial).markers, "mm");
  const std::string walker_osim = text::read_file(std::string(fixtures::fixtures_dir()) + "/models/walker.osim");
  // A model zipped with a mesh (one deflated, one stored with a data descriptor) and a resource fork.
  const std::string zipped_walker = write_zip({{"walker/walker.osim", walker_osim, true, false},
                                               {"walker/Geometry/bone.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", false, true},
                                               {"__MACOSX/walker/._walker.osim", "fork", false, false}});
  // The walker with the forces and wraps only the fuzzed reader's newer branches read.
  std::string walker_forces = walker_osim;
  walker_forces.insert(walker_forces.find("<objects>", walker_forces.find("<ForceSet")) + 9,
                       "<ExpressionBasedCoordinateForce name=\"e\"><coordinate>knee_angle_r</coordinate>"
                       "<expression>-k*(q-0.2)-2*max(qdot,0)^2; k=40</expression></ExpressionBasedCoordinateForce>"
                       "<PathActuator name=\"p\"><GeometryPath><PathPointSet><objects><PathPoint name=\"a\"><socket_parent_frame>/bodyset/femur_r</socket_parent_frame>"
                       "<location>0 0 0</location></PathPoint><PathPoint name=\"b\"><socket_parent_frame>/bodyset/tibia_r</socket_parent_frame><location>0 -0.1 0</location>"
                       "</PathPoint></objects></PathPointSet><PathWrapSet><objects><PathWrap><wrap_object>ring</wrap_object></PathWrap></objects>"
                       "</PathWrapSet></GeometryPath><optimal_force>10</optimal_force></PathActuator>");
  walker_forces.insert(walker_forces.find("</Body>"),  // the first body's: femur_r
                       "<WrapObjectSet><objects><WrapTorus name=\"ring\"><translation>0 -0.3 0</translation><inner_radius>0.01"
                       "</inner_radius><outer_radius>0.05</outer_radius><quadrant>-x</quadrant></WrapTorus></objects></WrapObjectSet>");
  const std::string contact = R"({"ground_height_m": 0, "defaults": {"radius_m": 0.03, "stiffness": 2e6},
    "spheres": [{"name": "heel_r", "body": "foot_r", "location_m": [0, -0.02, 0]}, {"body": "foot_l", "location_m": [0.1, -0.02, 0]}]})";
  return {
      {"trc", {trc, "PathFileType\t4\n"}},
      {"storage", {"x\nversion=1\nnRows=1\nnColumns=2\nendheader\ntime\ta\n0\t1\n", "endheader\n"}},
      {"c3d", {format_c3d_z_up(trial), std::string(512, '\0')}},
      {"osim", {walker_osim, walker_forces, "<Model>"}},
      {"external_loads", {"<ExternalLoads><objects><ExternalForce/></objects></ExternalLoads>"}},
      {"ik_tasks_json", {R"({"markers": {"R.ASIS": 2}})", "{"}},
      {"scale_setup", {"<OpenSimDocument><ScaleTool><mass>-5</mass></ScaleTool></OpenSimDocument>"}},
      {"setup_xml",
       {"<OpenSimDocument Version=\"30000\"><InverseKinematicsTool><marker_file>m.trc</marker_file><IKTaskSet><objects>"
        "<IKMarkerTask name=\"A\"><weight>2</weight></IKMarkerTask></objects></IKTaskSet></InverseKinematicsTool></OpenSimDocument>",
        "<OpenSimDocument><ForceSet><objects><CoordinateActuator name=\"r\"><coordinate>hip</coordinate>"
        "<optimal_force>100</optimal_force></CoordinateActuator></objects></ForceSet></OpenSimDocument>",
        "<CMCTool><desired_kinematics_file>q.mot</desired_kinematics_file><task_set_file>t.xml</task_set_file></CMCTool>",
        "<OpenSimDocument Version=\"30000\"><ControlSet><objects><ControlLinear name=\"a.excitation\"><use_steps>false</use_steps>"
        "<min_nodes><ControlLinearNode><t>0.5</t><value>0</value></ControlLinearNode><ControlLinearNode><t>0.6</t><value>2</value>"
        "</ControlLinearNode></min_nodes><max_nodes><ControlLinearNode><t>0.5</t><value>1</value></ControlLinearNode></max_nodes>"
        "</ControlLinear></objects></ControlSet></OpenSimDocument>"}},
      {"video_json",
       {video::format_calibration_json(fixtures::lab_rig()), video::format_tag_set_json(fixtures::tagged_walker().tags),
        video::format_aprilgrid_spec(video::AprilGridSpec{})}},
      {"contact_set_json", {contact, R"({"spheres": [7]})"}},
      {"cpg_model_json",  // the seed method's two-neuron example driving two muscles
       {R"({"network": {"s": [5, 5], "tau_r_s": [1, 1], "tau_a_s": [10, 10], "b": [2.5, 2.5], "a": [[0, 1.5], [1.5, 0]]},
            "start": {"x": [0.1, 0], "f": [0, 0]}, "cycle_s": 1.1, "muscles": ["soleus_r", "tib_ant_r"],
            "output_map": [[1, 0], [0, 1]], "output_bias": [0, 0], "feedback": {"signals": []}})",
        R"({"network": {"s": [1]}})"}},
      {"mesh",
       {"<?xml version=\"1.0\"?><VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\"><PolyData><Piece NumberOfPoints=\"3\" "
        "NumberOfPolys=\"1\"><Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 0 0 0 1 0</DataArray></Points>"
        "<Polys><DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 2</DataArray><DataArray type=\"Int32\" Name=\"offsets\" "
        "format=\"ascii\">3</DataArray></Polys></Piece></PolyData></VTKFile>",
        // The same triangle in binary (base64 of a 4-byte count and the floats), and compressed-header garbage.
        "<VTKFile type=\"PolyData\" byte_order=\"LittleEndian\"><PolyData><Piece><Points><DataArray type=\"Float32\" format=\"binary\">"
        "JAAAAAAAAAAAAAAAAAAAAAAAgD8AAAAAAAAAAAAAAAAAAIA/AAAAAA==</DataArray></Points><Polys><DataArray type=\"Int32\" Name=\"connectivity\" "
        "format=\"ascii\">0 1 2</DataArray><DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">3</DataArray></Polys></Piece></PolyData></VTKFile>",
        "<VTKFile type=\"PolyData\" compressor=\"vtkZLibDataCompressor\"><PolyData><Piece><Points><DataArray type=\"Float32\" format=\"binary\">"
        "AQAAAACAAAAkAAAAEAAAAA==eJxjYGBgAGEMDAABAAE=</DataArray></Points></Piece></PolyData></VTKFile>",
        // Raw appended data: a byte count of 36 and nine floats after the '_', NULs and all.
        "<VTKFile type=\"PolyData\"><PolyData><Piece><Points><DataArray type=\"Float32\" format=\"appended\" offset=\"0\"/></Points>"
        "</Piece></PolyData><AppendedData encoding=\"raw\">_" + std::string("\x24\0\0\0", 4) + std::string(12, '\0') +
            std::string("\0\0\x80\x3f\0\0\0\0\0\0\0\0\0\0\0\0\0\0\x80\x3f\0\0\0\0", 24) + "</AppendedData></VTKFile>",
        "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1/1/1 2//1 3 -1\n"}},
      {"zip",
       {zipped_walker, write_zip({{"a\\b.txt", "stored", false, false}}, "comment"), write_zip({}),
        write_zip({{"big.txt", std::string(100000, 'z'), true, false}})}},
      {"pipeline_options",
       {R"({"model": "walker", "stages": ["ik", "id"], "time_range": [0.1, 1.2], "ik": {"accuracy": 1e-5}})", "[]", "{\"stages\": 3}"}},
      {"upload",
       {multipart("/api/v1/trials", {{"markers", {"walk.trc", short_trc}}, {"options", {"options.json", R"({"model": "walker"})"}}}),
        multipart("/api/v1/trials", {{"markers", {"walk.trc", short_trc}}, {"options", {"options.json", R"({"model": "walker", "stages": ["ik"]})"}},
                                     {"grf", {"grf.mot", "endheader\ntime\tx\n0\t1\n"}}, {"loads", {"loads.xml", "<ExternalLoads/>"}}}),
        multipart("/api/v1/trials", {{"static", {"static.trc", short_trc}}, {"markers", {"walk.trc", short_trc}},
                                     {"options", {"options.json", R"({"model": "walker"})"}}}),
        multipart("/api/v1/models", {{"model", {"walker.osim", walker_osim}}}),
        multipart("/api/v1/models", {{"model", {"walker.osim", walker_osim}}, {"geometry", {"bone.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"}}}),
        multipart("/api/v1/models", {{"model", {"walker.zip", zipped_walker}}}),
        "/api/v1/trials\n--cpgaitfuzz--\r\n"}}};
}

}  // namespace cpgait::testing
