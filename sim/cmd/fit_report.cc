// sim/cmd/fit_report.cc — the outputs of `ncosim fit` (sim/cmd/fit_report.h).
#include "sim/cmd/fit_report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <vector>

#include "sim/analysis/output.h"

namespace ncosim::sim {

namespace {

// A link table printed whole up to this many characters; longer ones stay in link.toml.
constexpr std::size_t kPrintedLinkChars = 800;

std::string opt(double v) { return std::isfinite(v) ? fmt::format("{:.9g}", v) : ""; }

nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

bool has_interval(const models::FitParameter& p) {
  return std::isfinite(p.ci_low) && std::isfinite(p.ci_high);
}

// "  NAME  ESTIMATE  [LOW, HIGH]  METHOD", or the reason there is no interval (said once: a
// reason already in `said` reads "as above").
std::string parameter_line(const models::FitParameter& p, std::vector<std::string>& said) {
  std::string tail;
  if (has_interval(p)) {
    tail = fmt::format("[{:.6g}, {:.6g}]  {}", p.ci_low, p.ci_high, p.interval);
    if (p.interval == "likelihood_ratio") tail += " (at the edge of its range)";
  } else if (p.note.empty()) {
    tail = "(no interval)";
  } else if (std::find(said.begin(), said.end(), p.note) != said.end()) {
    tail = "(no interval, as above)";
  } else {
    said.push_back(p.note);
    tail = fmt::format("({})", p.note);
  }
  return fmt::format("  {:<18} {:>12.6g}  {}\n", p.name, p.estimate, tail);
}

// The parameters of `r` (every one, or those marked for the summary with a line for the rest).
std::string parameters_text(const models::FitResult& r, bool every) {
  std::string s;
  std::size_t left = 0;
  std::string left_names;
  std::vector<std::string> said;
  for (const auto& p : r.params) {
    if (every || p.summary) {
      s += parameter_line(p, said);
      continue;
    }
    const std::string stem = p.name.substr(0, p.name.find('['));
    if (left_names.find(stem) == std::string::npos)
      left_names += (left_names.empty() ? "" : ", ") + stem;
    ++left;
  }
  for (const auto& p : r.derived) s += parameter_line(p, said);
  if (left > 0) {
    s += fmt::format("  ({} more: {}, in fit.json and fit.csv; --verbose prints them)\n", left,
                     left_names);
  }
  return s;
}

std::string converged_text(const models::FitResult& r) {
  if (r.iteration_cap == 0) return "-";
  return r.converged ? "yes" : "NO";
}

std::string family_table(const FitSet& s) {
  std::string out =
      fmt::format("{:<16} {:>14} {:>4} {:>14} {:>14} {:>10} {:>9} {:>9} {:>9}\n", "family",
                  "loglik", "k", "aic", "bic", "iterations", "converged", "burst_tv", "acf_rmse");
  for (std::size_t i = 0; i < s.fits.size(); ++i) {
    const auto& r = s.fits[i];
    out +=
        fmt::format("{:<16} {:>14.6f} {:>4} {:>14.3f} {:>14.3f} {:>10} {:>9} {:>9.4f} {:>9.4f}{}\n",
                    r.family, r.loglik, r.parameters, r.aic, r.bic,
                    r.iteration_cap == 0 ? "-" : std::to_string(r.iterations), converged_text(r),
                    r.burst_tv, r.acf_rmse, i == s.best ? "  <- " + s.criterion : std::string());
  }
  for (const auto& k : s.skipped) {
    const auto colon = k.find(": ");
    out += fmt::format("{:<16} skipped: {}\n", k.substr(0, colon),
                       colon == std::string::npos ? k : k.substr(colon + 2));
  }
  return out;
}

}  // namespace

std::string fit_summary(const FitSet& s, bool verbose) {
  std::string out = fmt::format(
      "{}: {} packets, {} lost (loss {:.6g}){}\n", s.trace, s.packets, s.lost,
      static_cast<double>(s.lost) / static_cast<double>(std::max<std::size_t>(s.packets, 1)),
      s.longest_delay < 0 ? std::string(", none delivered")
                          : fmt::format(", delays 0 .. {} periods", s.longest_delay));
  out += family_table(s);
  bool any_converged = false;
  for (const auto& r : s.fits) any_converged = any_converged || r.converged;
  for (const auto& r : s.fits) {
    if (!r.converged) out += fmt::format("{}: {}\n", r.family, r.note);
  }
  const auto& best = s.fits[s.best];
  if (!any_converged) {
    out += fmt::format(
        "warning: no family converged; {} has the smallest {} but is not at a maximum (raise "
        "--max-iterations)\n",
        best.family, s.criterion);
  }
  for (std::size_t i = 0; i < s.fits.size(); ++i) {
    if (i != s.best && !verbose) continue;
    const auto& r = s.fits[i];
    out += fmt::format("\n{}{}: estimates and 95 % intervals\n", r.family,
                       i == s.best ? fmt::format(", selected by {}", s.criterion) : "");
    out += parameters_text(r, verbose);
  }
  if (best.link_toml.size() <= kPrintedLinkChars || verbose) {
    out += "\n" + best.link_toml;
  } else {
    out += fmt::format("\nits [[link]] table ({} characters) is in link.toml\n",
                       best.link_toml.size());
  }
  return out;
}

std::string fit_json(const FitSet& s) {
  auto params = [](const std::vector<models::FitParameter>& ps) {
    nlohmann::json a = nlohmann::json::array();
    for (const auto& p : ps) {
      a.push_back({{"name", p.name},
                   {"estimate", number(p.estimate)},
                   {"ci95_low", number(p.ci_low)},
                   {"ci95_high", number(p.ci_high)},
                   {"interval", has_interval(p) ? p.interval : std::string()},
                   {"note", p.note}});
    }
    return a;
  };
  auto numbers = [](const std::vector<double>& v) {
    nlohmann::json a = nlohmann::json::array();
    for (const double x : v) a.push_back(number(x));
    return a;
  };
  nlohmann::json j;
  j["trace"] = s.trace;
  j["packets"] = s.packets;
  j["lost"] = s.lost;
  j["criterion"] = s.criterion;
  j["selected"] = s.fits[s.best].family;
  j["skipped"] = s.skipped;
  j["families"] = nlohmann::json::array();
  for (std::size_t i = 0; i < s.fits.size(); ++i) {
    const auto& r = s.fits[i];
    nlohmann::json f = {{"family", r.family},
                        {"states", r.states},
                        {"selected", i == s.best},
                        {"loglik", number(r.loglik)},
                        {"parameters", r.parameters},
                        {"aic", number(r.aic)},
                        {"bic", number(r.bic)},
                        {"iterations", r.iterations},
                        {"iteration_cap", r.iteration_cap},
                        {"starts", r.starts},
                        {"converged", r.converged},
                        {"note", r.note},
                        {"params", params(r.params)},
                        {"derived", params(r.derived)},
                        {"marginal_pmf", numbers(r.marginal_pmf())},
                        {"burst_tv", number(r.burst_tv)},
                        {"acf_rmse", number(r.acf_rmse)},
                        {"burst_observed", numbers(r.burst_observed)},
                        {"burst_model", numbers(r.burst_model)},
                        {"acf_observed", numbers(r.acf_observed)},
                        {"acf_model", numbers(r.acf_model)},
                        {"link_toml", r.link_toml}};
    j["families"].push_back(std::move(f));
  }
  return j.dump(2) + "\n";
}

std::string fit_csv(const FitSet& s) {
  std::string csv = "family,section,item,estimate,ci95_low,ci95_high,observed,interval\n";
  for (std::size_t i = 0; i < s.fits.size(); ++i) {
    const auto& r = s.fits[i];
    auto row = [&](const std::string& section, const std::string& item, const std::string& est,
                   const std::string& lo = "", const std::string& hi = "",
                   const std::string& obs = "", const std::string& how = "") {
      csv += fmt::format("{},{},{},{},{},{},{},{}\n", r.family, section, csv_field(item), est, lo,
                         hi, obs, how);
    };
    row("fit", "packets", std::to_string(s.packets));
    row("fit", "loglik", opt(r.loglik));
    row("fit", "parameters", std::to_string(r.parameters));
    row("fit", "aic", opt(r.aic));
    row("fit", "bic", opt(r.bic));
    row("fit", "iterations", std::to_string(r.iterations));
    row("fit", "starts", std::to_string(r.starts));
    row("fit", "converged", r.converged ? "1" : "0");
    row("fit", "burst_tv", opt(r.burst_tv));
    row("fit", "acf_rmse", opt(r.acf_rmse));
    row("fit", "selected", i == s.best ? "1" : "0");
    for (const auto& p : r.params) {
      row("parameter", p.name, opt(p.estimate), opt(p.ci_low), opt(p.ci_high), "",
          has_interval(p) ? p.interval : "");
    }
    for (const auto& p : r.derived) {
      row("derived", p.name, opt(p.estimate), opt(p.ci_low), opt(p.ci_high), "",
          has_interval(p) ? p.interval : "");
    }
    for (std::size_t L = 0; L < r.burst_model.size(); ++L) {
      row("burst", std::to_string(L + 1), opt(r.burst_model[L]), "", "", opt(r.burst_observed[L]));
    }
    for (std::size_t k = 0; k < r.acf_model.size(); ++k) {
      row("acf", std::to_string(k + 1), opt(r.acf_model[k]), "", "", opt(r.acf_observed[k]));
    }
  }
  return csv;
}

std::string fit_link_toml(const FitSet& s) {
  const auto& best = s.fits[s.best];
  std::string toml =
      fmt::format("# ncosim fit {}: {} packets; selected by {} among the families below{}\n",
                  s.trace, s.packets, s.criterion, best.converged ? "" : " (NOT converged)");
  toml += best.link_toml;
  for (std::size_t i = 0; i < s.fits.size(); ++i) {
    if (i == s.best) continue;
    const auto& r = s.fits[i];
    toml += fmt::format("\n# {} (loglik {:.6g}, {} {:.6g}{}):\n", r.family, r.loglik, s.criterion,
                        s.criterion == "aic" ? r.aic : r.bic, r.converged ? "" : ", not converged");
    const std::string& text = r.link_toml;
    std::size_t pos = 0;
    while (pos < text.size()) {
      const std::size_t nl = text.find('\n', pos);
      toml += "# " + text.substr(pos, nl - pos) + "\n";
      pos = nl == std::string::npos ? text.size() : nl + 1;
    }
  }
  return toml;
}

}  // namespace ncosim::sim
