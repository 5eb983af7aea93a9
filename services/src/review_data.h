#pragma once
// What the dashboard's 3-D view needs for a finished IK: per frame, every body's pose and centre of
// mass, the model's markers and the measured ones, and the ground reaction forces. Computed on the
// server because the browser has no model.
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cpgait/capture/storage.h"

namespace cpgait::services {

// model/marker set: the trial's model; ik_mot: the IK result file; markers_trc: the uploaded TRC;
// grf/loads: the uploaded loads (empty when none). Positions in metres in ground, rotations as
// quaternions (x, y, z, w).
// The same over a motion already read (the reproduced gait's, sampled at the trial's frames).
nlohmann::json trial_kinematics_json(const std::string& model_path, const std::string& marker_set_path, const Storage& motion,
                                     const std::string& markers_trc, const std::string& grf_mot, const std::string& loads_xml);

// The rows of `motion` nearest to times_s - offset_s (those inside its span), timed at times_s: a
// simulation that starts at 0 laid on the trial's frames.
Storage motion_at_times(const Storage& motion, const std::vector<double>& times_s, double offset_s);

nlohmann::json trial_kinematics_json(const std::string& model_path, const std::string& marker_set_path,
                                     const std::string& ik_mot_path, const std::string& markers_trc,
                                     const std::string& grf_mot, const std::string& loads_xml);

}  // namespace cpgait::services

namespace cpgait::services {

// A results column's quantity without its _moment/_force suffix ("knee_angle_r_moment" -> "knee_angle_r").
std::string column_quantity(std::string column);

// Gait-cycle curves for the dashboard's cycle plots: the trial's kinematics (_ik.mot), joint moments
// (_id.sto) and muscle activations (static optimization's), each column cut at its side's heel
// strikes (right for _r columns and for those without a side, left for _l), every stride resampled
// to 0-100 % in 1 % steps, with the strides' mean and sample SD. Heel strikes: where the vertical
// force of the GRF applied to that foot rises through 20 N, else Zeni et al.'s kinematic method.
// Files absent from results_dir are left out.
nlohmann::json trial_cycles_json(const std::string& model_path, const std::string& marker_set_path, const std::string& results_dir,
                                 const std::string& trial_name, const std::string& grf_mot, const std::string& loads_xml);

}  // namespace cpgait::services
