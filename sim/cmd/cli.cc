// sim/cmd/cli.cc — subcommands of the ncosim executable.
#include "sim/cmd/cli.h"

#include <fmt/format.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <charconv>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <limits>
#include <optional>
#include <string_view>
#include <thread>

#include "estimators/export_c.h"
#include "lmi/limits.h"
#include "ncosim_version.h"
#include "network/worker.h"
#include "sim/analysis/compare.h"
#include "sim/analysis/output.h"
#include "sim/analysis/paired.h"
#include "sim/cmd/batch.h"
#include "sim/cmd/cli_checks.h"
#include "sim/cmd/codesign.h"
#include "sim/cmd/figure_cli.h"
#include "sim/cmd/find.h"
#include "sim/cmd/fit_cmd.h"
#include "sim/cmd/ladder.h"
#include "sim/cmd/list_keys.h"
#include "sim/cmd/manifest.h"
#include "sim/cmd/mpi_campaign.h"
#include "sim/cmd/record_link.h"
#include "sim/cmd/schema.h"
#include "sim/files/output_set.h"
#include "sim/present/table_view.h"
#include "sim/run/campaign.h"
#include "sim/scenario/registries.h"
#include "sim/scenario/resource_limits.h"
#include "sim/scenario/scenario.h"

#if NCOSIM_HAVE_SUMO
#include "sumo/channel.h"
#include "sumo/sumo.h"
#include "sumo/traffic.h"
#endif

