// tests/sim/validity_test.cc — the model_check note: prediction against simulation, and the
// departures from the design model that make the comparison meaningless.
#include "sim/analysis/validity.h"

#include <gtest/gtest.h>

#include "sim/analysis/output.h"
#include "test_util.h"

namespace ncosim::sim {
namespace {

using testing::load_one;
using testing::source_path;

const std::string kTable2 = source_path("scenarios/dolz2014_table2.toml");
constexpr std::size_t kS4 = 4;  // "S4, 60 gains"

// A row of the S4 observer with a simulated mse_ext and its 95 % half-width over 20 runs.
SummaryRow s4_row(const Scenario& sc, double simulated, double ci95) {
  SummaryRow r;
  r.estimator = sc.estimators[kS4].name;
  r.runs = 20;
  r.status = "ok";
  r.predicted_mse_ext = sc.estimators[kS4].design->report().predicted_mse_ext;
  r.mse_ext = simulated;
  r.mse_ext_ci95 = ci95;
  return r;
}

TEST(ModelCheck, IndependentCopiesFollowTheModelAndAreCheckedAgainstTheMonteCarloError) {
  auto sc = load_one(kTable2, {"link[0].independent=true", "link[1].independent=true"});
  EXPECT_EQ(design_model_departure(*sc, kS4), "");
  const double p = sc->estimators[kS4].design->report().predicted_mse_ext.value();
  // t_{0.9995,19} / t_{0.975,19} = 3.8834 / 2.0930 = 1.8554: a 95 % half-width of 0.001 is a
  // 99.9 % MC error of 0.00186.
  const std::string near = model_check_note(*sc, kS4, s4_row(*sc, p + 0.0018, 0.001));
  EXPECT_EQ(near.rfind("consistent: simulated mse_ext", 0), 0u) << near;
  const std::string far = model_check_note(*sc, kS4, s4_row(*sc, p + 0.0019, 0.001));
  EXPECT_EQ(far.rfind("MISMATCH: simulated mse_ext", 0), 0u) << far;
  EXPECT_NE(far.find("beyond the 99.9 % MC error 0.0019"), std::string::npos) << far;
  // No simulated value (diverged) or a single run: said, not compared.
  SummaryRow none = s4_row(*sc, p, 0.001);
  none.mse_ext.reset();
  none.status = "diverged";
  EXPECT_EQ(
      model_check_note(*sc, kS4, none).rfind("no simulated mse_ext to check (status diverged)", 0),
      0u);
  // The Kalman filter has no prediction: no note.
  SummaryRow kf;
  kf.runs = 20;
  kf.mse_ext = 0.04;
  EXPECT_EQ(model_check_note(*sc, 5, kf), "");
}

TEST(ModelCheck, DeparturesFromTheDesignModelAreNamed) {
  // The flagship as committed: physical packets, delays 0 and 1 both possible.
  auto phys = load_one(kTable2);
  const std::string d = design_model_departure(*phys, kS4);
  EXPECT_EQ(d,
            "physical packets on delay links 'net1', 'net2': one copy per sample, several possible "
            "delays <= "
            "max_delay; the design assumes independent copies per delay");
  const std::string note = model_check_note(*phys, kS4, s4_row(*phys, 0.0449, 0.0004));
  EXPECT_EQ(note.rfind("design model not followed (physical packets", 0), 0u) << note;
  EXPECT_NE(note.find("simulated 0.0449"), std::string::npos) << note;
  // With max_delay = 0 only delay 0 counts: one possible delay, the model holds.
  auto d0 = load_one(kTable2, {"estimator[4].max_delay=0"});
  EXPECT_EQ(design_model_departure(*d0, kS4), "");
  // Bursty losses.
  auto ge = load_one(
      kTable2,
      {"link=[{name=\"net1\", kind=\"gilbert_elliott\", p_good_to_bad=0.1, p_bad_to_good=0.3}, "
       "{name=\"net2\", kind=\"delay\", pmf=[0.3761, 0.3403]}]"});
  EXPECT_EQ(design_model_departure(*ge, kS4),
            "link 'net1' (gilbert_elliott): bursty or recorded losses; the design uses only the "
            "marginal law; "
            "physical packets on delay link 'net2': one copy per sample, several possible delays "
            "<= max_delay; the "
            "design assumes independent copies per delay");
}

}  // namespace
}  // namespace ncosim::sim
