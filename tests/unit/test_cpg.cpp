#include <gtest/gtest.h>

#include <random>

#include "cpgait/activation/static_optimization.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/cpg/cpg_fit.h"
#include "cpgait/cpg/cpg_phase.h"
#include "cpgait/cpg/phase_resetting.h"
#include "cpgait/cpg/matsuoka.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/optim/nnls.h"
#include "test_support.h"

using namespace cpgait;

// Acceptance 1 of the CPG issue: the paper's two-neuron oscillator (s 5, Tr 1, Ta 10, b 2.5,
// a12 = a21 = 1.5) alternates periodically, with a period within 5 % of Matsuoka's estimate.
TEST(Matsuoka, PapersTwoNeuronOscillatorMatchesTheAnalyticPeriod) {
  const MatsuokaNetwork n = MatsuokaNetwork::pair(5.0, 1.0, 10.0, 2.5, 1.5, 1.5);
  MatsuokaState st = MatsuokaState::resting(n);
  const double dt = 0.01;
  const Eigen::MatrixXd y = simulate_matsuoka(n, st, dt, 40000);
  const double simulated = oscillation_period(y.col(0), dt, 10000);
  const double analytic = 2 * M_PI / matsuoka_natural_frequency(1.0, 10.0, 2.5, 1.5);
  EXPECT_NEAR(analytic, 15.09, 0.01);
  EXPECT_NEAR(simulated / analytic, 1.0, 0.05) << "simulated " << simulated << " s, analytic " << analytic << " s";
  std::printf("[ info ] two-neuron oscillator: simulated period %.3f s, Matsuoka's estimate %.3f s (%+.1f %%)\n", simulated, analytic,
              100 * (simulated / analytic - 1));
  // Alternation: the two outputs are mostly active at different times and, over whole periods,
  // equally strong.
  const Eigen::MatrixXd tail = y.bottomRows(static_cast<Eigen::Index>(std::lround(12 * simulated / dt)));
  EXPECT_NEAR(oscillation_period(tail.col(1), dt), simulated, 0.02 * simulated);
  const double both = (tail.col(0).array() > 0.1 && tail.col(1).array() > 0.1).cast<double>().mean();
  EXPECT_LT(both, 0.3);
  EXPECT_NEAR(tail.col(0).mean(), tail.col(1).mean(), 0.01 * tail.col(0).mean());
}

// A network stepped with its inhibition prepared sparse follows the dense steps (to rounding), with
// and without feedback input.
TEST(Matsuoka, SparseStepsFollowTheDenseOnes) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  MatsuokaNetwork n;
  const int N = 12;
  n.tau_r_s = Eigen::VectorXd::Constant(N, 0.05);
  n.tau_a_s = Eigen::VectorXd::Constant(N, 0.6);
  n.b = Eigen::VectorXd::Constant(N, 2.5);
  n.s = Eigen::VectorXd::Constant(N, 1.0);
  n.a = Eigen::MatrixXd::Zero(N, N);
  for (int i = 0; i + 1 < N; i += 2) n.a(i, i + 1) = n.a(i + 1, i) = 1.5 + U(rng);
  for (int k = 0; k < 6; ++k) n.a(static_cast<int>(U(rng) * N) % N, static_cast<int>(U(rng) * N) % N) += 0.3 * U(rng);
  n.a.diagonal().setZero();
  MatsuokaState dense = MatsuokaState::resting(n), sparse = dense;
  MatsuokaScratch wd, ws;
  matsuoka_prepare(n, ws);
  ASSERT_EQ(ws.a.nonZeros(), (n.a.array() != 0).count());
  Eigen::VectorXd u = Eigen::VectorXd::Zero(N);
  for (int step = 0; step < 4000; ++step) {
    if (step == 2000) u.setConstant(0.2);
    matsuoka_step(n, dense, 0.002, u, wd);
    matsuoka_step(n, sparse, 0.002, u, ws);
  }
  EXPECT_LT((dense.x - sparse.x).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_GT(dense.x.cwiseMax(0.0).maxCoeff(), 0.05);  // it oscillates, not rests
}

