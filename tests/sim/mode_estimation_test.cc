// tests/sim/mode_estimation_test.cc — actuator links and the mode estimators in the campaign:
// the recorded mode, a noise-free case with MDE 0, reduction to the Kalman filter with ideal
// links, the on-time chain of a Markov link.
#include <gtest/gtest.h>

#include <cmath>

#include "models/actuator.h"
#include "models/link.h"
#include "sim/analysis/output.h"
#include "sim/run/campaign.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {
namespace {

std::unique_ptr<Scenario> from_text(const std::string& text) {
  return build_scenario(toml::parse(text, std::string_view("test.toml")), "test.toml", ".");
}

// Two-input plant (the CSTR's A scaled to be stable, its Bu), both inputs behind Markov
// links, both sensors behind a Bernoulli link; the three mode estimators and a Kalman filter.
std::string two_channel(const std::string& on_loss, const std::string& r, const std::string& w,
                        const std::string& act_link, const std::string& sensor_link, int runs,
                        const std::string& extra_estimators = "") {
  return R"(
[run]
periods = 201
warmup = 1
runs = )" +
         std::to_string(runs) + R"(
seed = 11
[plant]
A = [[-0.8882, -0.0097], [293.8556, 2.2973]]
Bu = [[0.011, -0.0014], [-0.3602, 0.4732]]
W = )" + w +
         R"(
x0 = [0.5, -0.5]
[input]
kind = "white"
std = 10.0
[[link]]
name = "act"
kind = "markov"
transition = [[0.8, 0.2], [0.4, 0.6]]
loss = [0.0, 1.0]
[[link]]
name = "sens"
kind = "bernoulli"
loss = 0.2
[[sensor]]
C = [[1.0, 0.0], [0.0, 1.0]]
R = )" + r +
         sensor_link + R"(
[[actuator]]
)" + act_link +
         "on_loss = \"" + on_loss + R"("
[[actuator]]
)" + act_link +
         "on_loss = \"" + on_loss + R"("
[[estimator]]
name = "alg1"
kind = "mode_io"
xhat0 = [0.5, -0.5]
[[estimator]]
name = "alg2"
kind = "mode_ss"
xhat0 = [0.5, -0.5]
[[estimator]]
name = "imm"
kind = "imm"
xhat0 = [0.5, -0.5]
)" + extra_estimators;
}

TEST(Actuator, HoldAndZeroApplyWhatArrivesAndNumberModesAsTable1) {
  // Channel 0 ideal, channel 1 always lost (bernoulli loss 1): mode = (delivered, lost) = 1.
  models::BernoulliLink lost(1.0, 0);
  std::vector<models::ActuatorSpec> specs(2);
  specs[1].link = 0;
  specs[1].u0 = 7.0;
  specs[1].on_loss = models::ActuatorSpec::OnLoss::kHold;
  models::ActuatorStage hold(specs, {&lost}, 1, 0);
  EXPECT_EQ(hold.actuate(Eigen::Vector2d(1.0, 2.0)), 1);
  EXPECT_EQ(hold.applied(), Eigen::Vector2d(1.0, 7.0));  // channel 1 holds u0
  specs[1].on_loss = models::ActuatorSpec::OnLoss::kZero;
  models::ActuatorStage zero(specs, {&lost}, 1, 0);
  EXPECT_EQ(zero.actuate(Eigen::Vector2d(1.0, 2.0)), 1);
  EXPECT_EQ(zero.applied(), Eigen::Vector2d(1.0, 0.0));
  EXPECT_TRUE(models::channel_delivered(1, 0, 2));
  EXPECT_FALSE(models::channel_delivered(1, 1, 2));
  EXPECT_FALSE(models::channel_delivered(2, 0, 2));
}

TEST(Actuator, MarkovOnTimeChainIsThePapersChain) {
  // States (delivered, lost) with loss (0, 1): the on-time process is the chain itself.
  Eigen::MatrixXd T(2, 2);
  T << 0.8, 0.2, 0.4, 0.6;
  models::MarkovLink link(T, {0.0, 1.0});
  EXPECT_NEAR((link.on_time_chain() - Eigen::Matrix2d(T)).cwiseAbs().maxCoeff(), 0.0, 1e-12);
  // Independent packets: both rows are (p, 1 - p).
  models::BernoulliLink b(0.3, 0);
  EXPECT_NEAR(b.on_time_chain()(1, 0), 0.7, 1e-15);
  EXPECT_NEAR(b.on_time_chain()(0, 0), 0.7, 1e-15);
}

