#pragma once
// What the dashboard's 3-D view needs for a finished IK: per frame, every body's pose and centre of
// mass, the model's markers and the measured ones, and the ground reaction forces. Computed on the
// server because the browser has no model.
#include <nlohmann/json.hpp>
#include <string>

namespace cpgait::services {

// model/marker set: the trial's model; ik_mot: the IK result file; markers_trc: the uploaded TRC;
// grf/loads: the uploaded loads (empty when none). Positions in metres in ground, rotations as
// quaternions (x, y, z, w).
nlohmann::json trial_kinematics_json(const std::string& model_path, const std::string& marker_set_path,
                                     const std::string& ik_mot_path, const std::string& markers_trc,
                                     const std::string& grf_mot, const std::string& loads_xml);

}  // namespace cpgait::services