// The sparse inhibition skips the silent neurons (y = 0) and otherwise sums as Eigen's sparse product
// does, so the rates are the same bits (rows of several inputs: another order would round otherwise).
TEST(Matsuoka, SparseRatesSkipSilentNeuronsBitForBit) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const int N = 60;
  MatsuokaNetwork n;
  n.tau_r_s = Eigen::VectorXd::NullaryExpr(N, [&] { return 0.02 + 0.1 * U(rng); });
  n.tau_a_s = Eigen::VectorXd::NullaryExpr(N, [&] { return 0.3 + U(rng); });
  n.b = Eigen::VectorXd::Constant(N, 2.5);
  n.s = Eigen::VectorXd::Constant(N, 1.0);
  n.a = Eigen::MatrixXd::Zero(N, N);
  for (int i = 0; i < N; ++i)
    for (int k = 0; k < 6; ++k) n.a(i, static_cast<int>(U(rng) * N) % N) = 3.0 * U(rng) / 7.0;
  n.a.diagonal().setZero();
  MatsuokaScratch w;
  matsuoka_prepare(n, w);
  MatsuokaState st;
  st.x = Eigen::VectorXd::NullaryExpr(N, [&] { return U(rng) - 0.5; });
  st.f = Eigen::VectorXd::NullaryExpr(N, [&] { return U(rng); });
  const Eigen::VectorXd u = Eigen::VectorXd::NullaryExpr(N, [&] { return 0.1 * U(rng); });
  MatsuokaState r;
  matsuoka_rates(n, st, u, r, &w.a);
  const Eigen::VectorXd y = st.x.cwiseMax(0.0);
  const Eigen::VectorXd inhibition = w.a * y;
  const Eigen::VectorXd x_rate = (n.s - st.x - n.b.cwiseProduct(st.f) - inhibition + u).cwiseQuotient(n.tau_r_s);
  const Eigen::VectorXd f_rate = (y - st.f).cwiseQuotient(n.tau_a_s);
  const int silent = static_cast<int>((y.array() == 0).count());
  EXPECT_GT(silent, N / 4);
  EXPECT_LT(silent, 3 * N / 4);
  for (int i = 0; i < N; ++i) {
    EXPECT_EQ(r.x[i], x_rate[i]) << i;
    EXPECT_EQ(r.f[i], f_rate[i]) << i;
  }
  // Summed in another order (each row's inputs last to first), some sum differs in its last bits.
  int reordered_differs = 0;
  for (int i = 0; i < N; ++i) {
    double sum = 0;
    for (int j = N - 1; j >= 0; --j) sum += n.a(i, j) * y[j];
    reordered_differs += sum != inhibition[i];
  }
  EXPECT_GT(reordered_differs, 0);
}

TEST(Nnls, MatchesKktConditions) {
  std::mt19937 rng(4);
  std::normal_distribution<double> g;
  for (int t = 0; t < 50; ++t) {
    const Eigen::MatrixXd A = Eigen::MatrixXd::NullaryExpr(30, 6, [&] { return g(rng); });
    const Eigen::VectorXd b = Eigen::VectorXd::NullaryExpr(30, [&] { return g(rng); });
    const Eigen::VectorXd x = nnls(A, b);
    const Eigen::VectorXd grad = A.transpose() * (A * x - b);
    for (int j = 0; j < 6; ++j) {
      ASSERT_GE(x[j], 0.0);
      if (x[j] > 1e-10) EXPECT_NEAR(grad[j], 0.0, 1e-8);  // free: stationary
      else EXPECT_GE(grad[j], -1e-8);                       // at zero: would not decrease
    }
  }
}

namespace {

// Patterns over one cycle produced by a known network and output map.
Eigen::MatrixXd patterns_of(const CpgModel& m, int samples, double& period) {
  const double dt = 0.001;
  const CpgRun r = run_cpg(m, 60.0 * m.network.tau_a_s.maxCoeff(), dt);
  period = oscillation_period(r.neurons.col(0), dt, static_cast<int>(r.neurons.rows() / 2));
  if (period <= 0) return {};  // no oscillation: no cycle to sample (and the rows below would overrun)
  const double per = period / dt, end = static_cast<double>(r.neurons.rows() - 1);
  Eigen::MatrixXd out(samples, r.excitations.cols());
  for (int k = 0; k < samples; ++k) {
    const double pos = end - per + per * k / samples;
    const int i = static_cast<int>(pos);
    out.row(k) = (1 - (pos - i)) * r.excitations.row(i) + (pos - i) * r.excitations.row(i + 1);
  }
  return out;
}

CpgModel random_pair_model(unsigned seed, int muscles) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  CpgModel m;
  // Symmetric inhibition (one a per pair, as the fitted family has); tonic inputs differ.
  const double a = 1.5 + u(rng);
  m.network = MatsuokaNetwork::pair(2 + 4 * u(rng), 0.1, 0.1 * (5 + 10 * u(rng)), 2 + 2 * u(rng), a, a);
  m.network.s[1] = 2 + 4 * u(rng);
  m.start = MatsuokaState::resting(m.network);
  m.output_map = Eigen::MatrixXd::NullaryExpr(muscles, 2, [&] { return u(rng) < 0.3 ? 0.0 : 0.3 * u(rng); });
  m.output_bias = Eigen::VectorXd::NullaryExpr(muscles, [&] { return 0.05 * u(rng); });
  m.feedback_gains = Eigen::MatrixXd::Zero(2, 0);
  return m;
}

}  // namespace

