// sim/cmd/ladder.cc — `ncosim ladder` (sim/cmd/ladder.h).
#include "sim/cmd/ladder.h"

#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "config/config.h"
#include "models/fit.h"
#include "models/link.h"
#include "ncosim_version.h"
#include "sim/analysis/compare.h"
#include "sim/analysis/output.h"
#include "sim/cmd/batch.h"
#include "sim/cmd/cli_checks.h"
#include "sim/cmd/fit_report.h"
#include "sim/cmd/ladder_report.h"
#include "sim/cmd/ladder_scenario.h"
#include "sim/cmd/record_link.h"
#include "sim/files/output_set.h"
#include "sim/scenario/scenario.h"

namespace ncosim::sim {

namespace fs = std::filesystem;

namespace {

const std::vector<std::string> kDefaultFamilies{"bernoulli", "delay", "gilbert_elliott", "markov2"};

// A number option in (lo, hi): "--tolerance: expected a number in (0, 1), got 2".
CLI::Validator open_range(double lo, double hi) {
  return CLI::Validator(
      [lo, hi](std::string& s) -> std::string {
        double v = 0.0;
        if (!CLI::detail::lexical_cast(s, v)) return fmt::format("expected a number, got '{}'", s);
        if (!(v > lo && v < hi))
          return fmt::format("expected a number in ({}, {}), got {}", lo, hi, s);
        return std::string();
      },
      fmt::format("NUMBER in ({}, {})", lo, hi));
}

void progress(const LadderArgs& a, const std::string& text) {
  if (!a.quiet) std::cerr << "ladder: " << text << "\n";
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The families, each known and once (bad input before anything runs).
std::vector<std::string> families(const LadderArgs& a) {
  std::vector<std::string> out;
  for (const auto& f : a.families.empty() ? kDefaultFamilies : a.families) {
    if (models::family_states(f) == 0) {
      throw config::ScenarioError(fmt::format(
          "--family: expected bernoulli, delay, gilbert_elliott or markov2 .. markov8, got '{}'",
          f));
    }
    if (std::find(out.begin(), out.end(), f) != out.end())
      throw config::ScenarioError(
          fmt::format("--family: expected each family once, got '{}' twice", f));
    out.push_back(f);
  }
  return out;
}

// The single case of the scenario, with its network links; refuses what the ladder cannot walk.
std::vector<std::size_t> network_links(const LoadedScenario& loaded) {
  if (!loaded.sweeps.empty()) {
    throw config::ScenarioError(config::format_error(
        loaded.file, 0, "sweep",
        "expected a scenario without [[sweep]] tables: the ladder compares one operating point "
        "(choose it with --set KEY=VALUE and drop the sweeps with --set 'sweep=[]', or run the "
        "ladder once per point as scripts/fidelity_ladder.py does)"));
  }
  const Scenario& sc = *loaded.cases.front().scenario;
  std::vector<std::size_t> out;
  for (std::size_t l = 0; l < sc.links.size(); ++l) {
    if (sc.links[l].link->network_attachment() == nullptr) continue;
    (void)record_link(sc, l, 0);  // refuses a link that cannot be recorded, before anything runs
    out.push_back(l);
  }
  if (out.empty()) {
    throw config::ScenarioError(config::format_error(
        loaded.file, 0, "link",
        "expected a [[link]] of kind \"network\" (a node of a [[network]]): the ladder replaces "
        "network links by fitted ones, and this scenario has none"));
  }
  return out;
}

// One network link: its record, its scored packets' fates, and what each family made of them.
struct LinkFit {
  std::size_t index = 0;
  std::string name;
  RecordedTrace trace;
  std::vector<int> sym;  // the scored packets (k >= warmup) of every run, one after the other
  FitSet set;
  std::vector<double> design_pmf;            // the delay fit's law
  std::map<std::string, std::string> table;  // family -> its [[link]] table
};

// The fates of the packets sent at k >= warmup, run after run (the order of record_link).
std::vector<int> scored_symbols(const Scenario& sc, const LinkFit& f) {
  std::vector<bool> scored;
  for (std::int64_t k = 0; k < sc.run.periods; ++k) {
    for (const auto& s : sc.model.sensors) {
      if (s.spec.link == static_cast<int>(f.index) && k % s.spec.every == 0)
        scored.push_back(k >= sc.run.warmup);
    }
  }
  std::vector<std::optional<std::int64_t>> fates;
  for (std::size_t i = 0; i < f.trace.delays.size(); ++i) {
    if (!scored[i % scored.size()]) continue;
    const std::int64_t d = f.trace.delays[i];
    fates.push_back(d == models::kLost ? std::nullopt : std::optional<std::int64_t>(d));
  }
  if (fates.empty()) {
    throw config::ScenarioError(
        fmt::format("--periods: link '{}' sends no packet after the warm-up ({} periods)", f.name,
                    sc.run.warmup));
  }
  try {
    return models::fate_symbols(fates);
  } catch (const std::out_of_range& e) {
    throw config::ScenarioError(
        fmt::format("link '{}': {} (the network is overloaded: its queue grows without bound)",
                    f.name, e.what()));
  }
}

// What stands for the bernoulli family when the delays vary (it holds one delay): the trace's
// loss, every delivered packet with its most common delay.
std::string loss_only_table(const LinkFit& f) {
  std::size_t lost = 0;
  std::map<int, std::size_t> count;
  for (const int s : f.sym) s == 0 ? ++lost : ++count[s - 1];
  int mode = 0;
  std::size_t most = 0;
  for (const auto& [d, n] : count) {
    if (n > most) most = n, mode = d;
  }
  return fmt::format(
      "[[link]]\nname = \"{}\"\n# not a likelihood fit (the delays vary; a bernoulli link holds "
      "one): the trace's loss, every delivered packet with its most common delay\nkind = "
      "\"bernoulli\"\nloss = {}\ndelay = {}\n",
      f.name, static_cast<double>(lost) / static_cast<double>(f.sym.size()), mode);
}

// Every family fitted to the link's scored packets (`delay` always: it gives design_pmf).
void fit_link(LinkFit& f, const std::vector<std::string>& fams, const LadderArgs& a) {
  models::FitOptions o;
  o.starts = a.starts;
  o.max_iterations = a.max_iterations;
  o.link_name = f.name;
  f.set.trace = fmt::format("link '{}' (scored packets of traces/{}.csv)", f.name, f.name);
  f.set.packets = f.sym.size();
  for (const int s : f.sym) {
    f.set.lost += s == 0 ? 1 : 0;
    f.set.longest_delay = std::max(f.set.longest_delay, s - 1);
  }
  std::vector<std::string> all = fams;
  if (std::find(all.begin(), all.end(), "delay") == all.end()) all.push_back("delay");
  const auto t0 = std::chrono::steady_clock::now();
  for (const auto& family : all) {
    try {
      f.set.fits.push_back(models::fit_family(family, f.sym, o));
      f.table[family] = f.set.fits.back().link_toml;
      if (family == "delay") f.design_pmf = f.set.fits.back().marginal_pmf();
    } catch (const std::domain_error& e) {
      f.set.skipped.push_back(fmt::format("{}: {}", family, e.what()));
      f.table[family] = loss_only_table(f);
    } catch (const std::invalid_argument& e) {
      throw config::ScenarioError(fmt::format(
          "--runs/--periods: link '{}': {} (record more runs or periods, or choose smaller "
          "families with --family)",
          f.name, e.what()));
    }
  }
  f.set.seconds = seconds_since(t0);
  f.set.best = models::best_fit(f.set.fits, f.set.criterion);
}

std::string trace_csv(const RecordedTrace& t) {
  std::string csv = "seq,delay\n";
  for (std::size_t i = 0; i < t.delays.size(); ++i) {
    csv += t.delays[i] == models::kLost ? fmt::format("{},\n", i)
                                        : fmt::format("{},{}\n", i, t.delays[i]);
  }
  return csv;
}

// The hidden sibling folder everything is made in; removed unless handed over.
class Staging {
 public:
  explicit Staging(const std::string& out) {
    const fs::path folder = output_set_folder(out);
    parent_ = folder.parent_path();
    name_ = folder.filename().string();
    fs::create_directories(parent_);
    const std::string prefix = "." + name_ + ".ladder.";
    int removed = 0;
    for (const auto& e : fs::directory_iterator(parent_)) {
      if (e.path().filename().string().rfind(prefix, 0) == 0) {
        fs::remove_all(e.path());  // a killed ladder's (the folder's lock is held)
        ++removed;
      }
    }
    if (removed > 0)
      std::cerr << fmt::format("ladder: removed {} leftover folder(s) of an interrupted ladder\n",
                               removed);
    path_ = parent_ / fmt::format("{}{}", prefix, static_cast<long>(::getpid()));
    if (!fs::create_directory(path_))
      throw std::runtime_error(fmt::format("cannot create '{}'", path_.string()));
  }
  ~Staging() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  Staging(const Staging&) = delete;
  Staging& operator=(const Staging&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path parent_, path_;
  std::string name_;
};

// std::cout captured while alive (the campaigns' tables: the ladder prints its own).
class CoutCapture {
 public:
  CoutCapture() : old_(std::cout.rdbuf(buf_.rdbuf())) {}
  ~CoutCapture() { std::cout.rdbuf(old_); }
  CoutCapture(const CoutCapture&) = delete;
  CoutCapture& operator=(const CoutCapture&) = delete;

 private:
  std::ostringstream buf_;
  std::streambuf* old_;
};

// The rung's campaign, run as `ncosim run` would run OUT/<rung>.toml, into the staging folder.
// Returns its exit status (0, or a signal's) and the simulation's wall time.
int run_rung(const LadderArgs& a, Rung& r, const std::string& out, const fs::path& staging) {
  const ScenarioText text((fs::path(out) / (r.name + ".toml")).string(), r.text);
  RunCommand cmd;
  cmd.file = (fs::path(out) / (r.name + ".toml")).string();
  cmd.out = (staging / "runs" / r.name).string();
  cmd.threads = a.threads;
  cmd.quiet = a.quiet;
  cmd.timing = false;
  cmd.command_line = fmt::format("{} (rung {})", a.command_line, r.name);
  int code = 0;
  {
    const CoutCapture capture;
    code = cmd_run_campaign(cmd);
  }
  std::ifstream in(fs::path(cmd.out) / "manifest.json");
  const nlohmann::json m = nlohmann::json::parse(in, nullptr, false);
  r.wall = m.is_object() && m.contains("wall_seconds") ? m["wall_seconds"].get<double>() : 0.0;
  return code;
}

// The one use of `ncosim compare`'s library: the rung against the network, paired run by run
// (same seed), as `ncosim compare NETWORK RUNG --allow-scenario-change` (sim/analysis/compare.h).
void compare_with_network(const fs::path& network, Rung& r, const fs::path& staging,
                          const std::string& out, const LadderArgs& a) {
  CompareOptions o;
  o.tolerance = a.tolerance;
  o.alpha = a.alpha;
  o.allow_scenario_change = true;
  RunFolder base = read_run_folder(network.string(), o.metric);
  RunFolder fresh = read_run_folder((staging / "runs" / r.name).string(), o.metric);
  read_row_statuses(base);
  read_row_statuses(fresh);
  base.dir = (fs::path(out) / "runs" / "network").string();  // where they will be
  fresh.dir = (fs::path(out) / "runs" / r.name).string();
  r.compare = compare_folders(base, fresh, o);
  r.compare_csv = compare_csv(r.compare);
  r.compare_md = compare_markdown(r.compare);
}

// The header of a written scenario: what it is, and the command that wrote it.
std::string rung_header(const LadderArgs& a, const std::string& what) {
  std::string cmd = a.command_line;
  for (char& c : cmd) c = c == '\n' || c == '\r' ? ' ' : c;
  return fmt::format(
      "# {}\n# {}\n# as `ncosim ladder` ran it (--set, --runs, --periods, --seed applied; the\n"
      "# file's comments are not kept). An ordinary scenario: `ncosim run` runs it alone.\n"
      "# Written by ncosim {}: {}\n\n",
      what, a.file, NCOSIM_VERSION, cmd);
}

}  // namespace

namespace {

// 1: every network link recorded and fitted.
std::vector<LinkFit> record_and_fit(const Scenario& sc, const std::vector<std::size_t>& links,
                                    const std::vector<std::string>& fams, const LadderArgs& a,
                                    LadderReport& report) {
  std::vector<LinkFit> out;
  for (std::size_t i = 0; i < links.size(); ++i) {
    LinkFit f;
    f.index = links[i];
    f.name = sc.links[f.index].name;
    progress(a, fmt::format("recording link '{}' ({} of {}): {} runs x {} periods, the whole "
                            "network simulated",
                            f.name, i + 1, links.size(), sc.run.runs, sc.run.periods));
    auto t0 = std::chrono::steady_clock::now();
    f.trace = record_link(sc, f.index, sc.run.runs, record_jobs(a.threads));
    report.record_seconds += seconds_since(t0);
    f.sym = scored_symbols(sc, f);
    progress(a, fmt::format("fitting link '{}': {} scored packets", f.name, f.sym.size()));
    fit_link(f, fams, a);
    report.fit_seconds += f.set.seconds;
    out.push_back(std::move(f));
  }
  return out;
}

// 2: the scenario of every rung: the network with the fitted design law, then one per family.
std::vector<Rung> rung_scenarios(const LoadedScenario& loaded, const std::vector<LinkFit>& fits,
                                 const std::vector<std::string>& fams, const LadderArgs& a,
                                 const std::string& out) {
  toml::table doc =
      ladder_document(loaded.file, loaded.text, a.sets, a.runs, a.periods,
                      a.seed >= 0 ? std::optional<std::uint64_t>(a.seed) : std::nullopt);
  rebase_input_paths(doc, loaded.inputs, fs::path(loaded.file).parent_path().string(), out);
  std::vector<Rung> rungs;
  toml::array* links = doc["link"].as_array();
  for (const auto& f : fits) {
    toml::array pmf;
    for (const double p : f.design_pmf) pmf.push_back(p);
    links->get(f.index)->as_table()->insert_or_assign("design_pmf", std::move(pmf));
  }
  Rung network;
  network.name = "network";
  network.text =
      rung_header(a,
                  "The network rung: every network link's design_pmf is the `delay` fit to its "
                  "recorded trace, of") +
      scenario_text(doc, loaded.file, {}, {});
  rungs.push_back(std::move(network));
  for (const auto& family : fams) {
    Rung r;
    r.name = family;
    std::map<std::size_t, std::string> replace;
    for (const auto& f : fits) {
      replace[f.index] = f.table.at(family);
      for (const auto& s : f.set.skipped) {
        if (s.rfind(family + ":", 0) == 0)
          r.note = "loss only (" + s.substr(family.size() + 2) + ")";
      }
      for (const auto& fr : f.set.fits) {
        if (fr.family == family && !fr.converged)
          r.note += (r.note.empty() ? "" : "; ") + fmt::format("not converged on '{}'", f.name);
      }
    }
    r.text = rung_header(a, fmt::format("The {} rung: every network link replaced by its `{}` fit "
                                        "to its recorded trace, [[network]] and [[background]] "
                                        "dropped, of",
                                        family, family)) +
             scenario_text(doc, loaded.file, replace, {"network", "background"});
    rungs.push_back(std::move(r));
  }
  return rungs;
}

}  // namespace

int cmd_ladder(const LadderArgs& a) {
  const std::vector<std::string> fams = families(a);
  RunOverrides overrides;
  overrides.runs = a.runs;
  overrides.periods = a.periods;
  if (a.seed >= 0) overrides.seed = static_cast<std::uint64_t>(a.seed);
  std::vector<std::string> sets = a.sets;
  for (auto& s : placeholder_design_laws(a.file, a.sets)) sets.push_back(s);
  const LoadedScenario loaded = load_cases(a.file, sets, overrides);
  const std::vector<std::size_t> links = network_links(loaded);
  const Scenario& sc = *loaded.cases.front().scenario;
  const std::string out =
      a.out.empty() ? (fs::path("out") / ("ladder_" + fs::path(a.file).stem().string())).string()
                    : a.out;
  std::error_code ec;
  if (fs::exists(out, ec) && !(fs::is_directory(out, ec) && fs::is_empty(out, ec)) && !a.replace) {
    throw config::ScenarioError(fmt::format(
        "--out: '{}' already holds files (a previous ladder?): choose another --out, or pass "
        "--replace to replace it as a whole",
        out));
  }
  const OutputFolderLock lock(out);  // one writer per folder for the whole command
  const Staging staging(out);
  LadderReport report;
  report.file = a.file;
  report.out = out;
  report.tolerance = a.tolerance;
  report.alpha = a.alpha;
  report.runs = sc.run.runs;
  report.periods = sc.run.periods;
  report.seed = sc.run.seed;
  const std::vector<LinkFit> fits = record_and_fit(sc, links, fams, a, report);
  report.rungs = rung_scenarios(loaded, fits, fams, a, out);
  for (std::size_t i = 0; i < report.rungs.size(); ++i) {
    Rung& r = report.rungs[i];
    progress(a, fmt::format("campaign {} of {}: {}", i + 1, report.rungs.size(), r.name));
    const int code = run_rung(a, r, out, staging.path());
    if (code != 0) {
      std::cerr << fmt::format(
          "ladder: the campaign of rung {} stopped (exit {}); nothing written\n", r.name, code);
      return code;
    }
    if (i > 0) compare_with_network(staging.path() / "runs" / "network", r, staging.path(), out, a);
  }
  for (const auto& r : report.rungs)  // the campaigns' locks (released): not part of the set
    fs::remove(staging.path() / "runs" / fmt::format(".{}.lock", r.name), ec);
  // Everything made: the files, then the folders, swapped in as OUT's new set.
  std::vector<std::pair<std::string, std::string>> files, traces, link_fits, compares;
  for (const auto& f : fits) {
    traces.emplace_back(f.name + ".csv", trace_csv(f.trace));
    link_fits.emplace_back(f.name + ".json", fit_json(f.set));
  }
  for (const auto& r : report.rungs) {
    files.emplace_back(r.name + ".toml", r.text);
    if (r.name == "network") continue;
    compares.emplace_back(r.name + ".csv", r.compare_csv);
    compares.emplace_back(r.name + ".md", r.compare_md);
  }
  for (const auto& f : fits) report.links.push_back(link_summary(f.name, f.set, f.design_pmf));
  files.emplace_back("ladder.csv", ladder_csv(report));
  files.emplace_back("ladder.md", ladder_markdown(report));
  write_files_atomically((staging.path() / "traces").string(), traces);
  write_files_atomically((staging.path() / "fits").string(), link_fits);
  write_files_atomically((staging.path() / "compare").string(), compares);
  std::vector<InstalledFile> installs;
  for (const char* dir : {"traces", "fits", "runs", "compare"}) {
    const fs::path from = staging.path() / dir;
    installs.push_back({dir, [from](const fs::path& to) { fs::rename(from, to); }});
  }
  write_output_set(out, files, {"*"}, installs);
  std::cout << ladder_summary(report);
  return 0;
}

CLI::App* add_ladder_command(CLI::App& app, LadderArgs& a) {
  CLI::App* sub = app.add_subcommand(
      "ladder",
      "the fidelity ladder: record every network link, fit the families, run each fitted "
      "surrogate paired with the network: where each leaves the band, and its speed-up");
  sub->add_option("--runs", a.runs, "Monte Carlo runs (overrides run.runs)")
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{10'000'000}));
  sub->add_option("--periods", a.periods, "periods per run (overrides run.periods)")
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{1'000'000'000}));
  sub->add_option("--seed", a.seed, "campaign seed (overrides run.seed)")->check(seed_range());
  sub->add_option("--family", a.families,
                  "family to fit and run, repeatable, lowest rung first (default: bernoulli, "
                  "delay, gilbert_elliott, markov2)");
  sub->add_option("--tolerance", a.tolerance,
                  "the band: a relative change of the network's MSE (default 0.05 = 5 %)")
      ->check(open_range(0.0, 1.0));
  sub->add_option("--alpha", a.alpha, "compare's significance level (default 0.05)")
      ->check(open_range(0.0, 1.0));
  sub->add_option("--starts", a.starts, "EM starts per hidden-state family (default 4)")
      ->check(CLI::Range(1, 100));
  sub->add_option("--max-iterations", a.max_iterations,
                  "EM iterations per hidden-state family (default 2000)")
      ->check(CLI::Range(1, 1'000'000));
  sub->add_option("--threads", a.threads,
                  "worker threads of each campaign, and network runs recorded at a time "
                  "(default: all cores)")
      ->check(CLI::Range(0, 4096));
  sub->add_flag("--replace", a.replace, "replace an --out folder that already holds files");
  sub->add_flag("--quiet", a.quiet, "no progress lines");
  return sub;
}

}  // namespace ncosim::sim
