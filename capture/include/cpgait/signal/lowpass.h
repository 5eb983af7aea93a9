#pragma once
// Signal conditioning as OpenSim's tools do it, so results stay comparable with OpenSim's.
#include <Eigen/Core>

namespace cpgait {

// Extends x by `pad` samples at each end with its odd reflection about the end values, which keeps
// value and slope continuous (OpenSim's Signal::Pad).
Eigen::VectorXd pad_odd_reflection(const Eigen::VectorXd& x, int pad);

// Third-order Butterworth low-pass (bilinear transform) run forward then backward: zero phase,
// sixth-order magnitude response, the first three samples of each pass taken as they are
// (OpenSim's Signal::LowpassIIR). dt in s, cutoff in Hz; a cutoff at or above Nyquist is clipped
// to 0.49 of the sample rate.
Eigen::VectorXd lowpass_butterworth3_zero_phase(const Eigen::VectorXd& x, double dt_s, double cutoff_hz);

}  // namespace cpgait
