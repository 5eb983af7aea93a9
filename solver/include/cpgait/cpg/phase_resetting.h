#pragma once
// Phase resetting at foot contact (Yamasaki, Nomura & Sato 2003, Biol Cybern 88:468; Aoi & Tsuchiya
// 2005, Auton Robots 19:219): the foot-contact feedback that entrains a CPG to the body it drives. At
// each touchdown the CPG's phase error against that foot's heel-strike phase is taken, and a share of
// it is made up by running the whole network faster or slower for a while, so that every neuron
// (and whatever reads the CPG's phase) moves along the limit cycle together.
#include <limits>

namespace cpgait {

struct PhaseResettingOptions {
  double share = 0;              // of the phase error made up at each touchdown, 0-1 (default 0: none)
  double time_s = 0.1;           // time constant of the making up, s (default 0.1)
  double phase_r = 0;            // heel-strike phases of the right foot (the CPG's; default 0) ...
  double phase_l = 0.5;          // ... and of the left (default 0.5; subject01's trial: 0.509)
  double refractory_cycles = 0.75;  // a foot's touchdowns count this many cycles apart (default 0.75)
  double max_rate_change = 0.5;  // the network's rate stays within 1 -+ this (default 0.5)
};

class PhaseResetting {
 public:
  explicit PhaseResetting(const PhaseResettingOptions& options) : o_(options) {}
  // Once per control interval at time t (s), with each foot's loading (right, left) and the CPG's cycle
  // (s, at its speed): the foot that touched down (0 right, 1 left; right first if both), or -1. A
  // touchdown is a foot becoming loaded, refractory_cycles after its last; the first call only
  // records the loading.
  int touchdown(double t_s, bool loaded_r, bool loaded_l, double cycle_s);
  // At a touchdown of `side`, the CPG's phase (0-1) then: the share of its error (the nearer way round)
  // becomes what is left to make up, replacing what was.
  void reset(int side, double phase);
  // The network's rate over the next interval dt (s; 1: unchanged), what is left reduced by what it
  // makes up.
  double rate(double dt_s, double cycle_s);
  double left_to_make_up() const { return debt_; }  // cycles
  int touchdowns() const { return touchdowns_; }

 private:
  PhaseResettingOptions o_;
  bool first_ = true, loaded_[2] = {false, false};
  double last_s_[2] = {-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  double debt_ = 0;
  int touchdowns_ = 0;
};

}  // namespace cpgait
