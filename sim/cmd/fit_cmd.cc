// sim/cmd/fit_cmd.cc — `ncosim fit`.
#include "sim/cmd/fit_cmd.h"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>

#include "config/config.h"
#include "models/fit.h"
#include "models/link.h"
#include "sim/analysis/output.h"
#include "sim/cmd/fit_report.h"
#include "sim/files/output_set.h"

namespace ncosim::sim {

namespace {

int count_lines(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) ++n;
  return std::max(n, 1);
}

// The fit's options from the command line: unknown families and criteria fail before the trace
// is read.
models::FitOptions fit_options(const FitArgs& a, const std::string& stem) {
  models::FitOptions o;
  if (!a.families.empty()) o.families = a.families;
  for (const auto& f : o.families) {
    if (models::family_states(f) == 0) {
      throw config::ScenarioError(fmt::format(
          "--family: expected bernoulli, delay, gilbert_elliott or markov2 .. markov8, got '{}'",
          f));
    }
  }
  if (a.criterion != "bic" && a.criterion != "aic") {
    throw config::ScenarioError(
        fmt::format("--criterion: expected bic or aic, got '{}'", a.criterion));
  }
  o.starts = a.starts;
  o.max_iterations = a.max_iterations;
  o.link_name = a.name.empty() ? stem : a.name;
  return o;
}

// The trace's packet fates as the fit's symbols; a trace error, an empty trace or a delay beyond
// the families' is a ScenarioError at its line (last_line: the trace's line count).
std::vector<int> trace_symbols(const std::string& path, int last_line) {
  std::vector<std::optional<std::int64_t>> trace;
  int first_row_line = 1;
  try {
    trace = models::load_trace(path, &first_row_line);
  } catch (const models::TraceError& e) {
    throw config::ScenarioError(e.line > 0 ? config::format_error(e.file, e.line, "", e.what())
                                           : std::string(e.what()));
  }
  if (trace.empty())
    throw config::ScenarioError(
        config::format_error(path, last_line, "", "the trace holds no packet"));
  // The families' laws are dense in the delay: a longer delay is bad input at its line.
  for (std::size_t i = 0; i < trace.size(); ++i) {
    if (trace[i] && *trace[i] > models::kMaxFitDelay) {
      throw config::ScenarioError(config::format_error(
          path, first_row_line + static_cast<int>(i), "",
          fmt::format("delay: expected at most {} periods (the largest delay the fit "
                      "families hold), got {}",
                      models::kMaxFitDelay, *trace[i])));
    }
  }
  return models::fate_symbols(trace);
}

// Each family fitted to the symbols; a family that cannot be fitted is skipped with a note when
// the families were not chosen, else an error.
std::vector<models::FitResult> fit_families(const FitArgs& a, const models::FitOptions& o,
                                            const std::vector<int>& sym, int last_line,
                                            std::vector<std::string>& skipped) {
  std::vector<models::FitResult> fits;
  for (const auto& f : o.families) {
    try {
      fits.push_back(models::fit_family(f, sym, o));
    } catch (const std::invalid_argument& e) {
      throw config::ScenarioError(config::format_error(
          a.trace, last_line, "",
          fmt::format("{} (choose smaller families with --family)", e.what())));
    } catch (const std::domain_error& e) {
      if (a.families.empty()) {
        skipped.push_back(fmt::format("{}: {}", f, e.what()));
        continue;
      }
      throw config::ScenarioError(config::format_error(
          a.trace, last_line, "", fmt::format("--family {}: {}", f, e.what())));
    }
  }
  return fits;
}

}  // namespace

int cmd_fit(const FitArgs& a) {
  const std::string stem = std::filesystem::path(a.trace).stem().string();
  const models::FitOptions o = fit_options(a, stem);
  const int last_line = count_lines(a.trace);
  const std::vector<int> sym = trace_symbols(a.trace, last_line);
  FitSet set;
  set.trace = a.trace;
  set.criterion = a.criterion;
  set.packets = sym.size();
  for (const int x : sym) {
    set.lost += x == 0 ? 1 : 0;
    set.longest_delay = std::max(set.longest_delay, x - 1);
  }
  const auto t0 = std::chrono::steady_clock::now();
  set.fits = fit_families(a, o, sym, last_line, set.skipped);
  set.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (set.fits.empty()) {
    throw config::ScenarioError(config::format_error(
        a.trace, last_line, "", "no family could be fitted (choose families with --family)"));
  }
  set.best = models::best_fit(set.fits, a.criterion);
  // out/fit_<stem>: git-ignored, like `run`'s default (never a committed reference folder).
  const std::string out =
      a.out.empty() ? (std::filesystem::path("out") / ("fit_" + stem)).string() : a.out;
  prepare_output_dir(out);
  const OutputFolderLock lock(out);  // sim/files/output_set.h: one writer per folder
  write_files_atomically(
      out,
      {{"fit.csv", fit_csv(set)}, {"fit.json", fit_json(set)}, {"link.toml", fit_link_toml(set)}});
  std::cout << fit_summary(set, a.verbose)
            << fmt::format("\nfitted in {:.2f} s; fit.csv, fit.json and link.toml written to {}/\n",
                           set.seconds, out);
  return 0;
}

}  // namespace ncosim::sim
