#include "cpgait/signal/lowpass.h"

#include <cmath>
#include <stdexcept>

namespace cpgait {

Eigen::VectorXd pad_odd_reflection(const Eigen::VectorXd& x, int pad) {
  const int n = static_cast<int>(x.size());
  if (pad <= 0) return x;
  if (pad >= n) throw std::invalid_argument("pad_odd_reflection: pad must be shorter than the signal");
  Eigen::VectorXd out(n + 2 * pad);
  for (int i = 0; i < pad; ++i) out[i] = 2.0 * x[0] - x[pad - i];
  out.segment(pad, n) = x;
  for (int i = 0; i < pad; ++i) out[pad + n + i] = 2.0 * x[n - 1] - x[n - 2 - i];
  return out;
}

Eigen::VectorXd lowpass_butterworth3_zero_phase(const Eigen::VectorXd& x, double dt_s, double cutoff_hz) {
  const int n = static_cast<int>(x.size());
  if (n < 4) throw std::invalid_argument("lowpass: need at least 4 samples");
  if (!(dt_s > 0)) throw std::invalid_argument("lowpass: sample interval must be positive");
  const double fs = 1.0 / dt_s;
  if (cutoff_hz >= 0.5 * fs) cutoff_hz = 0.49 * fs;
  // Prewarped analogue cutoff; H(s) = 1 / ((s + 1)(s^2 + s + 1)) through the bilinear transform.
  const double wa = std::tan(M_PI * cutoff_hz * dt_s);
  const double wa2 = wa * wa, wa3 = wa2 * wa;
  const double den = (wa + 1.0) * (wa2 + wa + 1.0);
  const double a[4] = {wa3 / den, 3 * wa3 / den, 3 * wa3 / den, wa3 / den};
  const double b[4] = {1.0, (3 * wa3 + 2 * wa2 - 2 * wa - 3) / den, (3 * wa3 - 2 * wa2 - 2 * wa + 3) / den,
                       (wa - 1) * (wa2 - wa + 1) / den};
  auto pass = [&](const Eigen::VectorXd& in) {
    Eigen::VectorXd out(n);
    for (int i = 0; i < 3; ++i) out[i] = in[i];
    for (int i = 3; i < n; ++i)
      out[i] = a[0] * in[i] + a[1] * in[i - 1] + a[2] * in[i - 2] + a[3] * in[i - 3] - b[1] * out[i - 1] -
               b[2] * out[i - 2] - b[3] * out[i - 3];
    return out;
  };
  const Eigen::VectorXd forward = pass(x);
  const Eigen::VectorXd backward = pass(forward.reverse());
  return backward.reverse();
}

}  // namespace cpgait