// Parameter recovery for a single oscillator pair: patterns of a known random network are fitted
// back with R^2 >= 0.99 on every active muscle. (Two coupled pairs are not yet recovered that
// well: see the issue note.)
TEST(CpgFit, RecoversARandomPairNetwork) {
  int tested = 0;
  for (unsigned seed = 5; tested < 2 && seed < 20; ++seed) {
    const CpgModel truth = random_pair_model(seed, 10);
    double period = 0;
    const Eigen::MatrixXd target = patterns_of(truth, 100, period);
    if (period == 0) continue;  // this draw does not oscillate: not a pattern to recover
    ++tested;
    std::vector<std::string> names(10);
    for (int k = 0; k < 10; ++k) names[k].assign(1, 'm').append(std::to_string(k));
    CpgFitOptions o;
    o.pairs = 1;
    o.starts = 4;
    o.max_iterations = 100;
    o.pattern_units = 0;  // recover the generating network itself
    const CpgFitResult r = fit_cpg(target, period, names, o);
    for (int k = 0; k < 10; ++k) {
      if (target.col(k).maxCoeff() > o.active_threshold) {
        EXPECT_GE(r.summary.r_squared[k], 0.99) << "seed " << seed << " muscle " << k;
      }
    }
    std::printf("[ info ] seed %u: %s\n", seed, r.summary.BriefReport().c_str());
    // The fitted model reproduces its own fit when run, at the gait cycle's period.
    const CpgRun run = run_cpg(r.model, 6 * period, 0.001);
    EXPECT_NEAR(oscillation_period(run.neurons.col(0), 0.001, 2000), period, 0.02 * period);
  }
  EXPECT_EQ(tested, 2);
}