namespace ncosim::sim {

namespace {

// out/<stem>: git-ignored, so a user's first `ncosim run scenarios/X.toml` never modifies the
// committed reference results/X/ (references are made with an explicit --out).
// CLI::Range for a double, with its bounds and the value as written (CLI::Range prints
// "Value 0.5 not in range 1.000000 to 1000000.000000"): "--mu: expected a number in [1, 1000000],
// got 0.5".
CLI::Validator number_range(double lo, double hi) {
  return CLI::Validator(
      [lo, hi](std::string& s) -> std::string {
        double v = 0.0;
        if (!CLI::detail::lexical_cast(s, v)) return fmt::format("expected a number, got '{}'", s);
        if (!(v >= lo && v <= hi))
          return fmt::format("expected a number in [{}, {}], got {}", lo, hi, s);
        return std::string();
      },
      fmt::format("NUMBER in [{}, {}]", lo, hi));
}

std::string default_out(const std::string& file) {
  return (std::filesystem::path("out") / std::filesystem::path(file).stem()).string();
}

nlohmann::json manifest(const LoadedScenario& loaded, const std::string& command_line, int threads,
                        double wall_seconds) {
  return campaign_manifest(loaded, command_line, threads, wall_seconds);  // sim/cmd/manifest.h
}

struct CommonArgs {
  std::string file;
  std::string out;
  std::vector<std::string> sets;
  RunOverrides overrides;
  std::int64_t seed = -1;
};

int cmd_run(const CommonArgs& a, RunCommand cmd) {
  cmd.file = a.file;
  cmd.out = a.out.empty() ? default_out(a.file) : a.out;
  cmd.sets = a.sets;
  cmd.overrides = a.overrides;
  if (a.seed >= 0) cmd.overrides.seed = static_cast<std::uint64_t>(a.seed);
  return cmd_run_campaign(cmd);  // sim/cmd/batch.cc: run store, signals, resume, shards
}

// The C export of every jump estimator of every case (`--export-c`); other kinds are listed
// as skipped. With sweeps the prefix ends in _case<c> (1-based, in sweep order).
std::vector<std::pair<std::string, std::string>> export_c_files(const LoadedScenario& loaded) {
  std::vector<est::CExportItem> items;
  std::vector<std::string> taken, skipped;
  for (std::size_t c = 0; c < loaded.cases.size(); ++c) {
    const Scenario& sc = *loaded.cases[c].scenario;
    std::string origin = loaded.file;
    for (std::size_t a = 0; a < loaded.sweeps.size(); ++a) {
      origin += fmt::format("{}{} = {}", a ? ", " : ", sweep case ", loaded.sweeps[a].key,
                            loaded.cases[c].labels[a]);
    }
    for (const auto& e : sc.estimators) {
      const est::JumpDesignAccess* jump = e.design->c_export();
      if (jump == nullptr) {
        if (c == 0) skipped.push_back(e.name);
        continue;
      }
      const std::string base =
          loaded.sweeps.empty() ? e.name : fmt::format("{} case{}", e.name, c + 1);
      items.push_back(
          {e.name, est::c_identifier(base, taken), jump, &sc.model.plant, sc.model.period, origin});
    }
  }
  if (items.empty())
    throw config::ScenarioError(
        fmt::format("{}: --export-c: no estimator of kind jump to export", loaded.file));
  for (const auto& name : skipped) {
    std::cerr << fmt::format(
        "ncosim design: --export-c exports jump estimators only; \"{}\" skipped\n", name);
  }
  auto files =
      est::export_c(items, fmt::format("ncosim {} ({})", NCOSIM_VERSION, NCOSIM_GIT_COMMIT));
  for (const auto& it : items)
    std::cout << fmt::format("{:<28} -> {}.h, {}.c\n", it.name, it.prefix, it.prefix);
  return files;
}

int cmd_design(const CommonArgs& a, const std::string& command_line,
               const std::string& export_dir) {
  LoadedScenario loaded = load_cases(a.file, a.sets, a.overrides);
  const std::string out = a.out.empty() ? default_out(a.file) : a.out;
  const OutputFolderLock lock(out);
  const auto dj = design_json(loaded);
  std::vector<std::pair<std::string, std::string>> c_files;
  if (!export_dir.empty()) {
    try {
      c_files = export_c_files(loaded);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(fmt::format("--export-c: {}", e.what()));
    }
  }
  write_files_atomically(
      out, {{"design.json", dj.dump(2) + "\n"},
            {"design.csv", design_csv(loaded)},
            {"manifest.json", manifest(loaded, command_line, 1, 0.0).dump(2) + "\n"}});
  if (!c_files.empty()) {
    write_files_atomically(export_dir, c_files);
    std::cout << fmt::format("C99 sources written to {}/\n", export_dir);
  }
  if (loaded.cases.size() > 1) {
    std::cout << fmt::format("{} cases designed; every case's estimators are in design.csv\n",
                             loaded.cases.size());
  }
  for (const auto& e : dj["estimators"]) {
    std::cout << fmt::format(
        "{:<28} {:<16} method={:<10} gains={:<6} predicted_mse_ext={:<10} status={}\n",
        e["name"].get<std::string>(), e["kind"].get<std::string>(), e["method"].get<std::string>(),
        e["stored_gains"].dump(),
        e["predicted_mse_ext"].is_number()
            ? fmt::format("{:.6g}", e["predicted_mse_ext"].get<double>())
            : std::string("null"),
        e["status"].get<std::string>());
  }
  std::cout << fmt::format("design.json, design.csv written to {}/\n", out);
  return 0;
}

int cmd_find(const CommonArgs& a, const FindOptions& opt, const std::string& target_text,
             const std::string& command_line) {
  FindOptions o = opt;
  o.target = parse_target(target_text, "--target");
  const FindResult res = find_threshold(a.file, a.sets, o, std::cerr);
  const std::string csv = find_csv(res, o);
  std::cout << fmt::format("{} where {} {} {} (bisection to {}):\n", o.key, o.target.quantity,
                           o.target.op, o.target.value, o.tol);
  for (const auto& r : res.rows) {
    std::string where;
    for (std::size_t i = 0; i < r.sweep_labels.size(); ++i) {
      where += fmt::format("{}={} ", res.sweeps[i].key, r.sweep_labels[i]);
    }
    std::cout << fmt::format(
        "  {}{:<24} {} = {:<12} {} = {:<12} designs={} {}\n", where, r.estimator, o.key,
        r.threshold ? fmt::format("{:.6f}", *r.threshold) : std::string("none"), o.target.quantity,
        r.value ? fmt::format("{:.6g}", *r.value) : std::string("none"), r.evaluations, r.status);
  }
  if (!a.out.empty()) {
    nlohmann::json m;
    m["scenario"] = a.file;
    m["overrides"] = a.sets;
    m["command_line"] = command_line;
    m["ncosim_version"] = NCOSIM_VERSION;
    m["git_commit"] = NCOSIM_GIT_COMMIT;
    m["date"] = utc_now();
    write_files_atomically(a.out, {{"find.csv", csv}, {"manifest.json", m.dump(2) + "\n"}});
    std::cout << fmt::format("find.csv written to {}/\n", a.out);
  }
  return 0;
}

int cmd_codesign(const CommonArgs& a, const CodesignOptions& opt, const std::string& command_line) {
  LoadedScenario loaded = load_cases(a.file, a.sets, a.overrides);
  if (loaded.cases.size() != 1) {
    throw config::ScenarioError(config::format_error(
        a.file, 0, "sweep", "expected a scenario without [[sweep]] for codesign"));
  }
  const std::string out = a.out.empty() ? default_out(a.file) : a.out;
  prepare_output_dir(out);
  const OutputFolderLock lock(out);
  const Scenario& sc = *loaded.cases.front().scenario;
  const nlohmann::json j = run_codesign(sc, opt);
  write_files_atomically(
      out, {{"codesign.json", j.dump(2) + "\n"},
            {"manifest.json", manifest(loaded, command_line, 1, 0.0).dump(2) + "\n"}});
  const bool all_ok = print_codesign(j, std::cout);  // sim/cmd/codesign.h
  std::cout << fmt::format("codesign.json written to {}/\n", out);
  if (!all_ok) {
    std::cerr << "ncosim: codesign: a status is not ok (see above and codesign.json)\n";
    return kExitFlagged;
  }
  return 0;
}

int cmd_check(const CommonArgs& a) {
  RunOverrides overrides = a.overrides;
  if (a.seed >= 0) overrides.seed = static_cast<std::uint64_t>(a.seed);
  LoadedScenario loaded = load_cases(a.file, a.sets, overrides);
  std::cout << fmt::format("{}: ok ({} case(s), {} estimator(s))\n", a.file, loaded.cases.size(),
                           loaded.cases.front().scenario->estimators.size());
  return 0;
}

template <class R>
void list_registry(const char* what, const R& registry) {
  std::cout << what << ":\n";
  for (const auto& e : registry.entries())
    std::cout << fmt::format("  {:<18} {}\n", e.name, e.help);
}

int cmd_list() {
  list_registry("plant kinds ([plant] kind)", plant_registry());
  list_registry("link kinds ([[link]] kind)", link_registry());
  list_registry("input kinds ([input] kind)", input_registry());
  list_registry("estimator kinds ([[estimator]] kind)", estimator_registry());
  list_registry("send policies ([[sensor]] policy)", send_policy_registry());
  list_fit_families();  // sim/cmd/list_keys.h
#if NCOSIM_HAVE_SUMO
  std::cout << "channel presets (sumo_distance preset; see `ncosim channel PRESET`):\n";
  for (const auto& n : sumo::preset_names())
    std::cout << fmt::format("  {:<18} {}\n", n, sumo::preset_help(n));
#endif
  return 0;
}

}  // namespace

namespace {

// Every option's storage and every subcommand of the command line (run_cli), filled by CLI11.
struct CommandLine {
  CLI::App app{"ncosim: discrete-event co-simulator for state estimation over networks"};
  CommonArgs a;
  int threads = 0;
  bool trace = false;
  bool quiet = false;
  std::string keys_kind, keys_format = "text";  // list --keys [KIND] --format
  double max_memory_mb = resource_limits().memory_bytes / 1e6;
  double max_work_gflop = resource_limits().work_flops / 1e9;
  std::vector<CLI::Option*> out_options;
  RunCommand run_cmd;
  CliHooks hooks;
  std::string columns_text;  // --columns a,b,c
  std::string export_dir, export_out;
  bool export_replace = false, merge_replace = false;
  std::string merge_out;
  std::vector<std::string> merge_dirs;
  std::string export_c_dir;
  FindOptions find_opt;
  std::string target_text;
  CodesignOptions cd_opt;
  CompareCommand cmp;
  FigureCommands figure_commands;
  std::string preset;
  bool csv = false, gnuplot = false;
  double max_distance = 1000.0, step = 10.0;
  CLI::App *run = nullptr, *export_cmd = nullptr, *merge = nullptr, *design = nullptr,
           *find = nullptr, *codesign = nullptr, *compare = nullptr, *check = nullptr,
           *channel = nullptr, *fit = nullptr;
  FitArgs fit_args;
  CLI::App* record_link = nullptr;  // sim/cmd/record_link.h
  CLI::App* schema = nullptr;       // sim/cmd/schema.h
  CLI::App* ladder = nullptr;       // sim/cmd/ladder.h
  LadderArgs ladder_args;
  std::string schema_out;
  std::string record_link_name;

