// tests/estimators/buffer_test.cc — Schenato (2008): kalman_buffer, static_buffer, the
// Theorem 3 design and the critical probability.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "estimators/design/buffer_design.h"
#include "sim/analysis/output.h"
#include "sim/run/campaign.h"
#include "sim/scenario/registries.h"
#include "test_util.h"

namespace ncosim::est {
namespace {

std::unique_ptr<EstimatorDesign> make(const std::string& kind, toml::table t, const Model& model) {
  return sim::estimator_registry().find(kind)->factory(config::Table(t, "estimator[0]", "test"),
                                                       model);
}

Packet packet(int sensor, std::int64_t stamp, const Eigen::VectorXd& y) {
  Packet p;
  p.sensor = sensor;
  p.send_period = stamp;
  p.count = 1;
  p.stamps = {stamp};
  p.values = y;
  return p;
}

// Schenato (2008)'s examples: motor (a = 1) and pendulum (a = 1.2).
buffer::Plant example(double a) {
  buffer::Plant p;
  p.A.resize(2, 2);
  p.A << a, 0.1, 0.0, 0.8;
  p.Q.resize(2, 2);
  p.Q << 0.2, 0.1, 0.1, 1.0;
  Eigen::MatrixXd C(1, 2);
  C << 1, 0;
  p.C = {C};
  p.R = {Eigen::MatrixXd::Identity(1, 1)};
  return p;
}

std::vector<double> paper_lambda(int N) {
  std::vector<double> l;
  for (int h = 0; h < N; ++h) l.push_back(0.05 * std::min(h, 15));
  return l;
}

TEST(BufferDesign, CriticalProbabilityOfTheExamplesAndOfTheCounterexample) {
  EXPECT_NEAR(buffer::critical_probability_bisection(example(1.0)).value, 0.0, 1e-6);
  EXPECT_NEAR(buffer::critical_probability_bisection(example(1.2)).value, 1.0 - 1.0 / 1.44, 1e-6);
  // A = diag(2, -2), C = [1 1]: Theorem 2(i)'s closed form says 0.75; the fixed point exists
  // only above 0.9375.
  buffer::Plant p;
  p.A = Eigen::Vector2d(2.0, -2.0).asDiagonal();
  p.Q = Eigen::MatrixXd::Identity(2, 2);
  p.C = {Eigen::MatrixXd::Ones(1, 2)};
  p.R = {Eigen::MatrixXd::Identity(1, 1)};
  const auto cp = buffer::critical_probability_bisection(p);
  EXPECT_NEAR(cp.value, 0.9375, 1e-6);
  EXPECT_NEAR(cp.lower_bound, 0.75, 1e-12);
  EXPECT_FALSE(buffer::riccati_fixed_point(p, {0.93}).exists);
  EXPECT_TRUE(buffer::riccati_fixed_point(p, {0.94}).exists);
  // An undetectable unstable mode: no lambda helps.
  p.C = {(Eigen::MatrixXd(1, 2) << 1.0, 0.0).finished()};
  const auto und = buffer::critical_probability_bisection(p);
  EXPECT_FALSE(und.detectable);
  EXPECT_EQ(und.value, 1.0);
}

// Eq. (37) (SDP on CSDP) and the bisection on the fixed point agree to 1e-4: on both examples,
// on A = diag(2, -2), C = [1 1], and on random systems.
TEST(BufferDesign, CriticalProbabilityBySdpAgreesWithBisection) {
  std::vector<buffer::Plant> plants{example(1.0), example(1.2)};
  buffer::Plant d;
  d.A = Eigen::Vector2d(2.0, -2.0).asDiagonal();
  d.Q = Eigen::MatrixXd::Identity(2, 2);
  d.C = {Eigen::MatrixXd::Ones(1, 2)};
  d.R = {Eigen::MatrixXd::Identity(1, 1)};
  plants.push_back(d);
  std::mt19937_64 gen(37);
  std::normal_distribution<double> N01(0.0, 1.0);
  for (int r = 0; r < 8; ++r) {
    buffer::Plant p;
    const int n = 2 + r % 2;
    p.A = Eigen::MatrixXd::NullaryExpr(n, n, [&] { return N01(gen); });
    p.A *= (0.8 + 0.2 * r) / p.A.eigenvalues().cwiseAbs().maxCoeff();  // rho 0.8 .. 2.2
    const Eigen::MatrixXd G = Eigen::MatrixXd::NullaryExpr(n, n, [&] { return N01(gen); });
    p.Q = G * G.transpose() + 0.1 * Eigen::MatrixXd::Identity(n, n);
    p.C = {Eigen::MatrixXd::NullaryExpr(1, n, [&] { return N01(gen); })};
    p.R = {Eigen::MatrixXd::Identity(1, 1)};
    plants.push_back(p);
  }
  for (std::size_t i = 0; i < plants.size(); ++i) {
    const auto bis = buffer::critical_probability_bisection(plants[i]);
    const auto sdp = buffer::critical_probability_sdp(plants[i]);
    ASSERT_TRUE(std::isfinite(sdp.value)) << "plant " << i;
    EXPECT_NEAR(sdp.value, bis.value, 1e-4) << "plant " << i << " A =\n" << plants[i].A;
    EXPECT_GE(bis.value, bis.lower_bound - 1e-12);
  }
  EXPECT_NEAR(buffer::critical_probability_sdp(d).value, 0.9375, 1e-4);
}

// Issue 29, finding 12: the sensors' rows, stacked for lambda_c, are compressed to n whitened rows
// with the same information C' R^-1 C: Phi is the same map and lambda_c the same (by bisection
// and by the SDP) as on the full stack, for sensors with correlated noise and more rows than
// states.
TEST(BufferDesign, CompressedStackGivesTheSamePhiAndCriticalProbability) {
  std::mt19937_64 gen(29);
  std::normal_distribution<double> N01(0.0, 1.0);
  for (int r = 0; r < 4; ++r) {
    buffer::Plant p;
    const int n = 2 + r % 2;
    p.A = Eigen::MatrixXd::NullaryExpr(n, n, [&] { return N01(gen); });
    p.A *= (1.1 + 0.3 * r) / p.A.eigenvalues().cwiseAbs().maxCoeff();
    p.Q = Eigen::MatrixXd::Identity(n, n);
    for (int s = 0; s < 3; ++s) {
      const int rows = 1 + s % 2;
      p.C.push_back(Eigen::MatrixXd::NullaryExpr(rows, n, [&] { return N01(gen); }));
      const Eigen::MatrixXd G = Eigen::MatrixXd::NullaryExpr(rows, rows, [&] { return N01(gen); });
      p.R.push_back(G * G.transpose() + 0.1 * Eigen::MatrixXd::Identity(rows, rows));
    }
    const buffer::Plant full = buffer::stacked(p), small = buffer::compressed(p);
    ASSERT_EQ(small.C.front().rows(), n);
    const Eigen::MatrixXd P0 = Eigen::MatrixXd::Identity(n, n);
    for (double lambda : {0.3, 0.9}) {
      EXPECT_LT((buffer::phi(full, {lambda}, P0) - buffer::phi(small, {lambda}, P0)).norm(), 1e-10)
          << "plant " << r;
    }
    EXPECT_NEAR(buffer::critical_probability_bisection(p).value,
                buffer::critical_probability_bisection(full).value, 1e-6)
        << "plant " << r;
    EXPECT_NEAR(buffer::critical_probability_sdp(p).value,
                buffer::critical_probability_sdp(full).value, 1e-4)
        << "plant " << r;
  }
}

TEST(BufferDesign, StableExactlyForNAbove1MotorAndAbove7Pendulum) {
  for (int N = 1; N <= 16; ++N) {
    EXPECT_EQ(buffer::design_static_gains(example(1.0), {paper_lambda(N)}).stable, N > 1)
        << "motor N=" << N;
    EXPECT_EQ(buffer::design_static_gains(example(1.2), {paper_lambda(N)}).stable, N > 7)
        << "pendulum N=" << N;
  }
}

TEST(BufferDesign, CovarianceOfTheDesignedGainsThroughLEqualsTheorem3) {
  // T_N = fixed point of L_{lambda_{N-1}}(K_{N-1}, .), T_k = L_{lambda_k}(K_k, T_{k+1}) must give
  // V_0 of Theorem 3: this pins K_k = gain(V_{k+1}). Shifting the gains by one slot must not.
  for (double a : {1.0, 1.2}) {
    int strictly_worse = 0;
    for (int N = 2; N <= 16; ++N) {
      const auto p = example(a);
      const std::vector<std::vector<double>> lam{paper_lambda(N)};
      const auto g = buffer::design_static_gains(p, lam);
      if (!g.stable) continue;
      const auto T = buffer::covariances_of_gains(p, lam, g.K);
      ASSERT_EQ(T.size(), static_cast<std::size_t>(N) + 1);
      for (int k = 0; k <= N; ++k) {
        EXPECT_LT((T[static_cast<std::size_t>(k)] - g.V[static_cast<std::size_t>(k)])
                      .cwiseAbs()
                      .maxCoeff(),
                  1e-9 * (1.0 + g.V[static_cast<std::size_t>(k)].norm()))
            << "a=" << a << " N=" << N << " k=" << k;
      }
      // Another indexing, K_k = gain(V_k): strictly worse somewhere in the range tested.
      std::vector<buffer::Gains> shifted = g.K;
      for (int k = 0; k < N; ++k)
        shifted[static_cast<std::size_t>(k)] = buffer::slot_gains(
            p, {lam[0][static_cast<std::size_t>(k)]}, g.V[static_cast<std::size_t>(k)]);
      const auto Ts = buffer::covariances_of_gains(p, lam, shifted);
      if (!Ts.empty()) {
        EXPECT_GE(Ts[0].trace(), g.V[0].trace() - 1e-9)
            << "a=" << a << " N=" << N;  // Theorem 3 is optimal
        strictly_worse += Ts[0].trace() > g.V[0].trace() + 1e-9;
      }
    }
    EXPECT_GT(strictly_worse, 5) << "a=" << a;
  }
}

TEST(BufferDesign, FourthMomentRadiusMarksHeavyTailsOfThePendulum) {
  // Measured for this project: above 1 for the pendulum with N = 8..11, below from 12.
  for (int N = 8; N <= 16; ++N) {
    const auto g = buffer::design_static_gains(example(1.2), {paper_lambda(N)});
    EXPECT_LT(g.second_moment_radius, 1.0);
    EXPECT_EQ(g.fourth_moment_radius >= 1.0, N <= 11)
        << "N=" << N << " rho4=" << g.fourth_moment_radius;
  }
}

// ------------------------------------------------------------------------------------------
// kalman_buffer

// The filterpy peer vectors (tests/data/peers), replayed for buffer 1 and 4.
TEST(KalmanBuffer, MatchesFilterpyIntermittentObservationsStepByStepForBuffer1And4) {
  for (int N : {1, 4}) {
    toml::table t{{"buffer", N}, {"P0", toml::array{toml::array{1.0, 0.0}, toml::array{0.0, 1.0}}}};
    const auto design = make("kalman_buffer", t, testing::kf_peer_model());
    auto kf = design->instantiate();
    const testing::PeerReplay r = testing::replay_kf_peer(*kf);
    ASSERT_EQ(r.rows, 500) << "peer vectors not found or malformed";
    EXPECT_LT(r.worst, 1e-9) << "N=" << N << " " << r.where;
  }
}

TEST(KalmanBuffer, OutOfOrderLateDuplicateAndCounted) {
  // On a static plant (A = I, Q = 0) the posterior depends only on the set of samples used,
  // not on their order.
  Model model = testing::kf_peer_model();
  model.plant.A = Eigen::MatrixXd::Identity(2, 2);
  model.plant.W = Eigen::MatrixXd::Zero(2, 2);
  toml::table t{{"buffer", 3}, {"P0", toml::array{toml::array{1.0, 0.0}, toml::array{0.0, 1.0}}}};
  const auto design = make("kalman_buffer", t, model);
  const Eigen::VectorXd u0(0), drive = Eigen::VectorXd::Zero(2);
  auto in_order = design->instantiate();
  auto shuffled = design->instantiate();
  const Eigen::VectorXd y1 = Eigen::VectorXd::Constant(1, 1.0),
                        y2 = Eigen::VectorXd::Constant(1, 3.0);
  for (std::int64_t k = 0; k < 4; ++k) {
    if (k == 1) in_order->on_packet(packet(0, 1, y1), 1);
    if (k == 2) in_order->on_packet(packet(0, 2, y2), 2);
    if (k == 3) {
      EXPECT_EQ(shuffled->on_packet(packet(0, 2, y2), 3), 1);  // delay 1
      EXPECT_EQ(shuffled->on_packet(packet(0, 1, y1), 3), 1);  // delay 2 < 3, older arrives later
      EXPECT_EQ(shuffled->on_packet(packet(0, 1, y1), 3), 0);  // duplicate
      EXPECT_EQ(shuffled->on_packet(packet(0, 0, y1), 3), 0);  // delay 3 = N: discarded
    }
    in_order->on_period(k, PeriodInput{u0, drive});
    shuffled->on_period(k, PeriodInput{u0, drive});
  }
  EXPECT_LT((Eigen::VectorXd(in_order->state()) - Eigen::VectorXd(shuffled->state())).norm(),
            1e-12);
  EXPECT_LT((*in_order->covariance() - *shuffled->covariance()).norm(), 1e-12);
  const auto* c = shuffled->counters();
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(c->late, 1);
  EXPECT_EQ(c->duplicates, 1);
  EXPECT_EQ(c->periods, 4);
  EXPECT_GT(c->flops_worst, 0.0);
  EXPECT_LE(c->flops_worst, *design->flops_per_period());
}

// kalman_buffer (buffer N) and kalman_extended (max_delay N-1) use the same information: the
// same estimate at every period of the same realisation, over random links.
TEST(KalmanBuffer, EqualsKalmanExtendedWithMaxDelayNMinus1OverRandomLinks) {
  std::mt19937_64 gen(5);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const auto dir =
      std::filesystem::temp_directory_path() / ("ncosim_buffer_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  for (int trial = 0; trial < 8; ++trial) {
    const int N = 1 + trial % 5;
    auto num = [&](double lo, double hi) { return fmt::format("{:.4f}", lo + (hi - lo) * U(gen)); };
    std::string links;
    for (int l = 0; l < 2; ++l) {
      links += fmt::format("[[link]]\nname = \"net{}\"\n", l);
      switch ((trial + l) % 4) {
        case 0: {
          std::string pmf;
          double left = 0.9;
          for (int d = 0; d < N + 2; ++d) {
            const double p = left * U(gen) * 0.6;
            left -= p;
            pmf += fmt::format("{}{:.4f}", d ? ", " : "", p);
          }
          links += "kind = \"delay\"\npmf = [" + pmf + "]\n";
          break;
        }
        case 1:
          links += "kind = \"negative_binomial\"\nsuccesses = 2\np = " + num(0.3, 0.8) +
                   "\nloss = 0.1\n";
          break;
        case 2:
          links += "kind = \"delay\"\nindependent = true\npmf = [" + num(0.2, 0.5) + ", " +
                   num(0.1, 0.4) + "]\n";
          break;
        default:
          links +=
              "kind = \"gilbert_elliott\"\np_good_to_bad = 0.2\np_bad_to_good = 0.4\nloss_bad = "
              "0.9\n";
          break;
      }
    }
    std::string text = fmt::format(
        "[run]\nperiods = 400\nwarmup = 0\nruns = 1\nseed = {}\n\n"
        "[plant]\nA = [[{}, {}], [{}, {}]]\nBu = [[1.0], [0.5]]\nW = [[0.1, 0.02], [0.02, 0.2]]\n\n"
        "[input]\nkind = \"white\"\nstd = 1.0\n\n"
        "[[sensor]]\nC = [[1.0, {}]]\nR = [[0.05]]\nlink = \"net0\"\nbuffer = {}\n\n"
        "[[sensor]]\nC = [[{}, 1.0]]\nR = [[0.1]]\nlink = \"net1\"\n\n{}\n"
        "[[estimator]]\nname = \"kb\"\nkind = \"kalman_buffer\"\nbuffer = {}\nP0 = [[1.0, 0.0], "
        "[0.0, 1.0]]\n\n"
        "[[estimator]]\nname = \"ke\"\nkind = \"kalman_extended\"\nmax_delay = {}\nP0 = [[1.0, "
        "0.0], [0.0, 1.0]]\n",
        trial + 1, num(0.5, 1.1), num(-0.3, 0.3), num(-0.3, 0.3), num(0.4, 1.0), num(-1, 1),
        trial % 4 == 2 ? 0 : trial % 3, num(-1, 1), links, N, N - 1);
    const auto file = (dir / "s.toml").string();
    std::ofstream(file) << text;
    auto sc = testing::load_one(file);
    std::vector<sim::TraceRow> trace;
    sim::simulate_run(*sc, 0, &trace);
    double worst = 0.0;
    for (const auto& row : trace) {
      const double scale = 1.0 + std::abs(row.xhat[1][0]) + std::abs(row.xhat[1][1]);
      for (int i = 0; i < 2; ++i)
        worst = std::max(worst, std::abs(row.xhat[0][i] - row.xhat[1][i]) / scale);
    }
    EXPECT_LT(worst, 1e-9) << "trial " << trial << "\n" << text;
  }
  std::filesystem::remove_all(dir);
}

// ------------------------------------------------------------------------------------------
// static_buffer

TEST(StaticBuffer, DesignReportAndStatuses) {
  Model model;
  model.plant.A = example(1.2).A;
  model.plant.Bu = Eigen::MatrixXd::Zero(2, 0);
  model.plant.Bw = Eigen::MatrixXd::Identity(2, 2);
  model.plant.W = example(1.2).Q;
  model.plant.x0 = Eigen::VectorXd::Zero(2);
  std::vector<double> cdf;
  for (int h = 0; h < 16; ++h) cdf.push_back(0.05 * h);
  models::ArrivalCdfLink link(cdf, 0.75);
  SensorModel s;
  s.spec.C = example(1.2).C[0];
  s.spec.R = Eigen::MatrixXd::Identity(1, 1);
  s.spec.link = 0;
  s.link = &link;
  model.sensors.push_back(s);
  for (int N : {7, 8, 12}) {
    const auto d = make("static_buffer", toml::table{{"buffer", N}}, model);
    const auto& r = d->report();
    EXPECT_EQ(r.stable.value(), N > 7);
    EXPECT_NEAR(r.extra["critical_probability"].get<double>(), 1.0 - 1.0 / 1.44, 1e-6);
    auto e = d->instantiate();
    if (N == 7) {
      EXPECT_EQ(r.status.rfind("unstable", 0), 0u) << r.status;
      EXPECT_FALSE(r.predicted_mse.has_value());
    } else {
      const auto g = buffer::design_static_gains(example(1.2), {paper_lambda(N)});
      EXPECT_NEAR(r.predicted_mse.value(), g.filtered.trace(), 1e-12);
      EXPECT_NEAR(r.extra["trace_V0"].get<double>(), g.trace_V0, 1e-12);
      EXPECT_EQ(e->status(), N <= 11 ? "heavy_tail" : "ok");
      EXPECT_EQ(r.extra["heavy_tail"].get<bool>(), N <= 11);
    }
  }
  // max_delay = N - 1 is the same as buffer = N; both at once is an error.
  const auto a = make("static_buffer", toml::table{{"max_delay", 11}}, model);
  EXPECT_EQ(a->report().extra["buffer"].get<int>(), 12);
  EXPECT_THROW(make("static_buffer", toml::table{{"max_delay", 1}, {"buffer", 2}}, model),
               config::ScenarioError);
  EXPECT_THROW(make("static_buffer", toml::table{{"buffer", 0}}, model), config::ScenarioError);
}

// design.json of the committed pendulum scenario: the contract fields and the Schenato fields.
TEST(StaticBuffer, DesignJsonOfThePendulumScenario) {
  const auto loaded =
      sim::load_cases(testing::source_path("scenarios/schenato2008_pendulum.toml"), {});
  const auto j = sim::design_json(loaded);
  ASSERT_EQ(j["estimators"].size(), 32u);
  for (const auto& e : j["estimators"]) {
    for (const char* f : {"name", "kind", "method", "design_seconds", "stored_gains",
                          "predicted_mse", "predicted_mse_ext", "stable", "critical_probability",
                          "critical_probability_sdp", "critical_probability_bisection", "buffer"}) {
      EXPECT_TRUE(e.contains(f)) << f << " missing in " << e["name"];
    }
    EXPECT_NEAR(e["critical_probability"].get<double>(), 1.0 - 1.0 / 1.44, 1e-4);
    EXPECT_EQ(e["critical_probability_method"], "sdp");
    const int N = e["buffer"].get<int>();
    if (e["kind"] == "static_buffer") {
      EXPECT_EQ(e["stable"].get<bool>(), N > 7) << N;
      EXPECT_EQ(e["predicted_mse"].is_number(), N > 7) << N;
      EXPECT_EQ(e["trace_V0"].is_number(), N > 7) << N;
      EXPECT_TRUE(e["fourth_moment_radius"].is_number());
      EXPECT_EQ(e["gains"].size(), static_cast<std::size_t>(N));
    } else {
      EXPECT_EQ(e["kind"], "kalman_buffer");
      EXPECT_TRUE(e["stable"].is_null());
      EXPECT_TRUE(e["predicted_mse"].is_null());
      EXPECT_NEAR(e["lambda_buffer"][0].get<double>(), 0.05 * std::min(N - 1, 15), 1e-12);
    }
  }
}

}  // namespace
}  // namespace ncosim::est
