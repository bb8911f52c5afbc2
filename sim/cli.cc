// sim/cli.cc — subcommands of the ncosim executable.
#include "sim/cli.h"

#include <fmt/format.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <limits>
#include <thread>

#include "ncosim_version.h"
#include "sim/campaign.h"
#include "sim/output.h"
#include "sim/registries.h"
#include "sim/scenario.h"

#if NCOSIM_HAVE_SUMO
#include "sumo/channel.h"
#include "sumo/mobility.h"
#include "sumo/sumo.h"
#endif

namespace ncosim::sim {

namespace {

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string default_out(const std::string& file) {
  return (std::filesystem::path("results") / std::filesystem::path(file).stem()).string();
}

nlohmann::json manifest(const LoadedScenario& loaded, const std::string& command_line, int threads,
                        double wall_seconds) {
  const Scenario& sc = *loaded.cases.front().scenario;
  nlohmann::json j;
  j["scenario"] = loaded.file;
  j["title"] = sc.title;
  j["scenario_hash"] = loaded.hash;
  j["overrides"] = loaded.overrides;
  j["seed"] = sc.run.seed;
  j["runs"] = sc.run.runs;
  j["periods"] = sc.run.periods;
  j["warmup"] = sc.run.warmup;
  j["cases"] = loaded.cases.size();
  j["command_line"] = command_line;
  j["ncosim_version"] = NCOSIM_VERSION;
  j["git_commit"] = NCOSIM_GIT_COMMIT;
  j["date"] = utc_now();
  j["threads"] = threads;
  j["wall_seconds"] = wall_seconds;
  j["recentred"] = sc.recentre;
  return j;
}

struct CommonArgs {
  std::string file;
  std::string out;
  std::vector<std::string> sets;
  RunOverrides overrides;
  std::int64_t seed = -1;
};

int cmd_run(const CommonArgs& a, int threads, bool trace, bool quiet, const std::string& command_line) {
  RunOverrides ov = a.overrides;
  if (a.seed >= 0) ov.seed = static_cast<std::uint64_t>(a.seed);
  LoadedScenario loaded = load_cases(a.file, a.sets, ov);
  const std::string out = a.out.empty() ? default_out(a.file) : a.out;
  prepare_output_dir(out);  // fail before the campaign, not after it
  const bool tty = ::isatty(2) != 0 && !quiet;
  std::vector<SummaryRow> rows;
  std::vector<CampaignResult> results;
  results.reserve(loaded.cases.size());
  double wall = 0.0;
  int used_threads = 1;
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    const Case& cs = loaded.cases[c];
    CampaignOptions opt;
    opt.threads = threads;
    opt.progress = tty;
    opt.trace = trace && c == 0;
    opt.progress_label = loaded.cases.size() > 1 ? fmt::format("case {}/{}:", c + 1, loaded.cases.size()) : "";
    results.push_back(run_campaign(*cs.scenario, opt));
    wall += results.back().wall_seconds;
    used_threads = results.back().threads;
    auto case_rows = summarise(*cs.scenario, results.back(), cs.labels);
    rows.insert(rows.end(), case_rows.begin(), case_rows.end());
  }
  const Scenario& first = *loaded.cases.front().scenario;
  const Eigen::Index n = first.model.plant.n();
  std::vector<std::vector<std::string>> labels;
  std::vector<const Scenario*> scs;
  std::vector<const CampaignResult*> res;
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    labels.push_back(loaded.cases[c].labels);
    scs.push_back(loaded.cases[c].scenario.get());
    res.push_back(&results[c]);
  }
  const std::string md = summary_markdown(first.title, loaded.sweeps, rows, n);
  std::vector<std::pair<std::string, std::string>> files{
      {"summary.csv", summary_csv(loaded.sweeps, rows, n)},
      {"summary.md", md},
      {"runs.csv", runs_csv(loaded.sweeps, labels, scs, res)},
      {"design.json", design_json(loaded).dump(2) + "\n"},
      {"manifest.json", manifest(loaded, command_line, used_threads, wall).dump(2) + "\n"},
  };
  if (trace) files.emplace_back("trajectory.csv", trajectory_csv(first, results.front().trace));
  write_files_atomically(out, files, {"trajectory.csv"});
  std::cout << md << fmt::format("\n{} runs x {} periods x {} case(s) in {:.2f} s on {} thread(s); results in {}/\n",
                                 first.run.runs, first.run.periods, loaded.cases.size(), wall, used_threads, out);
  return 0;
}

int cmd_design(const CommonArgs& a, const std::string& command_line) {
  LoadedScenario loaded = load_cases(a.file, a.sets, a.overrides);
  const std::string out = a.out.empty() ? default_out(a.file) : a.out;
  const auto dj = design_json(loaded);
  write_files_atomically(out, {{"design.json", dj.dump(2) + "\n"},
                               {"manifest.json", manifest(loaded, command_line, 1, 0.0).dump(2) + "\n"}});
  for (const auto& e : dj["estimators"]) {
    std::cout << fmt::format("{:<28} {:<16} method={:<10} gains={:<6} predicted_mse_ext={:<10} status={}\n",
                             e["name"].get<std::string>(), e["kind"].get<std::string>(),
                             e["method"].get<std::string>(), e["stored_gains"].dump(),
                             e["predicted_mse_ext"].is_number()
                                 ? fmt::format("{:.6g}", e["predicted_mse_ext"].get<double>())
                                 : std::string("null"),
                             e["status"].get<std::string>());
  }
  std::cout << fmt::format("design.json written to {}/\n", out);
  return 0;
}

