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

}  // namespace

int cmd_fit(const FitArgs& a) {
  models::FitOptions o;
  if (!a.families.empty()) o.families = a.families;
  // Unknown families fail before the trace is read.
  for (const auto& f : o.families) {
    if (models::family_states(f) == 0) {
      throw ScenarioError(fmt::format(
          "--family: expected bernoulli, delay, gilbert_elliott or markov2 .. markov8, got '{}'",
          f));
    }
  }
  if (a.criterion != "bic" && a.criterion != "aic") {
    throw ScenarioError(fmt::format("--criterion: expected bic or aic, got '{}'", a.criterion));
  }
  o.starts = a.starts;
  const std::string stem = std::filesystem::path(a.trace).stem().string();
  o.link_name = a.name.empty() ? stem : a.name;

  std::vector<std::optional<std::int64_t>> trace;
  int first_row_line = 1;
  try {
    trace = models::load_trace(a.trace, &first_row_line);
  } catch (const models::TraceError& e) {
    throw ScenarioError(e.line > 0 ? format_error(e.file, e.line, "", e.what())
                                   : std::string(e.what()));
  }
  const int last_line = count_lines(a.trace);
  if (trace.empty())
    throw ScenarioError(format_error(a.trace, last_line, "", "the trace holds no packet"));
  // The families' laws are dense in the delay: a longer delay is bad input at its line.
  for (std::size_t i = 0; i < trace.size(); ++i) {
    if (trace[i] && *trace[i] > models::kMaxFitDelay) {
      throw ScenarioError(
          format_error(a.trace, first_row_line + static_cast<int>(i), "",
                       fmt::format("delay: expected at most {} periods (the largest delay the fit "
                                   "families hold), got {}",
                                   models::kMaxFitDelay, *trace[i])));
    }
  }
  const std::vector<int> sym = models::fate_symbols(trace);

  std::vector<models::FitResult> fits;
  const auto t0 = std::chrono::steady_clock::now();
  for (const auto& f : o.families) {
    try {
      fits.push_back(models::fit_family(f, sym, o));
    } catch (const std::invalid_argument& e) {
      throw ScenarioError(
          format_error(a.trace, last_line, "",
                       fmt::format("{} (choose smaller families with --family)", e.what())));
    } catch (const std::domain_error& e) {
      if (a.families.empty()) {
        std::cerr << fmt::format("ncosim fit: {} skipped: {}\n", f, e.what());
        continue;
      }
      throw ScenarioError(
          format_error(a.trace, last_line, "", fmt::format("--family {}: {}", f, e.what())));
    }
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::size_t best = models::best_fit(fits, a.criterion);

  std::string csv = "family,section,item,estimate,ci95_low,ci95_high,observed\n";
  for (std::size_t i = 0; i < fits.size(); ++i) {
    const auto& r = fits[i];
    auto row = [&](const std::string& section, const std::string& item, const std::string& est,
                   const std::string& lo = "", const std::string& hi = "",
                   const std::string& obs = "") {
      csv += fmt::format("{},{},{},{},{},{},{}\n", r.family, section, csv_field(item), est, lo, hi,
                         obs);
    };
    row("fit", "packets", std::to_string(sym.size()));
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
  std::string toml =
      fmt::format("# ncosim fit {}: {} packets; selected by {} among the families below\n", a.trace,
                  sym.size(), a.criterion);
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
  // out/fit_<stem>: git-ignored, like `run`'s default (never a committed reference folder).
  const std::string out =
      a.out.empty() ? (std::filesystem::path("out") / ("fit_" + stem)).string() : a.out;
  prepare_output_dir(out);
  const OutputFolderLock lock(out);  // sim/files/output_set.h: one writer per folder
  write_files_atomically(out, {{"fit.csv", csv}, {"link.toml", toml}});

  std::cout << fmt::format("{}: {} packets, loss {:.6g}\n", a.trace, sym.size(),
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
  return 0;
}

}  // namespace ncosim::sim
