// The reproduced gait's bookkeeping on the fixture walker (the subject01 figures are in
// reference/test_so_gait2392.cpp): where in the reference it begins, and the CPG's phase there.
#include <gtest/gtest.h>

#include "cpgait/cpg/cpg_fit.h"
#include "cpgait/cpg/matsuoka.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/gait/reproduced_gait.h"
#include "cpgait/capture/input_error.h"
#include "test_support.h"

using namespace cpgait;

namespace {

// A two-neuron CPG driving every muscle of the model, its start state on the limit cycle.
CpgModel walker_cpg(const Model& m) {
  CpgModel c;
  c.network = MatsuokaNetwork::pair(5.0, 0.05, 0.5, 2.5, 1.5, 1.5);
  c.network.s[1] = 5.0;
  const int nm = static_cast<int>(m.muscles.size());
  for (const auto& mu : m.muscles) c.muscle_names.push_back(mu.name);
  c.output_map = Eigen::MatrixXd::Zero(nm, 2);
  for (int k = 0; k < nm; ++k) c.output_map(k, k % 2) = 0.05 + 0.01 * k;
  c.output_bias = Eigen::VectorXd::Zero(nm);
  c.feedback_gains = Eigen::MatrixXd::Zero(2, 0);
  c.start = MatsuokaState::resting(c.network);
  const double dt = 0.001;
  const CpgRun settle = run_cpg(c, 20.0, dt);
  c.cycle_s = oscillation_period(settle.neurons.col(0), dt, 0);
  MatsuokaState s = c.start;
  simulate_matsuoka(c.network, s, dt, 20000, Eigen::MatrixXd());
  c.start = s;
  return c;
}

}  // namespace

TEST(ReproducedGait, BeginsAnywhereWithTheCpgAtTheReferencesPhase) {
  const Model& m = refdata::walker();
  const CpgModel cpg = walker_cpg(m);
  ASSERT_GT(cpg.cycle_s, 0.2);
  // The reference: the default pose held for 3 s.
  std::vector<double> t;
  for (int i = 0; i <= 300; ++i) t.push_back(0.01 * i);
  Eigen::MatrixXd q = m.default_coordinates().transpose().replicate(static_cast<Eigen::Index>(t.size()), 1);
  const Storage reference = make_storage("still", coordinate_names(m), t, q, false);
  ContactSet feet = default_foot_contacts(m);
  place_ground_under_feet(m, feet, t, q);
  ReproducedGaitOptions o;
  o.start_time_s = 0.5;  // the CPG's start state belongs here
  o.duration_s = 0.01;
  o.reflex_kp = o.reflex_kv = 0;  // excitations: the CPG's alone
  const double dt = o.control_interval_s;

  // Begun 0.3 cycles later: the CPG is where it would be after 0.3 cycles.
  o.begin_time_s = o.start_time_s + 0.3 * cpg.cycle_s;
  const ReproducedGaitResult later = reproduce_gait(m, cpg, reference, feet, o);
  EXPECT_DOUBLE_EQ(later.reference_begin_s, o.begin_time_s);
  const CpgRun run = run_cpg(cpg, 0.3 * cpg.cycle_s, dt);
  const Eigen::VectorXd expected = run.excitations.bottomRows(1).transpose();
  EXPECT_LT((later.excitations.row(0).transpose() - expected).cwiseAbs().maxCoeff(), 1e-9);
  // ... and not where it starts (so the comparison above could fail).
  o.begin_time_s = -1;
  const ReproducedGaitResult at_start = reproduce_gait(m, cpg, reference, feet, o);
  EXPECT_DOUBLE_EQ(at_start.reference_begin_s, o.start_time_s);
  EXPECT_GT((at_start.excitations.row(0) - later.excitations.row(0)).cwiseAbs().maxCoeff(), 0.01);

  // A simulation that would run past the reference's end begins earlier instead, the CPG with it.
  o.start_time_s = 2.0;
  o.duration_s = 1.5;
  const ReproducedGaitResult early = reproduce_gait(m, cpg, reference, feet, o);
  EXPECT_NEAR(early.reference_begin_s, 1.5, 1e-12);
  for (const auto& w : early.warnings) {
    EXPECT_EQ(w.find("reference kinematics end"), std::string::npos) << w;
  }
  // A begin outside the reference is refused, naming the field.
  o.begin_time_s = 3.5;
  try {
    reproduce_gait(m, cpg, reference, feet, o);
    ADD_FAILURE() << "a begin after the reference's end was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "begin_time");
  }
}
