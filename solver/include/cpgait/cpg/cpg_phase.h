#pragma once
// Where a CPG is in its gait cycle, read from its rhythm neurons' state: the clock of a controller
// whose references are indexed by phase rather than by the trial's time, so that the speed knob,
// entrainment by feedback and transitions move them too.
#include <Eigen/Core>
#include <vector>

#include "cpgait/cpg/cpg_fit.h"

namespace cpgait {

// The rhythm layer: the leading neurons that no later neuron inhibits (the pattern neurons only
// listen to it). The whole network when none qualifies.
int cpg_rhythm_neurons(const MatsuokaNetwork& network);

// One free cycle of the rhythm neurons (x and f), sampled at equal phases from the model's start
// state, each coordinate scaled by its range over the cycle.
struct CpgPhaseTable {
  int rhythm_neurons = 0;
  Eigen::MatrixXd states;      // samples x (2 * rhythm_neurons), scaled
  Eigen::VectorXd inv_range;   // the scale per coordinate
  double phase_at_start = 0;   // the phase of sample 0
};
CpgPhaseTable cpg_phase_table(const CpgModel& model, int samples = 400);

// The phase in [0, 1) of a state (0: the heel strike the CPG's cycle starts at): the nearest sampled
// state's, refined along the segment to its nearer neighbour. The speed knob changes how fast the
// states go round, not which they are, so one table serves every speed.
double cpg_phase(const CpgPhaseTable& table, const MatsuokaState& state);
// The same phase to the bit, found from a hint: `nearest` holds the nearest sample of a state near
// this one (the last call's; -1: none) and receives this one's. The state's distance to the hint
// bounds the search: each other sample's sum of squares stops once it passes the best so far
// (partial distance search), which for most samples is after a term or two.
double cpg_phase(const CpgPhaseTable& table, const MatsuokaState& state, int& nearest);

}  // namespace cpgait
