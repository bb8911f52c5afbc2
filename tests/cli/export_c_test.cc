// tests/cli/export_c_test.cc — `ncosim design --export-c`: the exported C99 compiles with
// cc -std=c99 -Wall -Werror -pedantic, selects the same gain as the C++ estimator for every
// (N, pattern), and tracks the C++ jump estimator on a recorded run (packets with buffered,
// delayed and out-of-window samples, multi-output sensor, random inputs, samples of a simulated
// plant) to 1e-12.
#include "estimators/export_c.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using namespace ncosim;

const std::string kBinary = NCOSIM_BINARY;
const fs::path kFixture = fs::path(NCOSIM_SOURCE_DIR) / "tests" / "cli" / "data" / "export.toml";

using Outcome = ncosim::testing::CommandOutcome;

Outcome shell(const std::string& cmd) { return ncosim::testing::run_shell(cmd); }

fs::path fresh_dir(const std::string& name) {
  const fs::path d =
      fs::temp_directory_path() / fmt::format("ncosim_export_{}_{}", name, ::getpid());
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// The replay driver: R sensor delay ny v... (a received sample), S d... (a step with drive d;
// prints the extended state), G (prints the gain index of every N in 1..NBAR+1 and pattern).
std::string driver(const std::string& p) {
  std::string u = p;
  for (char& c : u) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  std::string src = R"(#include <stdio.h>
#include "@p.h"
int main(void) {
  @p_state s;
  char op;
  int i, sensor, delay, ny;
  unsigned int N;
  unsigned long m;
  double y[16], d[@U_N];
  @p_init(&s);
  while (scanf(" %c", &op) == 1) {
    if (op == 'R') {
      if (scanf("%d %d %d", &sensor, &delay, &ny) != 3 || ny > 16) return 2;
      for (i = 0; i < ny; ++i) {
        if (scanf("%lf", &y[i]) != 1) return 2;
      }
      printf("r %d\n", @p_receive(&s, sensor, delay, y));
    } else if (op == 'S') {
      for (i = 0; i < @U_N; ++i) {
        if (scanf("%lf", &d[i]) != 1) return 2;
      }
      @p_step(&s, d);
      printf("x");
      for (i = 0; i < @U_NB; ++i) printf(" %.17g", s.x[i]);
      printf("\n");
    } else if (op == 'G') {
      for (N = 1; N <= @U_NBAR + 1; ++N) {
        for (m = 0; m < (1UL << @U_NF); ++m) printf("%d\n", @p_gain_index(N, m));
      }
    } else {
      return 2;
    }
  }
  return 0;
}
)";
  std::string out;
  for (std::size_t i = 0; i < src.size(); ++i) {
    if (src[i] == '@' && src[i + 1] == 'p') {
      out += p;
      ++i;
    } else if (src[i] == '@' && src[i + 1] == 'U') {
      out += u;
      ++i;
    } else {
      out += src[i];
    }
  }
  return out;
}

TEST(CIdentifier, SanitisedUniqueAndValid) {
  std::vector<std::string> taken;
  EXPECT_EQ(est::c_identifier("S4, 60 gains", taken), "s4_60_gains");
  EXPECT_EQ(est::c_identifier("S4, 60 gains!", taken), "s4_60_gains_2");
  EXPECT_EQ(est::c_identifier("4th: S4 (int)", taken), "jump_4th_s4_int");
  EXPECT_EQ(est::c_identifier("  ", taken), "jump");
  EXPECT_EQ(est::c_identifier("***", taken), "jump_2");
  EXPECT_EQ(est::c_identifier("double", taken), "double_");
  EXPECT_EQ(est::c_identifier("Ñandú_x", taken), "and_x");
}