TEST(CpgModel, SpeedAmplitudeTransitionAndJson) {
  const CpgModel m = random_pair_model(5, 4);
  double period = 0;
  patterns_of(m, 50, period);
  CpgModel fast = m;
  fast.speed = 1.2;
  const CpgRun r = run_cpg(fast, 40 * period, 0.001);
  EXPECT_NEAR(oscillation_period(r.neurons.col(0), 0.001, 20000), period / 1.2, 0.01 * period);  // speed knob: cycle / 1.2
  CpgModel small = m;  // a small map, so nothing is clamped at 1
  small.output_map *= 0.1;
  CpgModel quiet = small;
  quiet.amplitude = 0.5;
  const CpgRun a = run_cpg(small, 2.0, 0.001), b = run_cpg(quiet, 2.0, 0.001);
  ASSERT_LT(a.excitations.maxCoeff(), 1.0);
  EXPECT_LT((b.excitations - 0.5 * a.excitations).cwiseAbs().maxCoeff(), 1e-9);  // amplitude scales the excitations
  // Walk -> stand (amplitude 0) over a second: smooth, and quiet at the end.
  CpgModel stand = m;
  stand.amplitude = 0.0;
  const CpgRun t = run_cpg_transition(m, stand, 1.0, 2.0, 3.0, 0.001);
  EXPECT_LT((t.excitations.bottomRows(500)).cwiseAbs().maxCoeff(), 1e-12);
  const Eigen::MatrixXd steps = (t.excitations.bottomRows(t.excitations.rows() - 1) - t.excitations.topRows(t.excitations.rows() - 1)).cwiseAbs();
  EXPECT_LT(steps.maxCoeff(), 0.05);  // no jumps
  // JSON round trip and validation.
  CpgModel named = m;
  named.muscle_names = {"a", "b", "c", "d"};
  const CpgModel back = CpgModel::from_json(named.to_json(), "model.json");
  EXPECT_EQ(back.muscle_names, named.muscle_names);
  EXPECT_LT((run_cpg(back, 1.0, 0.001).excitations - run_cpg(named, 1.0, 0.001).excitations).cwiseAbs().maxCoeff(), 1e-12);
  nlohmann::json bad = named.to_json();
  bad["output_map"][0][0] = -1.0;
  EXPECT_THROW(CpgModel::from_json(bad, "model.json"), InputError);
  bad = named.to_json();
  bad["network"]["tau_r_s"] = {1.0};
  EXPECT_THROW(CpgModel::from_json(bad, "model.json"), InputError);
  // A tuned controller, balance gains included, round-trips; a gain that is not a number is refused.
  named.controller = CpgController{.reflex_kp = 250, .reflex_kv = 17, .phase_reference = true, .pelvis_residuals = false, .trunk_kp = 2.4, .trunk_kv = 3.6, .lateral_d = 0.6, .lateral_v = 0.3, .sagittal_d = 0.8, .sagittal_v = -0.01, .start_time_s = 0.618, .begin_time_s = 0.25};
  named.controller->stance_lateral_d = 0.4, named.controller->stance_lateral_v = -0.17;
  named.controller->ankle_d = 1.3, named.controller->ankle_v = -0.35;
  const CpgModel tuned = CpgModel::from_json(named.to_json(), "model.json");
  ASSERT_TRUE(tuned.controller.has_value());
  const CpgController& k = *tuned.controller;
  EXPECT_EQ(std::vector<double>({k.reflex_kp, k.reflex_kv, k.trunk_kp, k.trunk_kv, k.lateral_d, k.lateral_v, k.sagittal_d, k.sagittal_v,
                                 k.start_time_s, k.begin_time_s}),
            std::vector<double>({250, 17, 2.4, 3.6, 0.6, 0.3, 0.8, -0.01, 0.618, 0.25}));
  EXPECT_EQ(k.stance_lateral_d, 0.4);
  EXPECT_EQ(k.stance_lateral_v, -0.17);
  EXPECT_EQ(k.ankle_d, 1.3);
  EXPECT_EQ(k.ankle_v, -0.35);
  bad = named.to_json();
  bad["controller"]["foot_placement"]["lateral_v_s"] = "fast";
  // Each mistyped member is refused by name.
  auto field_of = [](const nlohmann::json& doc) {
    try {
      CpgModel::from_json(doc, "model.json");
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), "model.json");
      return e.field();
    }
    return std::string("(accepted)");
  };
  EXPECT_EQ(field_of(bad), "controller.foot_placement.lateral_v_s");
  bad = named.to_json();
  bad["controller"]["foot_placement"] = 0.3;
  EXPECT_EQ(field_of(bad), "controller.foot_placement");
  bad = named.to_json();
  bad["controller"]["stance_hold"]["lateral_d"] = "wide";
  EXPECT_EQ(field_of(bad), "controller.stance_hold.lateral_d");
  bad = named.to_json();
  bad["controller"]["ankle_strategy"]["lateral_v_rad_s_per_m"] = nullptr;
  EXPECT_EQ(field_of(bad), "controller.ankle_strategy.lateral_v_rad_s_per_m");
  bad = named.to_json();
  bad["controller"]["ankle_strategy"] = 1.0;
  EXPECT_EQ(field_of(bad), "controller.ankle_strategy");
  bad = named.to_json();
  bad["controller"]["simulation"]["integrator"] = 2;
  EXPECT_EQ(field_of(bad), "controller.simulation.integrator");
  bad = named.to_json();
  bad["controller"]["phase_reference"] = "yes";
  EXPECT_EQ(field_of(bad), "controller.phase_reference");
  bad = named.to_json();
  bad["controller_schedule"] = nlohmann::json::array({named.to_json()["controller"]});
  bad["controller_schedule"][0]["speed"] = "slow";
  EXPECT_EQ(field_of(bad), "controller_schedule[0].speed");
  bad["controller_schedule"] = named.to_json()["controller"];
  EXPECT_EQ(field_of(bad), "controller_schedule");
  bad = named.to_json();
  bad["muscles"] = "soleus_r";
  EXPECT_EQ(field_of(bad), "muscles");
  bad = named.to_json();
  bad["cycle_s"] = nullptr;
  EXPECT_EQ(field_of(bad), "cycle_s");
  // The feet it was tuned on: 2 when the JSON predates them, as written otherwise, 2, 5 or 0 only.
  EXPECT_EQ(k.foot_spheres, 2);
  named.controller->foot_spheres = 5;
  EXPECT_EQ(CpgModel::from_json(named.to_json(), "model.json").controller->foot_spheres, 5);
  bad = named.to_json();
  bad["controller"].erase("foot_spheres");
  EXPECT_EQ(CpgModel::from_json(bad, "model.json").controller->foot_spheres, 2);
  bad["controller"]["foot_spheres"] = 3;
  try {
    CpgModel::from_json(bad, "model.json");
    ADD_FAILURE() << "3 spheres per foot accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "controller.foot_spheres");
  }
  // The entrainment share: 0 when the JSON predates it, as written otherwise, within [0, 1] only.
  EXPECT_EQ(k.entrainment, 0.0);
  named.controller->entrainment = 0.4;
  named.controller->entrainment_phase_r = 0.05, named.controller->entrainment_phase_l = 0.6;
  const CpgController entrained = *CpgModel::from_json(named.to_json(), "model.json").controller;
  EXPECT_EQ(std::vector<double>({entrained.entrainment, entrained.entrainment_phase_r, entrained.entrainment_phase_l}), std::vector<double>({0.4, 0.05, 0.6}));
  bad = named.to_json();
  bad["controller"]["entrainment"]["share"] = 1.2;
  try {
    CpgModel::from_json(bad, "model.json");
    ADD_FAILURE() << "an entrainment share of 1.2 accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "controller.entrainment.share");
  }
  // The simulation it was tuned in: not recorded (0, empty) when the JSON predates it, as written
  // otherwise; an integrator by another name, or an interval past 10 ms, is refused.
  EXPECT_EQ(k.control_interval_s, 0.0);
  EXPECT_EQ(k.integrator_tolerance, 0.0);
  EXPECT_EQ(k.integrator, "");
  named.controller->control_interval_s = 0.004, named.controller->integrator_tolerance = 2e-3, named.controller->integrator = "rosenbrock";
  const CpgController simulated = *CpgModel::from_json(named.to_json(), "model.json").controller;
  EXPECT_EQ(simulated.control_interval_s, 0.004);
  EXPECT_EQ(simulated.integrator_tolerance, 2e-3);
  EXPECT_EQ(simulated.integrator, "rosenbrock");
  for (const auto& [key, value] : std::vector<std::pair<std::string, nlohmann::json>>{{"integrator", "euler"}, {"control_interval_s", 0.02}, {"tolerance", -1}}) {
    bad = named.to_json();
    bad["controller"]["simulation"][key] = value;
    try {
      CpgModel::from_json(bad, "model.json");
      ADD_FAILURE() << key << " " << value.dump() << " accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(e.field(), "controller.simulation." + key);
    }
  }
}

