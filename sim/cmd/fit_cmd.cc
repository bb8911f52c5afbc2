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

std::string opt(double v) { return std::isfinite(v) ? fmt::format("{:.9g}", v) : ""; }

// "  NAME  ESTIMATE  [LOW, HIGH]" (the interval left out where none could be computed).
std::string parameter_line(const models::FitParameter& p) {
  const bool ci = std::isfinite(p.ci_low) && std::isfinite(p.ci_high);
  return fmt::format(
      "  {:<18} {:>12.6g}  {}\n", p.name, p.estimate,
      ci ? fmt::format("[{:.6g}, {:.6g}]", p.ci_low, p.ci_high) : std::string("(no interval)"));
}

// The selected family's parameters with their 95 % intervals (as in fit.csv), and the mean loss
// and mean burst of the Gilbert–Elliott fit (how a gilbert_elliott [[link]] is written).
std::string parameters_text(const std::vector<models::FitResult>& fits, std::size_t best) {
  std::string s = fmt::format("\n{} parameters, estimate and 95 % interval:\n", fits[best].family);
  for (const auto& p : fits[best].params) s += parameter_line(p);
  for (const auto& r : fits) {
    if (r.derived.empty()) continue;
    s += fmt::format(
        "{} as mean_loss and mean_burst (the keys of a gilbert_elliott [[link]]), 95 % interval:\n",
        r.family);
    for (const auto& p : r.derived) s += parameter_line(p);
  }
  return s;
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
                                            const std::vector<int>& sym, int last_line) {
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
        std::cerr << fmt::format("ncosim fit: {} skipped: {}\n", f, e.what());
        continue;
      }
      throw config::ScenarioError(config::format_error(
          a.trace, last_line, "", fmt::format("--family {}: {}", f, e.what())));
    }
  }
  return fits;
}

// fit.csv: per family its fit statistics, parameters, burst lengths and autocorrelations.
std::string fit_csv(const std::vector<models::FitResult>& fits, std::size_t packets,
                    std::size_t best) {
  std::string csv = "family,section,item,estimate,ci95_low,ci95_high,observed\n";
  for (std::size_t i = 0; i < fits.size(); ++i) {
    const auto& r = fits[i];
    auto row = [&](const std::string& section, const std::string& item, const std::string& est,
                   const std::string& lo = "", const std::string& hi = "",
                   const std::string& obs = "") {
      csv += fmt::format("{},{},{},{},{},{},{}\n", r.family, section, csv_field(item), est, lo, hi,
                         obs);
    };
    row("fit", "packets", std::to_string(packets));
    row("fit", "loglik", opt(r.loglik));
    row("fit", "parameters", std::to_string(r.parameters));
    row("fit", "aic", opt(r.aic));
    row("fit", "bic", opt(r.bic));
    row("fit", "iterations", std::to_string(r.iterations));
    row("fit", "starts", std::to_string(r.starts));
    row("fit", "converged", r.converged ? "1" : "0");
    row("fit", "burst_tv", opt(r.burst_tv));
    row("fit", "acf_rmse", opt(r.acf_rmse));
    row("fit", "selected", i == best ? "1" : "0");
    for (const auto& p : r.params)
      row("parameter", p.name, opt(p.estimate), opt(p.ci_low), opt(p.ci_high));
    for (std::size_t L = 0; L < r.burst_model.size(); ++L) {
      row("burst", std::to_string(L + 1), opt(r.burst_model[L]), "", "", opt(r.burst_observed[L]));
    }
    for (std::size_t k = 0; k < r.acf_model.size(); ++k) {
      row("acf", std::to_string(k + 1), opt(r.acf_model[k]), "", "", opt(r.acf_observed[k]));
    }
  }
  return csv;
}

// link.toml: the selected family's [[link]], then every other family's, commented out.
std::string link_toml(const FitArgs& a, const std::vector<models::FitResult>& fits,
                      std::size_t packets, std::size_t best) {
  std::string toml =
      fmt::format("# ncosim fit {}: {} packets; selected by {} among the families below\n", a.trace,
                  packets, a.criterion);
  toml += fits[best].link_toml;
  for (std::size_t i = 0; i < fits.size(); ++i) {
    if (i == best) continue;
    toml += fmt::format("\n# {} (loglik {:.6g}, {} {:.6g}):\n", fits[i].family, fits[i].loglik,
                        a.criterion, a.criterion == "aic" ? fits[i].aic : fits[i].bic);
    std::string text = fits[i].link_toml;
    std::string commented;
    std::size_t pos = 0;
    while (pos < text.size()) {
      const std::size_t nl = text.find('\n', pos);
      commented += "# " + text.substr(pos, nl - pos) + "\n";
      pos = nl == std::string::npos ? text.size() : nl + 1;
    }
    toml += commented;
  }
  return toml;
}

// What `ncosim fit` prints: the trace's loss, a table of the families, the selected family's
// parameters and its [[link]].
void print_fits(const FitArgs& a, const std::vector<models::FitResult>& fits, std::size_t packets,
                std::size_t best, double seconds, const std::string& out) {
  std::cout << fmt::format("{}: {} packets, loss {:.6g}\n", a.trace, packets,
                           fits.front().model.stationary().dot(fits.front().model.emission.col(0)));
  std::cout << fmt::format("{:<16} {:>14} {:>4} {:>14} {:>14} {:>6} {:>9} {:>9}\n", "family",
                           "loglik", "k", "aic", "bic", "iter", "burst_tv", "acf_rmse");
  for (std::size_t i = 0; i < fits.size(); ++i) {
    const auto& r = fits[i];
    std::cout << fmt::format(
        "{:<16} {:>14.6f} {:>4} {:>14.3f} {:>14.3f} {:>6} {:>9.4f} {:>9.4f}{}\n", r.family,
        r.loglik, r.parameters, r.aic, r.bic, r.iterations, r.burst_tv, r.acf_rmse,
        i == best ? "  <- " + a.criterion : std::string());
  }
  std::cout << parameters_text(fits, best);
  std::cout << fmt::format("\n{}\nfitted in {:.2f} s; fit.csv and link.toml written to {}/\n",
                           fits[best].link_toml, seconds, out);
}

}  // namespace

int cmd_fit(const FitArgs& a) {
  const std::string stem = std::filesystem::path(a.trace).stem().string();
  const models::FitOptions o = fit_options(a, stem);
  const int last_line = count_lines(a.trace);
  const std::vector<int> sym = trace_symbols(a.trace, last_line);
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<models::FitResult> fits = fit_families(a, o, sym, last_line);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::size_t best = models::best_fit(fits, a.criterion);
  const std::string csv = fit_csv(fits, sym.size(), best);
  const std::string toml = link_toml(a, fits, sym.size(), best);
  // out/fit_<stem>: git-ignored, like `run`'s default (never a committed reference folder).
  const std::string out =
      a.out.empty() ? (std::filesystem::path("out") / ("fit_" + stem)).string() : a.out;
  prepare_output_dir(out);
  const OutputFolderLock lock(out);  // sim/files/output_set.h: one writer per folder
  write_files_atomically(out, {{"fit.csv", csv}, {"link.toml", toml}});
  print_fits(a, fits, sym.size(), best, seconds, out);
  return 0;
}

}  // namespace ncosim::sim