TEST(ExportC, CompilesSelectsAndTracksTheCppEstimatorTo1e12) {
  if (shell("cc --version").code != 0) GTEST_SKIP() << "no C compiler (cc) on this machine";
  const fs::path dir = fresh_dir("c");
  const Outcome o =
      shell(fmt::format("'{}' design '{}' --out '{}' --export-c '{}'", kBinary, kFixture.string(),
                        (dir / "design").string(), (dir / "c").string()));
  ASSERT_EQ(o.code, 0) << o.output;
  EXPECT_NE(o.output.find("\"Kalman\" skipped"), std::string::npos) << o.output;

  auto sc = ncosim::testing::load_one(kFixture.string());
  std::vector<std::string> taken;
  int exported = 0;
  for (const auto& entry : sc->estimators) {
    const est::JumpDesignAccess* jump = entry.design->c_export();
    if (jump == nullptr) continue;
    ++exported;
    const std::string p = est::c_identifier(entry.name, taken);
    SCOPED_TRACE(entry.name + " -> " + p);
    ASSERT_TRUE(fs::exists(dir / "c" / (p + ".h")));
    ASSERT_TRUE(fs::exists(dir / "c" / (p + ".c")));
    { std::ofstream(dir / "c" / (p + "_driver.c")) << driver(p); }
    const fs::path exe = dir / "c" / (p + "_driver");
    const Outcome cc = shell(fmt::format(
        "cc -std=c99 -Wall -Werror -pedantic -O2 -I'{0}' '{0}/{1}.c' '{0}/{1}_driver.c' -o '{2}'",
        (dir / "c").string(), p, exe.string()));
    ASSERT_EQ(cc.code, 0) << cc.output;

    // The recorded run: packets of both sensors (buffered samples, delays beyond dbar) and inputs.
    const est::ExtendedModel& ext = jump->extended_model();
    const est::JumpDesign& design = jump->jump_design();
    auto estimator = entry.design->instantiate();
    std::mt19937_64 rng(2024);
    std::normal_distribution<double> normal(0.0, 1.0);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    std::string script = "G\n";
    std::vector<Eigen::VectorXd> expected;
    Eigen::VectorXd last_drive = Eigen::VectorXd::Zero(sc->model.plant.n());
    const int periods = 3000;
    const Eigen::Index n = ext.n;
    // The plant, simulated here so that the samples are those of a real run.
    const auto& plant = sc->model.plant;
    std::vector<Eigen::VectorXd> xtrue{Eigen::VectorXd::Zero(n)};
    for (std::int64_t k = 0; k < periods; ++k) {
      if (k > 0) {
        Eigen::VectorXd w(plant.nw());
        for (Eigen::Index i = 0; i < w.size(); ++i) w(i) = normal(rng);
        xtrue.push_back(plant.A * xtrue.back() + last_drive +
                        plant.Bw * (plant.W.llt().matrixL() * w));
      }
      for (int s = 0; s < static_cast<int>(sc->model.sensors.size()); ++s) {
        const auto& spec = sc->model.sensors[static_cast<std::size_t>(s)].spec;
        if (uniform(rng) < 0.45) continue;  // nothing from this sensor at k
        est::Packet pk;
        pk.sensor = s;
        const std::int64_t delay = static_cast<std::int64_t>(uniform(rng) * (ext.dbar + 3));
        pk.send_period = k - delay;
        for (int c = 0; c <= spec.buffer; ++c) {
          if (pk.send_period - c >= 0) pk.stamps.push_back(pk.send_period - c);
        }
        pk.count = static_cast<int>(pk.stamps.size());
        if (pk.count == 0) continue;
        pk.values.resize(pk.count * spec.ny());
        for (int i = 0; i < pk.count; ++i) {
          const Eigen::VectorXd y =
              spec.C * xtrue[static_cast<std::size_t>(pk.stamps[static_cast<std::size_t>(i)])];
          for (Eigen::Index r = 0; r < spec.ny(); ++r)
            pk.values(i * spec.ny() + r) = y(r) + 0.1 * normal(rng);
        }
        estimator->on_packet(pk, k);
        for (int i = 0; i < pk.count; ++i) {
          script +=
              fmt::format("R {} {} {}", s, k - pk.stamps[static_cast<std::size_t>(i)], spec.ny());
          for (Eigen::Index r = 0; r < spec.ny(); ++r)
            script += fmt::format(" {:.17g}", pk.values(i * spec.ny() + r));
          script += "\n";
        }
      }
      Eigen::VectorXd u(sc->model.plant.nu());
      for (Eigen::Index i = 0; i < u.size(); ++i) u(i) = normal(rng);
      const Eigen::VectorXd drive = sc->model.plant.Bu * u;
      last_drive = drive;
      estimator->on_period(k, est::PeriodInput{u, drive});
      script += "S";
      for (Eigen::Index i = 0; i < n; ++i) script += fmt::format(" {:.17g}", drive(i));
      script += "\n";
      expected.push_back(*estimator->extended());
    }
    { std::ofstream(dir / "c" / (p + ".in")) << script; }
    const Outcome run =
        shell(fmt::format("'{}' < '{}'", exe.string(), (dir / "c" / (p + ".in")).string()));
    ASSERT_EQ(run.code, 0) << run.output.substr(0, 500);
    std::istringstream lines(run.output);
    std::string line;
    // Gain selection: every N (one beyond Nbar: saturation) and every pattern.
    for (int N = 1; N <= design.Nbar + 1; ++N) {
      for (std::uint64_t m = 0; m < (std::uint64_t{1} << ext.fictitious_count()); ++m) {
        ASSERT_TRUE(std::getline(lines, line));
        const int want =
            m == 0 ? -1 : design.gain_of[static_cast<std::size_t>(std::min(N, design.Nbar) - 1)][m];
        ASSERT_EQ(std::stoi(line), want) << "N = " << N << ", pattern = " << m;
      }
    }
    // Tracking.
    std::size_t step = 0;
    double worst = 0.0, largest = 0.0;
    int used = 0;
    while (std::getline(lines, line)) {
      if (line.rfind("r ", 0) == 0) {
        used += line == "r 1" ? 1 : 0;
        continue;
      }
      ASSERT_EQ(line[0], 'x');
      ASSERT_LT(step, expected.size());
      std::istringstream xs(line.substr(1));
      for (Eigen::Index i = 0; i < ext.nb; ++i) {
        double v = 0.0;
        ASSERT_TRUE(xs >> v);
        const double want = expected[step](i);
        worst = std::max(worst, std::abs(v - want) / std::max(1.0, std::abs(want)));
        largest = std::max(largest, std::abs(want));
      }
      ++step;
    }
    EXPECT_EQ(step, static_cast<std::size_t>(periods));
    EXPECT_GT(used, periods / 2) << "the recorded run must exercise the updates";
    EXPECT_LE(worst, 1e-12) << "largest |x| " << largest;
    std::printf(
        "%-16s %zu steps, %d samples used, worst relative difference %.3g (|x| up to %.3g)\n",
        p.c_str(), step, used, worst, largest);
  }
  EXPECT_EQ(exported, 4);
  fs::remove_all(dir);
}