int cmd_check(const CommonArgs& a) {
  LoadedScenario loaded = load_cases(a.file, a.sets, a.overrides);
  std::cout << fmt::format("{}: ok ({} case(s), {} estimator(s))\n", a.file, loaded.cases.size(),
                           loaded.cases.front().scenario->estimators.size());
  return 0;
}

template <class R>
void list_registry(const char* what, const R& registry) {
  std::cout << what << ":\n";
  for (const auto& e : registry.entries()) std::cout << fmt::format("  {:<18} {}\n", e.name, e.help);
}

int cmd_list() {
  list_registry("plant kinds ([plant] kind)", plant_registry());
  list_registry("link kinds ([[link]] kind)", link_registry());
  list_registry("input kinds ([input] kind)", input_registry());
  list_registry("estimator kinds ([[estimator]] kind)", estimator_registry());
#if NCOSIM_HAVE_SUMO
  std::cout << "channel presets (sumo_distance preset; see `ncosim channel PRESET`):\n";
  for (const auto& n : sumo::preset_names()) std::cout << fmt::format("  {:<18} {}\n", n, sumo::preset_help(n));
#endif
  return 0;
}

}  // namespace

int run_cli(int argc, char** argv) {
#if NCOSIM_HAVE_SUMO
  // Hidden: one SUMO realisation recorded in this process (started by the [sumo] reader).
  if (argc > 1 && std::string_view(argv[1]) == "sumo-record") {
    return sumo::worker_main(std::vector<std::string>(argv + 2, argv + argc));
  }
  {
    std::error_code ec;
    const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (!ec) sumo::set_worker_executable(self.string());
  }
#endif
  CLI::App app{"ncosim: discrete-event co-simulator for state estimation over networks"};
  app.set_version_flag("--version", fmt::format("ncosim {} ({})", NCOSIM_VERSION, NCOSIM_GIT_COMMIT));
  app.require_subcommand(1);
  CommonArgs a;
  int threads = 0;
  bool trace = false;
  bool quiet = false;

  auto add_common = [&](CLI::App* sub, bool with_out) {
    sub->add_option("FILE", a.file, "scenario file (TOML)")->required();
    sub->add_option("--set", a.sets, "override one key before validation: KEY=VALUE (VALUE in TOML)");
    if (with_out) sub->add_option("--out", a.out, "output directory (default: results/<file stem>)");
  };
  CLI::App* run = app.add_subcommand("run", "run the Monte Carlo campaign and write the results");
  add_common(run, true);
  // Ranges as in [run] (CLI::PositiveNumber would print its bound as a 300-digit double).
  run->add_option("--runs", a.overrides.runs, "Monte Carlo runs (overrides run.runs)")
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{10'000'000}));
  run->add_option("--periods", a.overrides.periods, "periods per run (overrides run.periods)")
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{1'000'000'000}));
  run->add_option("--seed", a.seed, "campaign seed (overrides run.seed)")
      ->check(CLI::Range(std::int64_t{0}, std::numeric_limits<std::int64_t>::max()));
  run->add_option("--threads", threads, "worker threads (default: all cores)")
      ->check(CLI::Range(0, 4096));
  run->add_flag("--trace", trace, "also write trajectory.csv (x, xhat, arrivals of run 0)");
  run->add_flag("--quiet", quiet, "no progress line");
  CLI::App* design = app.add_subcommand("design", "offline design only: write design.json");
  add_common(design, true);
  CLI::App* check = app.add_subcommand("check", "parse and validate only");
  add_common(check, false);
  app.add_subcommand("list", "list every registered kind with a one-line help");
  std::string preset;
  bool csv = false, gnuplot = false;
  double max_distance = 1000.0, step = 10.0;
  CLI::App* channel = nullptr;
  if (have_sumo()) {
    channel = app.add_subcommand("channel", "print p(d) and the delay law of a sumo_distance channel preset");
    channel->add_option("PRESET", preset, "channel preset (see `ncosim list`)")->required();
    channel->add_flag("--csv", csv, "CSV: distance_m,mean_rx_dbm,p_reception");
    channel->add_flag("--gnuplot", gnuplot, "print a gnuplot script plotting the CSV");
    channel->add_option("--max-distance", max_distance, "largest distance (m, default 1000)");
    channel->add_option("--step", step, "distance step (m, default 10)");
  }

  // An unknown command: CLI11 would only say "A subcommand is required".
  if (argc > 1 && argv[1][0] != '-') {
    std::vector<std::string> commands;
    for (const CLI::App* sub : app.get_subcommands({})) commands.push_back(sub->get_name());
    if (std::find(commands.begin(), commands.end(), argv[1]) == commands.end()) {
      const std::string hint = did_you_mean(argv[1], commands);
      std::cerr << fmt::format(
          "ncosim: expected a command (run, design, check or list), got '{}'{}\n", argv[1],
          hint.empty() ? "" : fmt::format(" (did you mean '{}'?)", hint));
      return 2;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  }
  std::string command_line;
  for (int i = 0; i < argc; ++i) command_line += (i ? " " : "") + std::string(argv[i]);
  try {
    if (run->parsed()) return cmd_run(a, threads, trace, quiet, command_line);
    if (design->parsed()) return cmd_design(a, command_line);
    if (check->parsed()) return cmd_check(a);
#if NCOSIM_HAVE_SUMO
    if (channel != nullptr && channel->parsed()) return sumo::channel_command(preset, csv, gnuplot, max_distance, step);
#endif
    return cmd_list();
  } catch (const ScenarioError& e) {
    std::cerr << "ncosim: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "ncosim: error: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace ncosim::sim