// A jump_linear plant whose modes differ in the sign of Bu, driven by a white input of std 10:
// the mode is wrong only when |u| is within a few prediction sds (about 0.15) of 0, P ~ 0.01-0.02
// per period. 4 runs x 200 periods: an MDE above 5 % would be more than 10 sds off.
TEST(ModeEstimation, JumpLinearPlantModesAreEstimatedAndScored) {
  auto sc = from_text(R"(
[run]
periods = 201
warmup = 1
runs = 4
[plant]
kind = "jump_linear"
A = [[0.7]]
Bu = [[1.0]]
W = [[0.01]]
transition = [[0.9, 0.1], [0.2, 0.8]]
[[plant.mode]]
[[plant.mode]]
Bu = [[-1.0]]
[input]
kind = "white"
std = 10.0
[[sensor]]
C = [[1.0]]
R = [[0.01]]
[[estimator]]
kind = "imm"
[[estimator]]
kind = "mode_ss"
[[estimator]]
kind = "kalman_extended"
)");
  CampaignOptions opt;
  opt.time_estimators = false;
  const auto rows = summarise(*sc, run_campaign(*sc, opt), {});
  for (std::size_t e = 0; e < 2; ++e) {
    SCOPED_TRACE(rows[e].kind);
    ASSERT_TRUE(rows[e].mde_percent.has_value());
    EXPECT_LT(*rows[e].mde_percent, 5.0);
    EXPECT_EQ(rows[e].modes, 2);
  }
  EXPECT_FALSE(rows[2].mde_percent.has_value());  // not a mode estimator
}

TEST(Actuator, WrongCountOrJumpPlantIsABadInputError) {
  std::string text = two_channel("hold", "[[1e-4, 0], [0, 1e-4]]", "[[0, 0], [0, 0]]", "", "", 1);
  const auto second = text.find("[[actuator]]", text.find("[[actuator]]") + 1);
  text.erase(second, std::string("[[actuator]]\non_loss = \"hold\"\n").size());
  try {
    from_text(text);
    ADD_FAILURE() << "one actuator for two inputs accepted";
  } catch (const config::ScenarioError& e) {
    EXPECT_NE(std::string(e.what()).find("one [[actuator]] per input channel (2), got 1"),
              std::string::npos)
        << e.what();
  }
  // mode_io needs actuator modes; an actuator with a jump_linear plant is rejected.
  const std::string jump = R"(
[plant]
kind = "jump_linear"
A = [[0.7]]
Bu = [[1.0]]
W = [[0.01]]
transition = [[0.9, 0.1], [0.2, 0.8]]
[[plant.mode]]
[[plant.mode]]
A = [[0.2]]
[[sensor]]
C = [[1.0]]
R = [[0.01]]
)";
  EXPECT_THROW(from_text(jump + "[[estimator]]\nkind = \"mode_io\"\n"), config::ScenarioError);
  EXPECT_THROW(from_text(jump + "[[actuator]]\n[[estimator]]\nkind = \"imm\"\n"),
               config::ScenarioError);
  // A mode estimator without modes says what it needs.
  try {
    from_text(
        "[plant]\nA = [[0.5]]\nW = [[1]]\n[[sensor]]\nC = [[1]]\nR = [[1]]\n[[estimator]]\nkind = "
        "\"imm\"\n");
    ADD_FAILURE() << "imm without modes accepted";
  } catch (const config::ScenarioError& e) {
    EXPECT_NE(std::string(e.what()).find("expected a scenario with modes"), std::string::npos)
        << e.what();
  }
}