  // FILE, --set, --out (when `with_out`) and the resource limits of a command that reads a
  // scenario.
  void add_common(CLI::App* sub, bool with_out) {
    sub->add_option("FILE", a.file, "scenario file (TOML)")->required();
    sub->add_option("--set", a.sets,
                    "override one key before validation: KEY=VALUE (VALUE in TOML)");
    if (with_out)
      out_options.push_back(
          sub->add_option("--out", a.out, "output directory (default: out/<file stem>)"));
    sub->add_option("--max-memory", max_memory_mb,
                    fmt::format("memory limit in MB of a design or campaign, estimated before it "
                                "starts (default {:.0f})",
                                max_memory_mb))
        ->check(number_range(1.0, 1e9));
    sub->add_option(
           "--max-work", max_work_gflop,
           fmt::format(
               "work limit in GFLOP of one design, estimated before it starts (default {:.0f})",
               max_work_gflop))
        ->check(number_range(1e-9, 1e12));
  }

  // run, export, merge: the campaign and its run store.
  void add_campaign_commands() {
    run = app.add_subcommand("run", "run the Monte Carlo campaign and write the results");
    add_common(run, true);
    // Ranges as in [run] (CLI::PositiveNumber would print its bound as a 300-digit double).
    run->add_option("--runs", a.overrides.runs, "Monte Carlo runs (overrides run.runs)")
        ->check(CLI::Range(std::int64_t{1}, std::int64_t{10'000'000}));
    run->add_option("--periods", a.overrides.periods, "periods per run (overrides run.periods)")
        ->check(CLI::Range(std::int64_t{1}, std::int64_t{1'000'000'000}));
    run->add_option("--seed", a.seed, "campaign seed (overrides run.seed)")->check(seed_range());
    run->add_option("--threads", threads, "worker threads (default: all cores)")
        ->check(CLI::Range(0, 4096));
    run->add_flag("--trace", trace, "also write trajectory.csv (x, xhat, arrivals of run 0)");
    run->add_flag("--quiet", quiet, "no progress line");
    run->add_flag(
        "--resume", run_cmd.resume,
        "continue the campaign whose run store (runs.sqlite) is in --out: only the missing runs");
    run->add_flag(
        "--replace", run_cmd.replace,
        "start afresh and replace the run store in --out even when it holds runs of a different or "
        "unfinished campaign");
    run->add_flag("!--no-timing", run_cmd.timing,
                  "do not measure ns_per_period (no replay after the campaign)");
    run->add_option("--shard", run_cmd.shard,
                    "run the shard I of N (1-based): the runs r with r % N == I-1");
    run->add_option("--target-ci", run_cmd.target_ci,
                    "run batches of run.runs until every row's 95% CI half-width of mse is within "
                    "REL of its mean");
    run->add_option("--max-runs", run_cmd.max_runs, "with --target-ci: the most runs per case")
        ->check(CLI::Range(std::int64_t{1}, std::int64_t{10'000'000}));
    export_cmd =
        app.add_subcommand("export", "re-derive every export of a campaign from its run store");
    export_cmd->add_option("DIR", export_dir, "output folder holding runs.sqlite")->required();
    export_cmd->add_option("--out", export_out, "write the exports here instead of DIR");
    export_cmd->add_flag("--replace", export_replace,
                         "replace the run store in --out even when it holds runs of a different "
                         "campaign or runs DIR's store lacks");
    merge = app.add_subcommand("merge", "combine the run stores of a campaign's shards and export");
    merge->add_option("OUT", merge_out, "output folder of the merged campaign")->required();
    merge->add_option("DIR", merge_dirs, "output folders of the shards (each with runs.sqlite)")
        ->required();
    merge->add_flag("--replace", merge_replace,
                    "replace the run store in OUT (or an unfinished one beside it) even when it "
                    "holds runs of a different campaign or runs the shards lack");
    run->add_option("--columns", columns_text,
                    "the summary.csv columns printed on stdout, comma-separated (default: those "
                    "that fit the terminal: COLUMNS, its width, 120 when not a terminal)");
    run->add_option(
        "--format", run_cmd.format,
        "what stdout gets: md (the Markdown table), csv (summary.csv's text) or json "
        "(an array of rows); "
        "default: the table fitted to the terminal (COLUMNS, else its width, else 120)");
    run->add_flag("--fail-on-status", run_cmd.fail_on_status,
                  "exit 3 (after writing the results) when any row's status is not its expected "
                  "one (default ok; "
                  "[[estimator]] expected_status) or a network link is overloaded (links.csv "
                  "overload), listing those rows and links");
  }

  // design, find, codesign: offline design.
  void add_design_commands() {
    design = app.add_subcommand("design", "offline design only: write design.json and design.csv");
    add_common(design, true);
    design->add_option("--export-c", export_c_dir,
                       "also write a C99 header and source per jump estimator into this directory");
    find = app.add_subcommand(
        "find",
        "the value of one key at which a design quantity reaches a target (scan + bisection)");
    add_common(find, false);
    out_options.push_back(find->add_option(
        "--out", a.out, "also write find.csv and manifest.json into this directory"));
    find->add_option(
            "--key", find_opt.key,
            "scenario key path to vary, set as a float (e.g. link[0].delivery), or an entry "
            "of an array of numbers (e.g. link[0].pmf[1])")
        ->required();
    find->add_option("--target", target_text,
                     "QUANTITY<=VALUE (or >=, <, >) on a design.json field, "
                     "e.g. 'predicted_mse<=0.03'")
        ->required();
    find->add_option("--estimator", find_opt.estimators,
                     "estimator name (repeatable; default: every estimator)");
    find->add_option("--lo", find_opt.lo, "lower end of the key's range")->required();
    find->add_option("--hi", find_opt.hi, "upper end of the key's range")->required();
    find->add_option("--tol", find_opt.tol,
                     "bisection stops when the bracket is narrower (default 1e-4)");
    find->add_option("--scan", find_opt.scan,
                     "equal intervals scanned before the bisection, to bracket and check "
                     "monotonicity (default 8)")
        ->check(CLI::Range(1, 100000));
    codesign = app.add_subcommand("codesign",
                                  "send-on-delta threshold co-design (greedy, section 4) of the "
                                  "sod_jump estimators: codesign.json");
    add_common(codesign, true);
    codesign->add_option("--estimator", cd_opt.estimator, "only this sod_jump estimator");
    codesign->add_option("--mu", cd_opt.mu, "prescribed bound mu * z~0 (overrides [codesign] mu)")
        ->check(number_range(1.0, 1e6));
    codesign->add_flag("--quiet", quiet, "no progress lines");
  }

  // fit and record-link: a link's trace recorded and fitted.
  void add_trace_commands() {
    fit = app.add_subcommand(
        "fit", "fit channel models to a packet trace (seq,delay): a [[link]] table and fit.csv");
    fit->add_option("TRACE", fit_args.trace,
                    "trace CSV in the `trace` link's format (seq,delay; empty delay = lost)")
        ->required();
    fit->add_option("--out", fit_args.out, "output directory (default: out/fit_<trace stem>)");
    fit->add_option(
        "--family", fit_args.families,
        "family to fit (repeatable): bernoulli, delay, gilbert_elliott, markov2 .. markov8 "
        "(default: bernoulli, delay, gilbert_elliott, markov2, markov3)");
    fit->add_option("--criterion", fit_args.criterion,
                    "bic (default) or aic: which family link.toml proposes");
    fit->add_option("--starts", fit_args.starts, "EM starts per hidden-state family (default 4)")
        ->check(CLI::Range(1, 100));
    fit->add_option("--name", fit_args.name,
                    "name of the [[link]] table (default: the trace's file stem)");
    fit->add_option("--max-iterations", fit_args.max_iterations,
                    "EM iterations per hidden-state family before it is reported not converged "
                    "(default 2000)")
        ->check(CLI::Range(1, 1'000'000));
    fit->add_flag("--verbose", fit_args.verbose, "print every family's every parameter");
    record_link = app.add_subcommand("record-link",
                                     "the fate of every packet one link carries, run after run, as "
                                     "a trace (seq,delay) per case");
    add_common(record_link, true);
    record_link->add_option("--link", record_link_name, "the [[link]] to record (its name)")
        ->required();
    record_link->add_option("--runs", a.overrides.runs, "runs recorded (overrides run.runs)")
        ->check(CLI::Range(std::int64_t{1}, std::int64_t{10'000'000}));
    record_link
        ->add_option("--periods", a.overrides.periods, "periods per run (overrides run.periods)")
        ->check(CLI::Range(std::int64_t{1}, std::int64_t{1'000'000'000}));
    record_link->add_option("--seed", a.seed, "campaign seed (overrides run.seed)")
        ->check(seed_range());
    record_link->add_flag("--quiet", quiet, "no progress lines");
    record_link
        ->add_option("--threads", threads,
                     "a network link's runs simulated at a time (default: all cores)")
        ->check(CLI::Range(0, 4096));
  }

  // check, with what run's options change validated as run would see it (the Python check()
  // passes them).
  void add_check_command() {
    check = app.add_subcommand("check", "parse and validate only");
    add_common(check, false);
    check->add_option("--runs", a.overrides.runs, "Monte Carlo runs (overrides run.runs)")
        ->check(CLI::Range(std::int64_t{1}, std::int64_t{10'000'000}));
    check->add_option("--periods", a.overrides.periods, "periods per run (overrides run.periods)")
        ->check(CLI::Range(std::int64_t{1}, std::int64_t{1'000'000'000}));
    check->add_option("--seed", a.seed, "campaign seed (overrides run.seed)")->check(seed_range());
  }

  // compare, check, list, plot, report, fit, record-link, ladder and (SUMO builds) channel.
  void add_other_commands() {
    compare = app.add_subcommand("compare",
                                 "compare two `run` output folders row by row (paired where the "
                                 "seeds match): exit 1 on a regression, 4 when inconclusive "
                                 "(docs/compare.md)");
    compare->add_option("BASE", cmp.base, "the baseline output folder")->required();
    compare->add_option("NEW", cmp.fresh, "the output folder to check")->required();
    compare->add_option("--metric", cmp.options.metric,
                        "per-run column of runs.csv (default mse; mse_ext, mde_percent, rmse_xI)");
    compare->add_option("--tolerance", cmp.options.tolerance,
                        "relative band of the typical per-run ratio: worse above 1 + T, better "
                        "below 1 - T, unchanged when shown inside (default 0.05)");
    compare->add_option("--alpha", cmp.options.alpha,
                        "level of each one-sided test, in (0, 0.5); intervals at 1 - 2 alpha "
                        "(default 0.05)");
    compare
        ->add_option("--correction", cmp.correction,
                     "multiple-testing correction over the rows (default holm)")
        ->check(CLI::IsMember({"holm", "none"}));
    compare->add_flag("--allow-inconclusive", cmp.options.allow_inconclusive,
                      "an inconclusive row (too few runs to tell) passes: exit 0 instead of 4");
    compare->add_flag("--allow-scenario-change", cmp.options.allow_scenario_change,
                      "compare folders of another scenario text, --set or input files (other "
                      "--runs, --periods or "
                      "--seed need no option); rows in one folder only are not comparable");
    compare->add_option("--out", cmp.out,
                        "also write compare.csv and compare.md into this directory");
    add_check_command();
    CLI::App* list = app.add_subcommand("list", "list every registered kind with a one-line help");
    list->add_option("--keys", keys_kind,
                     "print the declared keys of KIND (e.g. link.bernoulli), or of every kind")
        ->expected(0, 1);
    list->add_option("--format", keys_format, "text (default) or md (a Markdown table)")
        ->check(CLI::IsMember({"text", "md"}));
    schema = app.add_subcommand(
        "schema", "write a JSON Schema (draft-07) of the scenario format, for TOML editors");
    schema->add_option("--out", schema_out, "write it into this file (default: stdout)");
    add_figure_commands(app, figure_commands);
    add_trace_commands();
    ladder = add_ladder_command(app, ladder_args);
    add_common(ladder, true);
    ladder->get_option("--out")->description("output folder (default: out/ladder_<file stem>)");
    if (have_sumo()) {
      channel = app.add_subcommand(
          "channel", "print p(d) and the delay law of a sumo_distance channel preset");
      channel->add_option("PRESET", preset, "channel preset (see `ncosim list`)")->required();
      channel->add_flag("--csv", csv, "CSV: distance_m,mean_rx_dbm,p_reception");
      channel->add_flag("--gnuplot", gnuplot, "print a gnuplot script plotting the CSV");
      channel->add_option("--max-distance", max_distance, "largest distance (m, default 1000)");
      channel->add_option("--step", step, "distance step (m, default 10)");
    }
  }

  // The parsed command, run. Throws what the commands throw.
  int dispatch(const std::string& command_line) {
    if (run->parsed()) {
      run_cmd.threads = threads;
      run_cmd.trace = trace;
      run_cmd.quiet = quiet;
      run_cmd.command_line = command_line;
      run_cmd.progress_observer = hooks.progress;
      run_cmd.second_signal_aborts = hooks.second_signal_aborts;
      if (run->count("--columns") != 0)
        run_cmd.columns = parse_column_list(columns_text);  // sim/present/table_view.h
      return cmd_run(a, run_cmd);
    }
    if (export_cmd->parsed())
      return cmd_export(export_dir, export_out, export_replace, command_line);
    if (merge->parsed()) return cmd_merge(merge_out, merge_dirs, merge_replace, command_line);
    if (design->parsed()) return cmd_design(a, command_line, export_c_dir);
    if (find->parsed()) return cmd_find(a, find_opt, target_text, command_line);
    if (check->parsed()) return cmd_check(a);
    if (compare->parsed()) return run_compare_command(cmp);
    if (fit->parsed()) return cmd_fit(fit_args);
    if (schema->parsed()) return cmd_schema(schema_out);
    if (record_link->parsed()) {
      RecordLinkArgs r{a.file, a.sets, a.overrides, record_link_name, a.out, quiet, threads};
      if (a.seed >= 0) r.overrides.seed = static_cast<std::uint64_t>(a.seed);
      return cmd_record_link(r);
    }
    if (ladder->parsed()) {
      ladder_args.file = a.file;
      ladder_args.sets = a.sets;
      ladder_args.out = a.out;
      ladder_args.command_line = command_line;
      return cmd_ladder(ladder_args);
    }
    if (const auto status = run_figure_commands(figure_commands)) return *status;
    if (codesign->parsed()) {
      cd_opt.progress = !quiet;
      return cmd_codesign(a, cd_opt, command_line);
    }
#if NCOSIM_HAVE_SUMO
    if (channel != nullptr && channel->parsed())
      return sumo::channel_command(preset, csv, gnuplot, max_distance, step);
#endif
    if (keys_format == "md" || app.get_subcommand("list")->get_option("--keys")->count() > 0)
      return cmd_list_keys(keys_kind, keys_format == "md");  // sim/cmd/list_keys.h
    return cmd_list();
  }
};

// An unknown command named with a did-you-mean (CLI11 would only say "A subcommand is
// required"): exit status 2, or nothing when argv[1] is a command or an option.
std::optional<int> unknown_command(const CLI::App& app, int argc, char** argv) {
  if (argc <= 1 || argv[1][0] == '-') return std::nullopt;
  std::vector<std::string> commands;
  for (const CLI::App* sub : app.get_subcommands({})) commands.push_back(sub->get_name());
  if (std::find(commands.begin(), commands.end(), argv[1]) != commands.end()) return std::nullopt;
  const std::string hint = config::did_you_mean(argv[1], commands);
  std::cerr << fmt::format(
      "ncosim: expected a command (run, export, merge, design, find, codesign, compare, fit, "
      "record-link, ladder, check, plot, report or list), got "
      "'{}'{}\n",
      argv[1], hint.empty() ? "" : fmt::format(" (did you mean '{}'?)", hint));
  return 2;
}

// The hidden commands of the processes a run starts: a network worker (network/worker.h), started
// by a run whose networks need a process of their own, and a live SUMO run stepped in this process
// (a [sumo] mode = "live" run); nullopt for any other command, once the executable those workers
// are started as is set: this one, or the embedder's.
std::optional<int> hidden_worker(int argc, char** argv, const CliHooks& hooks) {
  if (argc > 1 && std::string_view(argv[1]) == "network-worker")
    return network::worker_main(network_registry());
#if NCOSIM_HAVE_SUMO
  if (argc > 1 && std::string_view(argv[1]) == "sumo-live")
    return sumo::live_worker_main(std::vector<std::string>(argv + 2, argv + argc));
#endif
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  const std::string exe = !hooks.worker_executable.empty() ? hooks.worker_executable
                          : !ec                            ? self.string()
                                                           : std::string();
  if (!exe.empty()) {
    network::set_worker_executable(exe);
#if NCOSIM_HAVE_SUMO
    sumo::set_worker_executable(exe);
#endif
  }
  return std::nullopt;
}

}  // namespace

int run_cli(int argc, char** argv) { return run_cli(argc, argv, CliHooks{}); }

int run_cli(int argc, char** argv, const CliHooks& hooks) {
  if (const auto status = hidden_worker(argc, argv, hooks)) return *status;
  CommandLine cl;
  cl.hooks = hooks;
  CLI::App& app = cl.app;
  app.set_version_flag("--version",
                       fmt::format("ncosim {} ({})", NCOSIM_VERSION, NCOSIM_GIT_COMMIT));
  app.require_subcommand(1);
  cl.add_campaign_commands();
  cl.add_design_commands();
  cl.add_other_commands();
  if (const auto status = unknown_command(app, argc, argv)) return *status;
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
  for (const CLI::Option* o : cl.out_options) {
    if (o->count() > 0 && cl.a.out.empty()) {
      std::cerr << "ncosim: --out: expected a folder name, got an empty string\n";
      return 2;
    }
  }
  set_resource_limits({cl.max_memory_mb * 1e6, cl.max_work_gflop * 1e9});
  const auto code = [&]() -> int {
    try {
      return cl.dispatch(command_line);
    } catch (const config::ScenarioError& e) {
      // Every error of a file on its own line (one error's message may hold several lines).
      if (e.messages().size() == 1) {
        std::cerr << "ncosim: " << e.what() << "\n";
        return 2;
      }
      std::string_view text = e.what();
      for (std::size_t end; (end = text.find('\n')) != std::string_view::npos;
           text.remove_prefix(end + 1))
        std::cerr << "ncosim: " << text.substr(0, end) << "\n";
      std::cerr << "ncosim: " << text << "\n";
      return 2;
    } catch (const lmi::ResourceLimitError& e) {
      std::cerr << "ncosim: " << e.what() << " (--max-memory / --max-work raise the limits)\n";
      return 2;
    } catch (const std::bad_alloc&) {
      std::cerr << "ncosim: error: out of memory (std::bad_alloc) beyond what the resource "
                   "estimates foresaw; "
                   "lower run.runs, run.periods or the model size, or free memory\n";
      return 1;
    } catch (const std::exception& e) {
      std::cerr << "ncosim: error: " << e.what() << "\n";
      return 1;
    }
  }();
  // Under mpirun (`run`): MPI ends only now, after rank 0 reported its error; every rank exits
  // with rank 0's code (sim/cmd/mpi_campaign.h).
  return mpi_finish(code);
}

}  // namespace ncosim::sim
