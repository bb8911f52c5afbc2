// tests/sim/compare_test.cc — `ncosim compare` in process: reading folders, matching rows and
// runs, the paired and unpaired rank tests, tolerance, verdicts, intervals that read as their
// verdicts, exit codes and bad input.
#include "sim/analysis/compare.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "sim/analysis/compare_manifest.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {
namespace {

namespace fs = std::filesystem;

// A folder with manifest.json and runs.csv: estimators "A, x" and "B" (A's name needs quoting),
// `runs` runs each with mse = level * (1 + 0.1 z_run) + 0.001 z (a shared run effect, as the
// common random numbers give), scaled by `scale_b` for B; every value times `level`.
struct Folder {
  fs::path dir;
  explicit Folder(const std::string& name)
      : dir(fs::temp_directory_path() / ("ncosim_compare_" + name)) {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Folder() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  void write(const std::string& hash, std::uint64_t seed, int runs, double scale_b,
             int diverged_b = -1, const std::string& drop = "", std::uint64_t noise_seed = 0,
             double level = 1.0) const {
    std::ofstream(dir / "manifest.json")
        << "{\"scenario\": \"x.toml\", \"scenario_hash\": \"" << hash << "\", \"seed\": " << seed
        << ", \"title\": \"t\"}\n";
    std::mt19937_64 g(noise_seed == 0 ? seed : noise_seed);
    std::normal_distribution<double> z;
    std::ofstream out(dir / "runs.csv");
    out << "run,estimator,mse,mse_ext,periods,samples_used,samples_taken,diverged,status,flops_"
           "mean,late_samples,"
           "duplicate_samples,mde_percent,rmse_x1\n";
    for (int r = 0; r < runs; ++r) {
      const double shared = 1.0 + 0.1 * z(g);
      const double a = level * (shared + 0.001 * z(g));
      const double b = level * scale_b * (shared + 0.001 * z(g));
      if (drop != "A, x")
        out << r << ",\"A, x\"," << a << ",,"
            << "100,1,1,0,ok,,,,,1\n";
      if (drop != "B") {
        if (r == diverged_b) {
          out << r << ",B,,,50,1,1,1,ok,,,,,\n";
        } else {
          out << r << ",B," << b << ",,100,1,1,0,ok,,,,,1\n";
        }
      }
    }
  }
  std::string str() const { return dir.string(); }
  // Adds (or replaces) fields of manifest.json, as `ncosim run` writes them.
  void add_to_manifest(const nlohmann::json& fields) const {
    nlohmann::json m;
    std::ifstream(dir / "manifest.json") >> m;
    m.update(fields);
    std::ofstream(dir / "manifest.json") << m.dump(2) << "\n";
  }
};

CompareResult run(const Folder& b, const Folder& n, CompareOptions o = {}) {
  return compare_folders(read_run_folder(b.str(), o.metric), read_run_folder(n.str(), o.metric), o);
}

const CompareRow& row(const CompareResult& r, const std::string& name) {
  for (const auto& x : r.rows) {
    if (x.estimator == name) return x;
  }
  throw std::runtime_error("no row " + name);
}

TEST(Compare, IdenticalFoldersAreUnchangedAndExitZero) {
  Folder b("id_b"), n("id_n");
  b.write("h", 7, 20, 1.0);
  n.write("h", 7, 20, 1.0);
  const auto r = run(b, n);
  ASSERT_EQ(r.rows.size(), 2u);
  EXPECT_EQ(row(r, "A, x").verdict, "unchanged");
  EXPECT_EQ(row(r, "A, x").test, "paired");
  EXPECT_EQ(row(r, "A, x").pairs, 20u);
  EXPECT_EQ(*row(r, "A, x").diff, 0.0);
  EXPECT_EQ(r.exit_code(), 0);
}

TEST(Compare, PairedTestFlagsAOnePercentRegressionThatTheUnpairedTestCannotTell) {
  // B is 1 % worse on every run; the run-to-run spread (10 %) hides it from an unpaired test
  // (SE ~ 0.1 sqrt(2/20) = 3.2 %) but the per-run ratios have spread ~0.14 %.
  Folder b("reg_b"), n("reg_n"), w("reg_w");
  b.write("h", 7, 20, 1.0);
  n.write("h", 7, 20, 1.01);
  CompareOptions half;  // a tolerance of 0.5 %: +1 % is beyond it
  half.tolerance = 0.005;
  const auto r = run(b, n, half);
  EXPECT_EQ(row(r, "B").verdict, "worse");
  EXPECT_EQ(row(r, "B").test, "paired");
  EXPECT_NEAR(*row(r, "B").relative, 0.01, 0.002);
  EXPECT_LT(*row(r, "B").relative_low, 0.01);
  EXPECT_GT(*row(r, "B").relative_high, 0.01);
  EXPECT_EQ(row(r, "A, x").verdict, "unchanged");
  EXPECT_EQ(r.exit_code(), 1);
  // A different seed in NEW: no common runs, unpaired; 20 runs of 10 % spread can neither show
  // +1 % nor its absence within 0.5 %: inconclusive (exit 4), not "unchanged".
  w.write("h", 8, 20, 1.01);
  const auto u = run(b, w, half);
  EXPECT_EQ(row(u, "B").test, "unpaired");
  EXPECT_EQ(row(u, "B").note, "different seeds: unpaired");
  EXPECT_EQ(row(u, "B").verdict, "inconclusive");
  EXPECT_EQ(u.exit_code(), kCompareInconclusive);
  half.allow_inconclusive = true;
  EXPECT_EQ(run(b, w, half).exit_code(), 0);
  // Within a 2 % tolerance the same +1 % is unchanged (shown inside the band), and within the
  // default 5 % too.
  CompareOptions tol;
  tol.tolerance = 0.02;
  EXPECT_EQ(row(run(b, n, tol), "B").verdict, "unchanged");
  EXPECT_EQ(row(run(b, n), "B").verdict, "unchanged");
}

TEST(Compare, ImprovementIsBetterAndDivergenceIsWorse) {
  Folder b("div_b"), n("div_n");
  b.write("h", 7, 10, 1.0);
  n.write("h", 7, 10, 0.97);
  CompareOptions one;
  one.tolerance = 0.01;
  EXPECT_EQ(row(run(b, n, one), "B").verdict, "better");
  EXPECT_EQ(row(run(b, n), "B").verdict, "unchanged");  // -3 %, within the default 5 %
  n.write("h", 7, 10, 1.0, 3);
  const auto r = run(b, n);
  EXPECT_EQ(row(r, "B").verdict, "worse");
  EXPECT_EQ(row(r, "B").note, "diverged in 1 of 10 NEW runs, none in BASE");
  EXPECT_EQ(r.exit_code(), 1);
  EXPECT_EQ(row(run(n, b), "B").verdict, "better");
}

TEST(Compare, MetricWithoutValuesIsNotComparable) {
  Folder b("nc_b"), n("nc_n");
  b.write("h", 7, 10, 1.0);
  n.write("h", 7, 10, 1.0);
  CompareOptions o;
  o.metric = "mse_ext";
  const auto r = run(b, n, o);
  EXPECT_EQ(row(r, "B").verdict, "not comparable");
  EXPECT_EQ(row(r, "B").note, "no mse_ext values");
  EXPECT_EQ(r.exit_code(), 0);
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const CompareInputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(Compare, BadInputNamesTheFileOrOption) {
  Folder b("bad_b"), n("bad_n");
  b.write("h", 7, 5, 1.0);
  n.write("other", 7, 5, 1.0);
  std::string e = error_of([&] { run(b, n); });
  EXPECT_NE(e.find((n.dir / "manifest.json").string() + ": a different scenario"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("--allow-scenario-change"), std::string::npos) << e;
  CompareOptions allow;
  allow.allow_scenario_change = true;
  EXPECT_EQ(run(b, n, allow).warnings.size(), 1u);

  n.write("h", 7, 5, 1.0, -1, "B");
  e = error_of([&] { run(b, n); });
  EXPECT_NE(e.find((n.dir / "runs.csv").string() + ": missing row estimator \"B\""),
            std::string::npos)
      << e;
  const auto r = run(b, n, allow);
  EXPECT_EQ(row(r, "B").verdict, "not comparable");
  EXPECT_EQ(row(r, "B").note, "only in BASE");

  CompareOptions metric;
  metric.metric = "msee";
  e = error_of([&] { run(b, b, metric); });
  EXPECT_NE(e.find("--metric: expected a per-run column"), std::string::npos) << e;

  std::ofstream(n.dir / "runs.csv", std::ios::app) << "3,B,0.1\n";
  e = error_of([&] { read_run_folder(n.str(), "mse"); });
  EXPECT_NE(e.find((n.dir / "runs.csv").string() + ":7: expected 14 fields"), std::string::npos)
      << e;
  fs::remove(n.dir / "manifest.json");
  e = error_of([&] { read_run_folder(n.str(), "mse"); });
  EXPECT_NE(e.find((n.dir / "manifest.json").string() + ": cannot open"), std::string::npos) << e;
  e = error_of([&] { read_run_folder((n.dir / "nope").string(), "mse"); });
  EXPECT_NE(e.find("not a directory"), std::string::npos) << e;
}

TEST(Compare, NonFiniteNegativeOrOverflowingValuesAreRefusedAtTheirLine) {
  // Line 1 is the header; run r of B is on line 3 + 2 r. Each bad cell refuses the folder
  // (it used to drop the run, or to make the statistics overflow).
  Folder n("nonfinite");
  const std::string file = (n.dir / "runs.csv").string();
  for (const std::string bad : {"nan", "inf", "-inf", "-1e308", "1e400", "-0.5"}) {
    n.write("h", 7, 5, 1.0);
    std::string text;
    {
      std::ifstream in(n.dir / "runs.csv");
      std::stringstream ss;
      ss << in.rdbuf();
      text = ss.str();
    }
    const std::string cell = "\n2,B,";
    const auto at = text.find(cell);
    ASSERT_NE(at, std::string::npos);
    const auto end = text.find(',', at + cell.size());
    text.replace(at + cell.size(), end - at - cell.size(), bad);
    std::ofstream(n.dir / "runs.csv") << text;
    const std::string e = error_of([&] { read_run_folder(n.str(), "mse"); });
    EXPECT_NE(e.find(file + ":7: mse: expected a finite number >= 0"), std::string::npos)
        << bad << ": " << e;
    EXPECT_NE(e.find("\"" + bad + "\""), std::string::npos) << e;
  }
  // A run index that is not a small integer (inf used to be cast to an integer).
  for (const std::string bad : {"inf", "1e300", "nan", "-1", "1.5"}) {
    n.write("h", 7, 5, 1.0);
    std::ofstream(n.dir / "runs.csv", std::ios::app) << bad << ",B,0.1,,100,1,1,0,ok,,,,,1\n";
    const std::string e = error_of([&] { read_run_folder(n.str(), "mse"); });
    EXPECT_NE(e.find(file + ":12: run: expected a run index"), std::string::npos)
        << bad << ": " << e;
  }
}

TEST(Compare, HugeValuesAreTestedWithoutOverflow) {
  // NEW = 1e160 x BASE: squares of the differences overflowed a double before the values were
  // scaled; the row was "unchanged" (p = 0.5 from an infinite standard error). Now the ratio's
  // logarithm is tested, and printed readably (it was a 160-digit number).
  Folder b("huge_b"), n("huge_n");
  b.write("h", 7, 20, 1.0);
  n.write("h", 7, 20, 1.0, -1, "", 0, 1e160);
  auto r = run(b, n);
  EXPECT_EQ(row(r, "B").verdict, "worse");
  EXPECT_EQ(row(r, "A, x").verdict, "worse");
  EXPECT_EQ(r.exit_code(), 1);
  ASSERT_TRUE(row(r, "B").relative.has_value());
  EXPECT_NEAR(*row(r, "B").relative / 1e160, 1.0, 0.01);
  ASSERT_TRUE(row(r, "B").diff.has_value());
  EXPECT_TRUE(std::isfinite(*row(r, "B").diff));
  EXPECT_EQ(row(run(n, b), "B").verdict, "better");
  const std::string huge = compare_markdown(r);
  EXPECT_NE(huge.find("| B | **worse** | paired | 20 | 1.0"), std::string::npos) << huge;
  EXPECT_NE(huge.find(" | ×1e+160 [×"), std::string::npos) << huge;
  EXPECT_EQ(huge.find("0000000000"), std::string::npos) << huge;
  // Values near the largest double: their sum overflows (the means were inf, the change NaN),
  // yet B's +1 % is found and measured like at level 1.
  b.write("h", 7, 20, 1.0, -1, "", 0, 1e307);
  n.write("h", 7, 20, 1.01, -1, "", 0, 1e307);
  CompareOptions half;
  half.tolerance = 0.005;
  r = run(b, n, half);
  EXPECT_EQ(row(r, "B").verdict, "worse");
  EXPECT_EQ(row(r, "A, x").verdict, "unchanged");
  ASSERT_TRUE(row(r, "B").relative.has_value());
  EXPECT_NEAR(*row(r, "B").relative, 0.01, 0.002);
  ASSERT_TRUE(row(r, "B").base_mean.has_value());
  EXPECT_NEAR(*row(r, "B").base_mean / 1e307, 1.0, 0.1);
  const std::string md = compare_markdown(r);
  EXPECT_EQ(md.find("nan"), std::string::npos) << md;
  EXPECT_EQ(md.find("inf"), std::string::npos) << md;
}

TEST(Compare, CsvAndMarkdownCarryEveryRow) {
  Folder b("out_b"), n("out_n");
  b.write("h", 7, 10, 1.0);
  n.write("h", 7, 10, 1.05);
  CompareOptions one;
  one.tolerance = 0.01;
  const auto r = run(b, n, one);
  const std::string csv = compare_csv(r);
  EXPECT_EQ(csv.substr(0, csv.find('\n')),
            "estimator,metric,verdict,test,runs_base,runs_new,pairs,base_mean,new_mean,diff,"
            "relative_change,relative_ci_low,relative_ci_high,ci_level,p_worse,p_better,"
            "p_unchanged,note");
  EXPECT_NE(csv.find("\"A, x\",mse,unchanged,paired,10,10,10,"), std::string::npos) << csv;
  EXPECT_NE(csv.find("B,mse,worse,paired,10,10,10,"), std::string::npos) << csv;
  const std::string md = compare_markdown(r);
  EXPECT_NE(md.find("| B | **worse** | paired | 10 |"), std::string::npos) << md;
  EXPECT_NE(md.find("1 worse, 0 better, 1 unchanged, 0 inconclusive, 0 not comparable: exit 1"),
            std::string::npos)
      << md;
  // +5 %, paired: in %, with the confidence of the Holm step that decided it (the first of 2
  // rows: alpha / 2, 95 %).
  EXPECT_NE(md.find("| B | **worse** | paired | 10 | 1.0"), std::string::npos) << md;
  // The same noise in both folders: +5 % within the 6 digits of runs.csv, shown with the
  // decimals that give the interval's width two significant digits.
  EXPECT_NE(md.find(" | +4.999945 % [+4.999799, +5.000055] | "), std::string::npos) << md;
  EXPECT_NE(md.find("] | 95 % | "), std::string::npos) << md;
}

TEST(CompareIdentity, SameScenarioWithAnotherSeedIsComparedUnpairedWithoutTheOption) {
  // Same text and --set (scenario_text_hash), --seed 8 in NEW: scenario_hash differs (it covers
  // --seed), yet no --allow-scenario-change is needed (it was exit 2); Welch, and it says why.
  Folder b("seed_b"), n("seed_n");
  b.write("h7", 7, 20, 1.0);
  n.write("h8", 8, 20, 1.0);
  b.add_to_manifest({{"scenario_text_hash", "t"}, {"runs", 20}, {"date", "2026-01-01T00:00:00Z"}});
  n.add_to_manifest({{"scenario_text_hash", "t"}, {"runs", 20}, {"date", "2026-02-02T00:00:00Z"}});
  const auto r = run(b, n);
  EXPECT_EQ(row(r, "B").test, "unpaired");
  EXPECT_EQ(row(r, "B").note, "different seeds: unpaired");
  EXPECT_TRUE(r.warnings.empty());
  const std::vector<std::string> diff{"scenario_hash: h7 -> h8", "seed: 7 -> 8"};  // not `date`
  EXPECT_EQ(r.differences, diff);
  const std::string md = compare_markdown(r);
  EXPECT_NE(md.find("- BASE -> NEW differ in:\n  - scenario_hash: h7 -> h8\n  - seed: 7 -> 8\n"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("- test: unpaired, Wilcoxon's rank-sum test of the two sets of runs: the "
                    "seeds differ (7 -> 8)"),
            std::string::npos)
      << md;
}

TEST(CompareIdentity, OtherRunsWithTheSameSeedArePairedOnTheCommonRuns) {
  // --runs 30 in NEW: runs 0..19 are the same realisations in both (same seed), so paired on them.
  Folder b("runs_b"), n("runs_n");
  b.write("h20", 7, 20, 1.0);
  n.write("h30", 7, 30, 1.01);
  b.add_to_manifest({{"scenario_text_hash", "t"}, {"runs", 20}});
  n.add_to_manifest({{"scenario_text_hash", "t"}, {"runs", 30}});
  const auto r = run(b, n);
  EXPECT_EQ(row(r, "B").test, "paired");
  EXPECT_EQ(row(r, "B").pairs, 20u);
  EXPECT_EQ(row(r, "B").note, "paired on the 20 runs both have");
  EXPECT_EQ(row(r, "B").verdict, "unchanged");  // +1 %, shown within the default 5 %
  CompareOptions half;
  half.tolerance = 0.005;
  EXPECT_EQ(row(run(b, n, half), "B").verdict, "worse");  // the +1 % that only pairing finds
  const std::vector<std::string> diff{"runs: 20 -> 30", "scenario_hash: h20 -> h30"};
  EXPECT_EQ(r.differences, diff);
  EXPECT_NE(compare_markdown(r).find("- test: paired on the runs both folders have"),
            std::string::npos);
}

TEST(CompareIdentity, AnotherScenarioTextIsRefusedNamingEveryDifferingField) {
  Folder b("text_b"), n("text_n");
  b.write("h1", 7, 5, 1.0);
  n.write("h2", 8, 5, 1.0);
  const std::string long_title(100, 'x');
  b.add_to_manifest({{"scenario_text_hash", "t1"},
                     {"overrides", nlohmann::json::array()},
                     {"git_commit", "abc"},
                     {"inputs", {{"trace.csv", "1111"}, {"net.xml", "3333"}}},
                     {"threads", 1}});
  n.add_to_manifest({{"scenario_text_hash", "t2"},
                     {"overrides", {"plant.W=[[2.0]]"}},
                     {"git_commit", "def"},
                     {"inputs", {{"trace.csv", "2222"}, {"net.xml", "3333"}}},
                     {"threads", 2},
                     {"title", long_title}});
  const std::string e = error_of([&] { run(b, n); });
  EXPECT_NE(e.find((n.dir / "manifest.json").string() +
                   ": a different scenario or different overrides than " +
                   (b.dir / "manifest.json").string()),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("--allow-scenario-change"), std::string::npos) << e;
  for (const std::string& line : std::vector<std::string>{
           "\n  git_commit: abc -> def", "\n  overrides: [] -> [\"plant.W=[[2.0]]\"]",
           "\n  scenario_hash: h1 -> h2", "\n  scenario_text_hash: t1 -> t2", "\n  seed: 7 -> 8",
           "\n  inputs 'trace.csv': 1111 -> 2222",
           "\n  title: t -> " + long_title.substr(0, 77) + "..."}) {
    EXPECT_NE(e.find(line), std::string::npos) << line << " not in: " << e;
  }
  EXPECT_EQ(e.find("threads"), std::string::npos) << e;  // how it ran, not what
  EXPECT_EQ(e.find("net.xml"), std::string::npos) << e;  // the same content in both
  EXPECT_EQ(e.find("older ncosim"), std::string::npos) << e;
  // With the option: compared (Welch: other seeds), the differences listed in compare.md.
  CompareOptions allow;
  allow.allow_scenario_change = true;
  const auto r = run(b, n, allow);
  EXPECT_EQ(row(r, "B").test, "unpaired");
  EXPECT_NE(compare_markdown(r).find("  - scenario_text_hash: t1 -> t2\n"), std::string::npos);
  // Same text, other inputs: refused, the file named on its own line too.
  n.add_to_manifest({{"scenario_text_hash", "t1"}});
  const std::string in = error_of([&] { run(b, n); });
  EXPECT_NE(in.find("the content of the input file(s) 'trace.csv' (1111 vs 2222) differs"),
            std::string::npos)
      << in;
  EXPECT_NE(in.find("\n  inputs 'trace.csv': 1111 -> 2222"), std::string::npos) << in;
}

TEST(CompareIdentity, AManifestWithoutTheTextHashGoesByTheScenarioHashAndSaysWhy) {
  // A folder of an older ncosim (no scenario_text_hash, no store): its scenario_hash covers
  // --seed, so another seed cannot be told from another scenario; the message says so.
  Folder b("old_b"), n("old_n");
  b.write("h7", 7, 5, 1.0);
  n.write("h8", 8, 5, 1.0);
  n.add_to_manifest({{"scenario_text_hash", "t"}});
  const std::string e = error_of([&] { run(b, n); });
  EXPECT_NE(e.find("(BASE " + b.str() +
                   ": a manifest.json without scenario_text_hash (an older ncosim) and no run "
                   "store; its scenario_hash also covers --runs, --periods and --seed"),
            std::string::npos)
      << e;
  EXPECT_EQ(e.find("(NEW "), std::string::npos) << e;
  b.write("h8", 7, 5, 1.0);  // the same scenario_hash: the same scenario, as before
  EXPECT_EQ(row(run(b, n), "B").test, "unpaired");
}

TEST(CompareIdentity, FirstDifferingLineOfTwoTexts) {
  EXPECT_EQ(first_differing_line("a\nb\nc\n", "a\nb\nc\n"), "");
  EXPECT_EQ(first_differing_line("a\nb = 1\nc\n", "a\nb = 2\nc\n"), "line 2: `b = 1` -> `b = 2`");
  EXPECT_EQ(first_differing_line("a\n", "a\nb\n"), "line 2: `` -> `b`");
  EXPECT_EQ(first_differing_line("a", "a\nb"), "line 2: (end of file) -> `b`");
  // Lines that differ after their first 57 characters still differ (shown shortened).
  const std::string head(70, 'k');
  EXPECT_EQ(first_differing_line(head + "1", head + "2"),
            "line 1: `" + head.substr(0, 57) + "...` -> `" + head.substr(0, 57) + "...`");
}

TEST(CompareIdentity, TheTextHashCoversTheTextAndSetOnlyTheScenarioHashAlsoTheRunOptions) {
  // results/README.md, manifest.json: scenario_hash = FNV-1a of text + "\n--set A"... + "\n--runs
  // N"
  // + "\n--periods N" + "\n--seed N" for the options given; scenario_text_hash without the last
  // three.
  const std::string text =
      "title = \"t\"\n[run]\nperiods = 50\nruns = 2\n[plant]\nA = [[0.5]]\nW = [[1.0]]\n"
      "[[sensor]]\nC = [[1.0]]\nR = [[1.0]]\n[[estimator]]\nname = \"ol\"\nkind = \"open_loop\"\n";
  const std::vector<std::string> sets{"run.warmup=1"};
  RunOverrides ov;
  ov.runs = 3;
  ov.seed = 9;
  const auto plain = load_cases_text("x.toml", text, sets);
  const auto with = load_cases_text("x.toml", text, sets, ov);
  EXPECT_EQ(plain.text_hash, fnv1a_hex(text + "\n--set run.warmup=1"));
  EXPECT_EQ(plain.hash, plain.text_hash);
  EXPECT_EQ(with.text_hash, plain.text_hash);
  EXPECT_EQ(with.hash, fnv1a_hex(text + "\n--set run.warmup=1\n--runs 3\n--seed 9"));
  EXPECT_EQ(scenario_text_hash(text, sets), plain.text_hash);
}

}  // namespace
}  // namespace ncosim::sim