// Practically noise-free (R = 1e-14 I, sigma 1e-7, against inputs of sigma 10 and no process
// noise): y[k] determines the applied input up to 1e-5, so every estimator must recover the
// delivery pattern at every period: MDE exactly 0, for the hold and the zero strategy (ideal
// sensor link: a period without output would leave its mode to the chain's prediction).
TEST(ModeEstimation, ObservableModeWithoutNoiseGivesZeroMde) {
  for (const std::string strategy : {"hold", "zero"}) {
    auto sc = from_text(two_channel(strategy, "[[1e-14, 0], [0, 1e-14]]", "[[0, 0], [0, 0]]",
                                    "link = \"act\"\n", "", 4));
    CampaignOptions opt;
    opt.time_estimators = false;
    const auto rows = summarise(*sc, run_campaign(*sc, opt), {});
    for (const auto& r : rows) {
      SCOPED_TRACE(strategy + " " + r.estimator);
      ASSERT_TRUE(r.mde_percent.has_value());
      EXPECT_EQ(*r.mde_percent, 0.0);
      EXPECT_EQ(r.status, "ok");
      // Every (true, estimated) pair is on the diagonal; 4 runs x 200 scored periods.
      std::int64_t total = 0, diagonal = 0;
      for (int t = 0; t < r.modes; ++t) {
        for (int e = 0; e < r.modes; ++e)
          total += r.confusion[static_cast<std::size_t>(t * r.modes + e)];
        diagonal += r.confusion[static_cast<std::size_t>(t * r.modes + t)];
      }
      EXPECT_EQ(total, 4 * 200);
      EXPECT_EQ(diagonal, total);
    }
  }
}

// Ideal actuators (no link): only mode 0 is reachable, so every mode estimator is the Kalman
// filter of the plant (the held inputs are known: u0 with zero covariance, then the delivered
// u). With process noise and a lossy sensor link, each estimate must equal kalman_extended's
// (max_delay = 0, same xhat0 and P0) to 1e-9 at every period of run 0.
TEST(ModeEstimation, IdealLinksReduceEveryEstimatorToTheKalmanFilter) {
  for (const std::string strategy : {"hold", "zero"}) {
    auto sc = from_text(two_channel(
        strategy, "[[0.01, 0], [0, 0.02]]", "[[0.01, 0], [0, 0.04]]", "", "\nlink = \"sens\"", 1,
        "[[estimator]]\nname = \"kf\"\nkind = \"kalman_extended\"\nxhat0 = [0.5, -0.5]\n"));
    std::vector<TraceRow> trace;
    simulate_run(*sc, 0, &trace);
    ASSERT_EQ(trace.size(), 201U);
    double worst = 0.0;
    for (const auto& row : trace) {
      for (std::size_t e = 0; e < 3; ++e) {
        for (std::size_t i = 0; i < 2; ++i) {
          const double ref = row.xhat[3][i];
          worst = std::max(worst, std::abs(row.xhat[e][i] - ref) / std::max(1.0, std::abs(ref)));
        }
        if (row.period > 0) {
          EXPECT_EQ(row.mode_hat[e], 0);
        }
      }
    }
    EXPECT_LT(worst, 1e-9) << strategy;
    std::printf("%s: worst relative difference to the Kalman filter %.3g\n", strategy.c_str(),
                worst);
  }
}

// The recorded mode is the actuators' delivery pattern: with the paper's chains the share of
// periods with both inputs delivered is (2/3)^2 = 4/9 (stationary start). 20 runs x 200
// periods = 4000 draws, positively correlated (chain eigenvalue 0.4): sd <= sqrt(p(1-p)/4000 *
// (1 + 0.4)/(1 - 0.4)) ~ 0.012, so |share - 4/9| < 0.05 is over 4 sd.
TEST(ModeEstimation, TrueModeFollowsTheLinksStationaryLaw) {
  auto sc = from_text(two_channel("hold", "[[1e-4, 0], [0, 1e-4]]", "[[0, 0], [0, 0]]",
                                  "link = \"act\"\n", "", 20));
  std::int64_t all = 0, zero = 0;
  for (std::uint64_t run = 0; run < 20; ++run) {
    std::vector<TraceRow> trace;
    simulate_run(*sc, run, &trace);
    for (const auto& row : trace) {
      if (row.mode < 0) continue;
      ++all;
      zero += row.mode == 0;
    }
  }
  EXPECT_EQ(all, 20 * 200);
  EXPECT_NEAR(static_cast<double>(zero) / static_cast<double>(all), 4.0 / 9.0, 0.05);
}

}  // namespace
}  // namespace ncosim::sim