// A gain schedule over the speed knob: at a tuned knob its own controller and amplitude; between two,
// reflex gains and amplitude geometrically and balance gains and entrainment linearly interpolated; held beyond the
// ends; the start and beginning the CPG controller's. It round-trips through the JSON, and an entry
// at a knob that is not positive is refused naming it.
TEST(CpgModel, SpeedScheduleInterpolatesBetweenTunedKnobs) {
  CpgModel m = random_pair_model(5, 4);
  m.muscle_names = {"a", "b", "c", "d"};
  m.amplitude = 0.6;
  m.controller = CpgController{.reflex_kp = 100, .reflex_kv = 10, .phase_reference = true, .pelvis_residuals = false, .trunk_kp = 2.0, .trunk_kv = 2.0, .lateral_d = 0.3, .lateral_v = 0.1, .sagittal_d = 0.5, .sagittal_v = 0.0, .start_time_s = 0.618, .begin_time_s = 0.25, .speed = 1.0};
  const CpgController slow{.reflex_kp = 400, .reflex_kv = 40, .phase_reference = true, .pelvis_residuals = false, .trunk_kp = 4.0, .trunk_kv = 1.0, .lateral_d = 0.7, .lateral_v = 0.3, .sagittal_d = 0.9, .sagittal_v = -0.1, .start_time_s = 9.0, .begin_time_s = 9.0, .speed = 0.8};
  const CpgController fast{.reflex_kp = 200, .reflex_kv = 20, .phase_reference = true, .pelvis_residuals = false, .trunk_kp = 3.0, .trunk_kv = 3.0, .lateral_d = 0.5, .lateral_v = 0.2, .sagittal_d = 0.7, .sagittal_v = 0.1, .start_time_s = 9.0, .begin_time_s = 9.0, .speed = 1.2, .foot_spheres = 2, .entrainment = 0.6};
  m.controller->entrainment = 0.2;
  m.speed_schedule = {{fast, 0.5}, {slow, 1.2}};  // any order
  m.speed_schedule[1].controller.stance_lateral_d = 0.2;  // slow's
  m.speed_schedule[1].controller.ankle_v = 0.4;
  m.controller->ankle_v = 0.2;
  const CpgModel at09 = scheduled_at_speed(m, 0.9);
  const CpgController& k = *at09.controller;
  EXPECT_NEAR(k.reflex_kp, 200, 1e-9);  // sqrt(400 x 100)
  EXPECT_NEAR(k.reflex_kv, 20, 1e-9);
  EXPECT_NEAR(k.trunk_kp, 3.0, 1e-12);
  EXPECT_NEAR(k.sagittal_v, -0.05, 1e-12);
  EXPECT_NEAR(k.stance_lateral_d, 0.1, 1e-12);  // halfway from slow's 0.2 to the controller's 0
  EXPECT_NEAR(k.ankle_v, 0.3, 1e-12);
  EXPECT_NEAR(at09.amplitude, std::sqrt(1.2 * 0.6), 1e-12);
  EXPECT_EQ(k.start_time_s, 0.618);
  EXPECT_EQ(k.begin_time_s, 0.25);
  EXPECT_EQ(k.speed, 0.9);
  EXPECT_NEAR(scheduled_at_speed(m, 1.1).controller->lateral_d, 0.4, 1e-12);
  EXPECT_NEAR(scheduled_at_speed(m, 1.1).amplitude, std::sqrt(0.6 * 0.5), 1e-12);
  EXPECT_NEAR(scheduled_at_speed(m, 1.1).controller->entrainment, 0.4, 1e-12);  // linearly, as the balance gains
  for (double knob : {0.8, 0.5}) {
    const CpgModel held = scheduled_at_speed(m, knob);
    EXPECT_EQ(held.controller->reflex_kp, 400) << knob;
    EXPECT_EQ(held.amplitude, 1.2) << knob;
  }
  EXPECT_EQ(scheduled_at_speed(m, 1.0).controller->reflex_kp, 100);
  EXPECT_EQ(scheduled_at_speed(m, 1.7).controller->trunk_kv, 3.0);
  const CpgModel back = CpgModel::from_json(m.to_json(), "model.json");
  ASSERT_EQ(back.speed_schedule.size(), 2u);
  EXPECT_EQ(back.speed_schedule[1].controller.speed, 0.8);
  EXPECT_EQ(back.speed_schedule[1].amplitude, 1.2);
  EXPECT_EQ(scheduled_at_speed(back, 0.9).controller->reflex_kp, k.reflex_kp);
  nlohmann::json bad = m.to_json();
  bad["controller_schedule"][1]["speed"] = 0.0;
  try {
    CpgModel::from_json(bad, "model.json");
    ADD_FAILURE() << "a schedule entry at knob 0 was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("controller_schedule[1].speed"), std::string::npos) << e.what();
  }
  bad = m.to_json();
  bad.erase("controller");
  EXPECT_THROW(CpgModel::from_json(bad, "model.json"), InputError);  // a schedule without the controller it extends
}