TEST(ExportC, FailedDesignOrNoJumpEstimatorIsAnErrorAndWritesNothing) {
  const fs::path dir = fresh_dir("bad");
  // A3 with every packet lost: the design fails; nothing may be written.
  const Outcome o = shell(
      fmt::format("'{}' design '{}' --set 'link[0].pmf=[0.0]' --set 'link[1].pmf=[0.0]' --out '{}' "
                  "--export-c '{}'",
                  kBinary, kFixture.string(), (dir / "design").string(), (dir / "c").string()));
  EXPECT_EQ(o.code, 1) << o.output;
  EXPECT_NE(o.output.find("the design failed"), std::string::npos) << o.output;
  EXPECT_FALSE(fs::exists(dir / "c"));
  EXPECT_FALSE(fs::exists(dir / "design" / "design.json"));
  fs::remove_all(dir);
}

}  // namespace

namespace {

TEST(ExportC, SweepCasesGetTheirOwnNamesAndAllCompile) {
  if (shell("cc --version").code != 0) GTEST_SKIP() << "no C compiler (cc) on this machine";
  const fs::path dir = fresh_dir("sweep");
  const fs::path fig5 = fs::path(NCOSIM_SOURCE_DIR) / "scenarios" / "dolz2014_fig5.toml";
  const Outcome o = shell(
      fmt::format("'{}' design '{}' --set 'sweep[0].values=[0.9, 0.95]' --out '{}' --export-c '{}'",
                  kBinary, fig5.string(), (dir / "design").string(), (dir / "c").string()));
  ASSERT_EQ(o.code, 0) << o.output;
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir / "c"))
    files += e.path().extension() == ".c" ? 1 : 0;
  EXPECT_EQ(files, 8);  // 2 cases x 4 estimators
  EXPECT_TRUE(fs::exists(dir / "c" / "s4_n1_b0_case1.h"));
  EXPECT_TRUE(fs::exists(dir / "c" / "s4_n4_b3_case2.c"));
  // Every file compiles, and all of them link together (no symbol clash).
  const Outcome cc = shell(
      fmt::format("cd '{}' && cc -std=c99 -Wall -Werror -pedantic -c *.c && ld -r *.o -o all.o",
                  (dir / "c").string()));
  EXPECT_EQ(cc.code, 0) << cc.output;
  fs::remove_all(dir);
}

}  // namespace
