// sim/present/report.cc — `ncosim report`: one self-contained HTML page of an output folder.
#include "sim/present/report.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "config/config.h"
#include "sim/analysis/output.h"
#include "sim/present/report_parts.h"

namespace ncosim::sim {

namespace fs = std::filesystem;
using namespace report_parts;  // sim/present/report_parts.h

namespace {

void replace_all(std::string& s, const std::string& from, const std::string& to) {
  for (std::size_t pos = s.find(from); pos != std::string::npos;
       pos = s.find(from, pos + to.size())) {
    s.replace(pos, from.size(), to);
  }
}

// The columns a summary.csv of this version writes; any other column (e.g. the paired comparison
// against a reference estimator) is shown in its own table.
bool known_column(const std::string& c) {
  static const std::set<std::string> known{
      "estimator",        "kind",           "runs",          "mse",
      "mse_ci95",         "mse_ext",        "mse_ext_ci95",  "mde_percent",
      "flops_per_period", "stored_gains",   "ns_per_period", "predicted_mse_ext",
      "delivered_ratio",  "status",         "predicted_mse", "flops_mean",
      "mde_ci95",         "sent_per_period"};
  if (known.count(c) != 0) return true;
  return c.rfind("rmse_x", 0) == 0;  // ermse_x*: with the further columns (a narrower table)
}

constexpr const char* kCss = R"(
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; margin: 1.5em auto; max-width: 1300px;
       padding: 0 1em; color: #1a1a1a; line-height: 1.4; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; margin-top: 1.6em; }
.sub { color: #555; margin-top: 0; }
table { border-collapse: collapse; margin: 0.5em 0; font-size: 0.85em; }
th, td { border: 1px solid #d0d0d0; padding: 0.2em 0.5em; text-align: right; white-space: nowrap; }
th { background: #f0f2f5; position: sticky; top: 0; }
td.t, th.t { text-align: left; }
td.status { white-space: normal; min-width: 6em; max-width: 20em; }
th { white-space: normal; vertical-align: bottom; } span.ci { display: block; color: #555; font-size: 0.9em; }
tr.bad td { background: #fde2e1; } td.status-bad { color: #a40000; font-weight: bold; }
tr.expected td { background: #f0f0f0; color: #444; }
div.expected { background: #f0f2f5; border: 1px solid #ccc; padding: 0.5em 1em; margin-top: 0.5em; }
td.best { font-weight: bold; background: #e3f4e1; }
.warn { background: #fff4ce; border: 1px solid #e0c060; padding: 0.5em 1em; }
.ok { background: #e3f4e1; border: 1px solid #9c9; padding: 0.5em 1em; }
.scroll { overflow-x: auto; }
figure { margin: 1em 0; } figure svg { max-width: 100%; height: auto; border: 1px solid #eee; }
figcaption { color: #555; font-size: 0.9em; }
details { margin: 0.3em 0; } summary { cursor: pointer; font-weight: 600; }
pre { background: #f6f8fa; padding: 0.8em; overflow-x: auto; font-size: 0.85em; }
nav ul { columns: 3; font-size: 0.9em; }
)";

struct SummaryTable {
  CsvTable t;
  std::vector<int> keys;  // sweep key columns
  int est = -1, status = -1;
  int expected = -1;  // expected_status ([[estimator]] expected_status), -1 when absent

  // Row r's status is neither ok nor the one its scenario expects (expected_status).
  bool bad(const std::vector<std::string>& r) const {
    return status >= 0 && !status_as_expected(r[static_cast<std::size_t>(status)], expected_of(r));
  }
  // Row r's status is not ok but the one its scenario expects: told, not flagged.
  bool expected_failure(const std::vector<std::string>& r) const {
    return status >= 0 && !bad(r) && r[static_cast<std::size_t>(status)] != "ok";
  }
  // The status as the run's table prints it: "diverged (expected)", "ok (expected diverged)".
  std::string status_text(const std::vector<std::string>& r) const {
    const std::string& st = r[static_cast<std::size_t>(status)];
    const std::string ex = expected_of(r);
    if (ex.empty()) return st;
    if (!bad(r)) return st == "ok" ? st : st + " (expected)";
    return st + " (expected " + ex + ")";
  }

 private:
  std::string expected_of(const std::vector<std::string>& r) const {
    return expected >= 0 ? r[static_cast<std::size_t>(expected)] : "";
  }
};

// Cell text of column c: "value ± ci" when a c_ci95 column exists.
// The CI on a line of its own under the value (a narrower column).
std::string cell(const CsvTable& t, const std::vector<std::string>& r, int c, int ci) {
  std::string v = html_escape(r[static_cast<std::size_t>(c)]);
  if (ci >= 0 && !r[static_cast<std::size_t>(ci)].empty())
    v += "<span class=\"ci\"> ± " + html_escape(r[static_cast<std::size_t>(ci)]) + "</span>";
  (void)t;
  return v;
}

double to_double(const std::string& s) {
  try {
    std::size_t used = 0;
    const double v = std::stod(s, &used);
    return used == s.size() ? v : NAN;
  } catch (const std::exception&) {
    return NAN;
  }
}

// One HTML table of `rows` (indices into t.rows) over the given columns.
std::string html_table(const SummaryTable& tb, const std::vector<std::size_t>& rows,
                       const std::vector<int>& cols, bool mark_best) {
  const CsvTable& t = tb.t;
  std::string h = "<div class=\"scroll\"><table>\n<tr>";
  std::vector<int> ci(cols.size(), -1);
  for (std::size_t i = 0; i < cols.size(); ++i) {
    const std::string& name = t.header[static_cast<std::size_t>(cols[i])];
    ci[i] = t.column(name + "_ci95");
    const bool text = cols[i] == tb.est || name == "kind" || cols[i] == tb.status;
    h += fmt::format("<th{}>{}{}</th>", text ? " class=\"t\"" : "", header_text(name),
                     ci[i] >= 0 ? " ± 95 % CI" : "");
  }
  h += "</tr>\n";
  // Lowest mse of the rows (marked when it is a number and rows > 1).
  const int mse = t.column("mse");
  double best = INFINITY;
  if (mark_best && mse >= 0) {
    for (std::size_t r : rows) {
      const double v = to_double(t.rows[r][static_cast<std::size_t>(mse)]);
      if (v < best) best = v;
    }
  }
  for (std::size_t r : rows) {
    const auto& row = t.rows[r];
    const bool bad = tb.bad(row), expected = tb.expected_failure(row);
    h += bad ? "<tr class=\"bad\">" : expected ? "<tr class=\"expected\">" : "<tr>";
    for (std::size_t i = 0; i < cols.size(); ++i) {
      const int c = cols[i];
      std::string cls;
      if (c == tb.est || t.header[static_cast<std::size_t>(c)] == "kind") cls = "t";
      if (c == tb.status) cls = bad ? "t status status-bad" : "t status";
      if (c == mse && rows.size() > 1 && to_double(row[static_cast<std::size_t>(c)]) == best)
        cls = "best";
      h += fmt::format("<td{}>{}</td>", cls.empty() ? "" : fmt::format(" class=\"{}\"", cls),
                       c == tb.status ? html_escape(tb.status_text(row)) : cell(t, row, c, ci[i]));
    }
    h += "</tr>\n";
  }
  return h + "</table></div>\n";
}

// summary.csv of `dir` with its sweep key, estimator and status columns; throws when unreadable.
SummaryTable read_summary_table(const std::string& dir) {
  const fs::path sp = fs::path(dir) / "summary.csv";
  const auto stext = try_read(sp);
  if (!stext)
    throw config::ScenarioError(
        fmt::format("{}: cannot read (is this an ncosim output folder?)", sp.string()));
  SummaryTable tb;
  tb.t = parse_csv(*stext, sp.string());
  tb.est = tb.t.column("estimator");
  tb.status = tb.t.column("status");
  tb.expected = tb.t.column("expected_status");
  if (tb.est < 0)
    throw config::ScenarioError(
        config::format_error(sp.string(), 1, "", "expected an `estimator` column"));
  for (int i = 0; i < tb.est; ++i) tb.keys.push_back(i);
  return tb;
}

// manifest.json of `dir`, or an empty object when it is missing or unreadable.
nlohmann::json read_manifest(const std::string& dir) {
  if (const auto m = try_read(fs::path(dir) / "manifest.json")) {
    try {
      return nlohmann::json::parse(*m);
    } catch (const std::exception&) {
    }
  }
  return nlohmann::json::object();
}

// The sweep cases of summary.csv: consecutive rows with the same sweep labels.
struct Cases {
  std::vector<std::vector<std::size_t>> rows;  // row indices of each case
  std::vector<std::string> labels;             // "key = value, ..." ("" without sweep keys)
};

Cases split_cases(const SummaryTable& tb) {
  const CsvTable& t = tb.t;
  Cases cases;
  for (std::size_t r = 0; r < t.rows.size(); ++r) {
    std::string label;
    for (int k : tb.keys) {
      label +=
          fmt::format("{}{} = {}", label.empty() ? "" : ", ", t.header[static_cast<std::size_t>(k)],
                      t.rows[r][static_cast<std::size_t>(k)]);
    }
    if (cases.rows.empty() || cases.labels.back() != label) {
      cases.rows.emplace_back();
      cases.labels.push_back(label);
    }
    cases.rows.back().push_back(r);
  }
  return cases;
}

// Columns from `estimator` on: the known ones that hold a value somewhere (ci columns merged
// into their value's cell) in `main_cols`, the others in `extra_cols`.
void split_columns(const SummaryTable& tb, std::vector<int>& main_cols,
                   std::vector<int>& extra_cols) {
  const CsvTable& t = tb.t;
  for (int c = tb.est; c < static_cast<int>(t.header.size()); ++c) {
    const std::string& name = t.header[static_cast<std::size_t>(c)];
    const bool ci_of_shown = name.size() > 5 && name.compare(name.size() - 5, 5, "_ci95") == 0 &&
                             t.column(name.substr(0, name.size() - 5)) >= 0;
    if (ci_of_shown) continue;
    bool any = c == tb.est || c == tb.status;
    for (const auto& r : t.rows) any = any || !r[static_cast<std::size_t>(c)].empty();
    if (!any) continue;
    (known_column(name) ? main_cols : extra_cols).push_back(c);
  }
  // The status next to the estimator, where a wide table's scroll never hides it.
  const auto st = std::find(main_cols.begin(), main_cols.end(), tb.status);
  if (st != main_cols.end() && !main_cols.empty() && main_cols.front() == tb.est) {
    main_cols.erase(st);
    main_cols.insert(main_cols.begin() + 1, tb.status);
  }
}

// The document's head, title and the line under it (scenario, cases, estimators, runs, seed,
// folder).
std::string page_head(const std::string& dir, const nlohmann::json& man, const std::string& title,
                      const Cases& cases) {
  std::string h = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\"/>\n";
  h += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"/>\n";
  h += fmt::format("<title>{} — ncosim report</title>\n<style>{}</style>\n</head>\n<body>\n",
                   html_escape(title), kCss);
  h += fmt::format("<h1>{}</h1>\n", html_escape(title));
  h += fmt::format(
      "<p class=\"sub\">{} · {} case(s) · {} estimator(s){}{}{} · folder {}</p>\n",
      man.contains("scenario") ? html_escape(json_text(man["scenario"])) : "scenario unknown",
      cases.rows.size(), cases.rows.empty() ? 0 : cases.rows.front().size(),
      man.contains("runs") ? fmt::format(" · {} runs", html_escape(json_text(man["runs"]))) : "",
      man.contains("periods") ? fmt::format(" × {} periods", html_escape(json_text(man["periods"])))
                              : "",
      man.contains("seed") ? fmt::format(" · seed {}", html_escape(json_text(man["seed"]))) : "",
      html_escape(dir));
  return h;
}

// Warnings: every row whose status is neither ok nor the one its scenario expects (or a line
// saying there is none); the rows whose failure status is the expected one, listed apart as
// expected (e.g. an open-loop reference that diverges by design); the re-centring note.
std::string warnings_section(const std::string& dir, const SummaryTable& tb, const Cases& cases,
                             const nlohmann::json& man) {
  const CsvTable& t = tb.t;
  std::string warn, expected;
  for (std::size_t c = 0; c < cases.rows.size() && tb.status >= 0; ++c) {
    for (std::size_t r : cases.rows[c]) {
      const auto& row = t.rows[r];
      if (!tb.bad(row) && !tb.expected_failure(row)) continue;
      (tb.bad(row) ? warn : expected) += fmt::format(
          "<li>{}{}: <b>{}</b></li>\n",
          cases.labels[c].empty() ? "" : html_escape(cases.labels[c]) + " · ",
          html_escape(row[static_cast<std::size_t>(tb.est)]), html_escape(tb.status_text(row)));
    }
  }
  std::string h;
  if (!warn.empty()) {
    h += "<div class=\"warn\" id=\"warnings\"><b>Rows whose status is not the expected one</b> "
         "(not trustworthy; expected: ok unless the scenario declares expected_status; see the "
         "status column in results/README.md):\n<ul>\n" +
         warn + "</ul></div>\n";
  } else {
    h += fmt::format("<p class=\"ok\" id=\"warnings\">Every row has status ok{}.</p>\n",
                     expected.empty() ? "" : " or the status its scenario expects");
  }
  if (!expected.empty()) {
    h += "<div class=\"expected\" id=\"expected\"><b>Rows with their expected status</b> (the "
         "scenario declares it with expected_status: an outcome the campaign is meant to show, "
         "not a fault):\n<ul>\n" +
         expected + "</ul></div>\n";
  }
  if (man.contains("recentred") && man["recentred"].is_boolean() && man["recentred"].get<bool>()) {
    // trajectory.csv only where this folder has one (a run without --trace writes none).
    h += fmt::format(
        "<p class=\"sub\">The plant was simulated re-centred (scenarios/README.md); metrics are "
        "unaffected{}.</p>\n",
        fs::exists(fs::path(dir) / "trajectory.csv")
            ? ", trajectory.csv carries the physical state in its x*_physical columns"
            : "");
  }
  return h;
}

// The table of contents; the further-columns section only when there is one.
std::string contents_nav(bool further) {
  std::string h =
      "<nav><b>Contents:</b> <a href=\"#figures\">figures</a> · <a href=\"#summary\">summary</a>";
  if (further) h += " · <a href=\"#further\">paired comparison / further columns</a>";
  h += " · <a href=\"#design\">design</a> · <a href=\"#manifest\">manifest</a> · <a "
       "href=\"#scenario\">scenario</a></nav>\n";
  return h;
}

// The figures, inlined as SVG with ids prefixed per figure (f1-, f2-, ...).
std::string figures_section(const std::vector<ReportFigure>& figures) {
  std::string h = "<h2 id=\"figures\">Figures</h2>\n";
  if (figures.empty()) h += "<p>No figures (report written with --no-figures).</p>\n";
  for (std::size_t i = 0; i < figures.size(); ++i) {
    h += fmt::format(
        "<figure id=\"fig-{}\">\n{}\n<figcaption>Figure {}: {}</figcaption>\n</figure>\n", i + 1,
        inline_svg(figures[i].svg, fmt::format("f{}-", i + 1)), i + 1,
        html_escape(figures[i].title));
  }
  return h;
}

// Several cases: one row per case, one column per estimator (mse ± CI), linked to the case's
// section; the lowest mse of a case green, a row not ok red with its status.
std::string case_overview(const SummaryTable& tb, const Cases& cases) {
  const CsvTable& t = tb.t;
  const int mse = t.column("mse"), mci = t.column("mse_ci95");
  std::string h =
      "<h3 id=\"overview\">mse per case and estimator</h3>\n<div class=\"scroll\"><table>\n<tr><th "
      "class=\"t\">case</th>";
  for (std::size_t r : cases.rows.front()) {
    h += fmt::format("<th>{}</th>", html_escape(t.rows[r][static_cast<std::size_t>(tb.est)]));
  }
  h += "</tr>\n";
  for (std::size_t c = 0; c < cases.rows.size(); ++c) {
    h += fmt::format("<tr><td class=\"t\"><a href=\"#case-{}\">{}</a></td>", c + 1,
                     html_escape(cases.labels[c]));
    double best = INFINITY;
    for (std::size_t r : cases.rows[c]) {
      best = std::min(best, mse >= 0 ? to_double(t.rows[r][static_cast<std::size_t>(mse)]) : NAN);
    }
    for (std::size_t r : cases.rows[c]) {
      const auto& row = t.rows[r];
      const bool bad = tb.bad(row), told = bad || tb.expected_failure(row);
      const bool is_best = mse >= 0 && to_double(row[static_cast<std::size_t>(mse)]) == best;
      h += fmt::format("<td{}>{}{}</td>",
                       bad ? " class=\"status-bad\"" : (is_best ? " class=\"best\"" : ""),
                       mse >= 0 ? cell(t, row, mse, mci) : "",
                       told ? " " + html_escape(tb.status_text(row)) : "");
    }
    h += "</tr>\n";
  }
  return h + "</table></div>\n";
}

// The summary: one table, or with several cases the overview and one folded table per case.
std::string summary_section(const SummaryTable& tb, const Cases& cases,
                            const std::vector<int>& main_cols) {
  std::string h = "<h2 id=\"summary\">Summary</h2>\n";
  h += "<p class=\"sub\">Numbers as written in summary.csv (columns: results/README.md); rows "
       "whose status is neither ok nor the expected one are red, rows with their expected "
       "failure status grey; the lowest mse of each case is green. Columns empty in every row "
       "are left out.</p>\n";
  if (cases.rows.size() <= 1) {
    return h + html_table(tb, cases.rows.empty() ? std::vector<std::size_t>{} : cases.rows.front(),
                          main_cols, true);
  }
  h += case_overview(tb, cases) + "<h3>Every case</h3>\n";
  for (std::size_t c = 0; c < cases.rows.size(); ++c) {
    h += fmt::format("<details id=\"case-{}\"><summary>case {}: {}</summary>\n{}</details>\n",
                     c + 1, c + 1, html_escape(cases.labels[c]),
                     html_table(tb, cases.rows[c], main_cols, true));
  }
  return h;
}

// The columns beyond the known ones (e.g. the paired comparison), every row in one table.
std::string further_section(const SummaryTable& tb, const Cases& cases,
                            const std::vector<int>& extra_cols) {
  std::string h = "<h2 id=\"further\">Paired comparison and further columns</h2>\n";
  h += "<p class=\"sub\">Columns of summary.csv beyond the ones above (for instance the paired "
       "differences "
       "against the reference estimator), as written.</p>\n";
  std::vector<int> cols = tb.keys;
  cols.push_back(tb.est);
  cols.insert(cols.end(), extra_cols.begin(), extra_cols.end());
  std::vector<std::size_t> all(tb.t.rows.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
  const std::string table = html_table(tb, all, cols, false);
  h += cases.rows.size() > 1 ? "<details><summary>every case</summary>\n" + table + "</details>\n"
                             : table;
  return h;
}

}  // namespace

std::string inline_svg(const std::string& svg, const std::string& prefix) {
  const auto start = svg.find("<svg");
  std::string s = start == std::string::npos ? svg : svg.substr(start);
  for (const char q : {'"', '\''}) {
    replace_all(s, fmt::format(" id={}", q), fmt::format(" id={}{}", q, prefix));
    replace_all(s, fmt::format("href={}#", q), fmt::format("href={}#{}", q, prefix));
  }
  replace_all(s, "url(#", "url(#" + prefix);
  // gnuplot repeats ids across the panels of a multiplot (gnuplot_plot_1a in each): the second
  // and later copies get a suffix, so that every id of the page is unique.
  std::map<std::string, int> seen;
  std::string out;
  out.reserve(s.size() + 64);
  std::size_t pos = 0;
  for (;;) {
    std::size_t a = std::string::npos;
    char q = '"';
    for (const char c : {'"', '\''}) {
      const std::size_t p = s.find(fmt::format(" id={}", c), pos);
      if (p < a) {
        a = p;
        q = c;
      }
    }
    if (a == std::string::npos) break;
    const std::size_t v = a + 5, e = s.find(q, v);
    if (e == std::string::npos) break;
    const std::string id = s.substr(v, e - v);
    out.append(s, pos, e - pos);
    if (const int n = seen[id]++; n > 0) out += fmt::format("-{}", n);
    pos = e;
  }
  out.append(s, pos, std::string::npos);
  return out;
}

std::string build_report(const std::string& dir, const std::vector<ReportFigure>& figures) {
  const SummaryTable tb = read_summary_table(dir);
  const nlohmann::json man = read_manifest(dir);
  const std::string title =
      man.contains("title") ? json_text(man["title"]) : fs::path(dir).filename().string();
  const Cases cases = split_cases(tb);
  std::vector<int> main_cols, extra_cols;
  split_columns(tb, main_cols, extra_cols);

  std::string h;
  h.reserve(64 * 1024);
  h += page_head(dir, man, title, cases);
  h += warnings_section(dir, tb, cases, man);
  h += contents_nav(!extra_cols.empty());
  h += figures_section(figures);
  h += summary_section(tb, cases, main_cols);
  if (!extra_cols.empty()) h += further_section(tb, cases, extra_cols);
  h += "<h2 id=\"design\">Design</h2>\n" + design_section(dir);
  h += manifest_section(man);
  h += scenario_section(dir, man);
  h += "<p class=\"sub\">Written by <code>ncosim report</code>; self-contained (no script, no "
       "network).</p>\n";
  h += "</body>\n</html>\n";
  return h;
}

int report_command(const std::string& dir, const ReportOptions& opt) {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  if (!fs::is_directory(dir)) throw config::ScenarioError(fmt::format("{}: not a directory", dir));
  PlotOptions po = opt.plot;
  po.formats = {"svg"};
  std::vector<Figure> figs;
  if (opt.figures) {
    figs = build_figures(dir, po);
    // The extended-state metric as well, where the summary has it and it is not the chosen one.
    if (po.metric == "mse") {
      const auto t = parse_csv(try_read(fs::path(dir) / "summary.csv").value_or(""), "summary.csv");
      const int c = t.column("mse_ext");
      bool any = false;
      for (const auto& r : t.rows) any = any || (c >= 0 && !r[static_cast<std::size_t>(c)].empty());
      if (any) {
        PlotOptions pe = po;
        pe.metric = "mse_ext";
        pe.trace = false;
        figs.insert(figs.begin() + 1, build_figures(dir, pe).front());
      }
    }
    if (!po.trace && fs::exists(fs::path(dir) / "trajectory.csv")) {
      PlotOptions pt = po;
      pt.trace = true;
      for (auto& f : build_figures(dir, pt)) {
        if (f.kind == FigureKind::kTrace) figs.push_back(std::move(f));
      }
    }
  }
  const auto t1 = clock::now();
  if (!figs.empty()) render_figures(dir, figs, {"svg"});
  const auto t2 = clock::now();
  std::vector<ReportFigure> rf;
  for (const auto& f : figs) {
    const auto svg = try_read(fs::path(dir) / (f.name + ".svg"));
    if (!svg) throw std::runtime_error(fmt::format("gnuplot wrote no {}.svg in {}", f.name, dir));
    rf.push_back({f.title, *svg});
  }
  const std::string html = build_report(dir, rf);
  const fs::path out = opt.out.empty() ? fs::path(dir) / "report.html" : fs::path(opt.out);
  write_files_atomically(out.parent_path().empty() ? "." : out.parent_path().string(),
                         {{out.filename().string(), html}});
  const auto t3 = clock::now();
  const double gnuplot_s = std::chrono::duration<double>(t2 - t1).count();
  const double total_s = std::chrono::duration<double>(t3 - t0).count();
  std::cout << fmt::format(
      "{} written ({:.0f} KB, {} figure(s)) in {:.3f} s: {:.3f} s without gnuplot, {:.3f} s "
      "gnuplot\n",
      out.string(), static_cast<double>(html.size()) / 1024.0, rf.size(), total_s,
      total_s - gnuplot_s, gnuplot_s);
  return 0;
}

}  // namespace ncosim::sim