// The pattern layer: narrow bursts at any phase (and a muscle with two bursts a cycle), which a
// rhythm layer's broad half-waves cannot reproduce, are fitted by each muscle's own neurons; the
// assembled network, run as a CPG, reproduces the fit.
TEST(CpgFit, PatternNeuronsShapeNarrowBurstsAtAnyPhase) {
  const int S = 100, M = 6;
  Eigen::MatrixXd target(S, M);
  const double centres[M] = {0.08, 0.25, 0.45, 0.62, 0.85, 0.3};
  for (int k = 0; k < S; ++k)
    for (int m = 0; m < M; ++m) {
      auto burst = [&](double c, double w) {
        double d = std::abs(static_cast<double>(k) / S - c);
        d = std::min(d, 1 - d);
        return std::exp(-0.5 * d * d / (w * w));
      };
      target(k, m) = m < 5 ? 0.6 * burst(centres[m], 0.05) : 0.4 * burst(0.3, 0.04) + 0.5 * burst(0.8, 0.06);
    }
  std::vector<std::string> names;
  for (int m = 0; m < M; ++m) names.push_back(std::string("m").append(std::to_string(m)));
  CpgFitOptions rhythm_only;
  rhythm_only.pattern_units = 0;
  const CpgFitResult a = fit_cpg(target, 1.1, names, rhythm_only);
  const CpgFitResult b = fit_cpg(target, 1.1, names, CpgFitOptions{});
  std::printf("[ info ] narrow bursts: rhythm layer only %s\n[ info ] narrow bursts: with pattern neurons %s\n",
              a.summary.BriefReport().c_str(), b.summary.BriefReport().c_str());
  EXPECT_LT(a.summary.mean_r_squared_active, 0.9);
  EXPECT_GE(b.summary.mean_r_squared_active, 0.97);
  for (int m = 0; m < M; ++m) EXPECT_GE(b.summary.r_squared[m], 0.93) << names[m];
  const double dt = 1.1 / 1000;
  const CpgRun run = run_cpg(b.model, 3 * 1.1, dt);
  double largest = 0;
  for (int k = 0; k < S; ++k) {
    const int step = static_cast<int>(std::lround((2 * 1.1 + k * 1.1 / S) / dt)) - 1;
    largest = std::max(largest, (run.excitations.row(step) - b.fitted.row(k).cwiseMax(0.0).cwiseMin(1.0)).cwiseAbs().maxCoeff());
  }
  std::printf("[ info ] narrow bursts: running the fitted CPG, largest difference from the fit %.4f\n", largest);
  EXPECT_LT(largest, 0.01);
  // JSON keeps the two-layer network.
  const CpgModel back = CpgModel::from_json(b.model.to_json(), "model.json");
  EXPECT_LT((run_cpg(back, 1.0, dt).excitations - run_cpg(b.model, 1.0, dt).excitations).cwiseAbs().maxCoeff(), 1e-12);
}

// The controller's clock: the seed's pair (s 5, Tr 1, Ta 10, b 2.5, a 1.5) as the rhythm, with a
// pattern neuron it excites. Running freely at speed 1 or 1.3, the phase read from the state
// advances as time x speed / cycle; the pattern neuron's state does not move it. Read from a hint
// (the search the reproduced gait makes), it is the same to the bit, whatever the hint.
TEST(CpgPhase, ReadFromTheRhythmNeuronsAtAnySpeed) {
  const MatsuokaNetwork pair = MatsuokaNetwork::pair(5.0, 1.0, 10.0, 2.5, 1.5, 1.5);
  CpgModel m;
  m.network.tau_r_s = Eigen::Vector3d(1.0, 1.0, 1.0);
  m.network.tau_a_s = Eigen::Vector3d(10.0, 10.0, 3.0);
  m.network.b = Eigen::Vector3d(2.5, 2.5, 1.0);
  m.network.s = Eigen::Vector3d(5.0, 5.0, 0.5);
  m.network.a = Eigen::Matrix3d::Zero();
  m.network.a.topLeftCorner(2, 2) = pair.a;
  m.network.a(2, 0) = -0.8;  // negative: neuron 0 excites the pattern neuron
  m.output_map = Eigen::MatrixXd::Zero(1, 3);
  m.output_bias = Eigen::VectorXd::Zero(1);
  // Settle, then measure the period: the model's cycle.
  const double dt = 0.01;
  MatsuokaState st = MatsuokaState::resting(m.network);
  const Eigen::MatrixXd y = simulate_matsuoka(m.network, st, dt, 20000);
  m.cycle_s = oscillation_period(y.col(0), dt, 10000);
  ASSERT_GT(m.cycle_s, 5.0);
  m.start = st;
  m.phase_at_start = 0.3;
  EXPECT_EQ(cpg_rhythm_neurons(m.network), 2);

  const CpgPhaseTable table = cpg_phase_table(m);
  EXPECT_NEAR(cpg_phase(table, m.start), 0.3, 1e-9);
  {
    // The table steps the rhythm neurons alone: the same states as the whole network's, stepped
    // as the table samples them (400 samples of 10 steps).
    MatsuokaState whole = m.start;
    MatsuokaScratch scratch;
    double worst_state = 0;
    for (int k = 0; k < table.states.rows(); ++k) {
      const double expected[4] = {whole.x[0], whole.x[1], whole.f[0], whole.f[1]};
      for (int c = 0; c < 4; ++c) worst_state = std::max(worst_state, std::abs(table.states(k, c) - expected[c] * table.inv_range[c]));
      for (int i = 0; i < 10; ++i) matsuoka_step(m.network, whole, m.cycle_s / (table.states.rows() * 10), Eigen::VectorXd(), scratch);
    }
    EXPECT_LT(worst_state, 1e-12);
  }
  double worst = 0;
  for (const double speed : {1.0, 1.3}) {
    m.speed = speed;
    const MatsuokaNetwork n = network_at_speed(m);
    MatsuokaState s = m.start;
    MatsuokaScratch scratch;
    const int S = static_cast<int>(table.states.rows());
    int hint = -1;
    for (int k = 1; k <= 1700; ++k) {
      matsuoka_step(n, s, dt, Eigen::VectorXd(), scratch);
      const double expected = 0.3 + k * dt * speed / m.cycle_s;
      const double phase = cpg_phase(table, s);
      const double error = std::remainder(phase - expected, 1.0);
      worst = std::max(worst, std::abs(error));
      // From the hint (the last step's nearest sample), and from a hint half a cycle off or none: the
      // same phase to the bit.
      EXPECT_EQ(cpg_phase(table, s, hint), phase);
      int far = (hint + S / 2) % S, none = -1, outside = S;
      EXPECT_EQ(cpg_phase(table, s, far), phase);
      EXPECT_EQ(cpg_phase(table, s, none), phase);
      EXPECT_EQ(cpg_phase(table, s, outside), phase);
      EXPECT_EQ(far, hint);
      EXPECT_EQ(none, hint);
      EXPECT_EQ(outside, hint);
    }
    MatsuokaState kicked = s;
    kicked.x[2] += 5.0;
    EXPECT_EQ(cpg_phase(table, kicked), cpg_phase(table, s));
  }
  std::printf("[info] phase error over 1.7 cycles at speeds 1 and 1.3: %.2e of a cycle\n", worst);
  EXPECT_LT(worst, 2e-3);
}

// Phase resetting's touchdowns: a foot becoming loaded counts, not a foot loaded from the first call,
// nor one touching down again within 0.75 cycles of its last (a toe's touch after toe-off); when both
// feet touch down at once the right's counts.
TEST(PhaseResetting, TouchdownsCountOncePerStepOfEachFoot) {
  PhaseResetting p(PhaseResettingOptions{});
  const double cycle = 1.2;
  EXPECT_EQ(p.touchdown(0.0, true, false, cycle), -1);   // loaded from the start
  EXPECT_EQ(p.touchdown(0.5, false, false, cycle), -1);
  EXPECT_EQ(p.touchdown(0.6, false, true, cycle), 1);    // the left lands
  EXPECT_EQ(p.touchdown(1.0, true, true, cycle), 0);     // the right's first counted touchdown
  EXPECT_EQ(p.touchdown(1.7, false, true, cycle), -1);
  EXPECT_EQ(p.touchdown(1.75, true, true, cycle), -1);   // 0.75 s after its last: within 0.9 s
  EXPECT_EQ(p.touchdown(1.8, false, false, cycle), -1);
  EXPECT_EQ(p.touchdown(2.0, true, true, cycle), 0);     // both at once (the left's 1.4 s after its last)
  EXPECT_EQ(p.touchdown(2.5, false, false, cycle), -1);
  EXPECT_EQ(p.touchdown(3.0, false, true, cycle), 1);    // the left's counted at 2.0 too: 1.0 s after
  EXPECT_EQ(p.touchdowns(), 0);                          // resets are the caller's
}

// Phase resetting's making up: the share of the phase error, the nearer way round, is made up in
// full by the rates (their excess over 1 times dt, in cycles), at most 1.5x or 0.5x, with the time
// constant given; a new touchdown replaces what was left.
TEST(PhaseResetting, RatesMakeUpTheShareOfThePhaseError) {
  PhaseResettingOptions o;
  o.share = 0.5;
  PhaseResetting p(o);
  const double cycle = 1.2, dt = 0.001;
  auto made_up = [&](double seconds, double* lowest = nullptr, double* highest = nullptr) {
    double sum = 0;
    for (int k = 0; k < static_cast<int>(seconds / dt); ++k) {
      const double r = p.rate(dt, cycle);
      if (lowest) *lowest = std::min(*lowest, r);
      if (highest) *highest = std::max(*highest, r);
      sum += (r - 1) * dt / cycle;
    }
    return sum;
  };
  EXPECT_EQ(p.rate(dt, cycle), 1.0);  // nothing to make up
  p.reset(0, 0.9);                    // the right lands 0.1 cycles early: the CPG speeds up
  EXPECT_NEAR(p.left_to_make_up(), 0.05, 1e-12);
  double lowest = 2, highest = 0;
  EXPECT_NEAR(made_up(3.0, &lowest, &highest), 0.05, 1e-9);
  EXPECT_EQ(highest, 1.5);            // 0.05 x 1.2 / 0.1 = 0.6: clamped
  EXPECT_GE(lowest, 1.0);
  p.reset(1, 0.2);                    // the left lands 0.3 cycles late
  EXPECT_NEAR(made_up(3.0), 0.15, 1e-9);
  p.reset(1, 0.95);                   // 0.45 early the nearer way, not 0.55 late
  EXPECT_NEAR(p.left_to_make_up(), -0.225, 1e-12);
  p.reset(0, 0.02);                   // replaces it
  const double first = made_up(0.1);  // one time constant once unclamped: most of it
  EXPECT_LT(first, -0.006);
  EXPECT_GT(first, -0.01);
  EXPECT_NEAR(first + made_up(3.0), -0.01, 1e-9);
  EXPECT_EQ(p.touchdowns(), 4);
}
