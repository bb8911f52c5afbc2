// sim/present/table_view.cc — the stdout table of `run` (sim/present/table_view.h).
#include "sim/present/table_view.h"

#include <fmt/format.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <map>
#include <nlohmann/json.hpp>

#include "config/config.h"

namespace ncosim::sim {

namespace {

// Width in code points, so "±", "Δ" and "–" count once (as a terminal shows them).
std::size_t width_of(const std::string& s) {
  std::size_t w = 0;
  for (unsigned char ch : s) w += (ch & 0xC0) != 0x80;
  return w;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

}  // namespace

std::size_t table_width(const char* columns_env, int fd) {
  std::size_t width = 0;
  if (columns_env != nullptr && *columns_env != '\0') {
    const char* end = columns_env + std::char_traits<char>::length(columns_env);
    std::size_t v = 0;
    const auto [ptr, ec] = std::from_chars(columns_env, end, v);
    if (ec == std::errc() && ptr == end && v > 0) width = v;
  }
  if (width == 0 && ::isatty(fd) != 0) {
    winsize ws{};
    if (::ioctl(fd, TIOCGWINSZ, &ws) == 0 && ws.ws_col > 0) width = ws.ws_col;
  }
  if (width == 0) width = kDefaultTableWidth;
  return std::max(width, kNarrowestTableWidth);
}

std::vector<std::string> parse_column_list(const std::string& text) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (true) {
    const auto comma = text.find(',', start);
    const std::string name =
        trim(text.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (name.empty()) {
      throw config::ScenarioError(
          fmt::format("--columns: expected a comma-separated list of summary.csv column names, got "
                      "\"{}\" (an empty name)",
                      text));
    }
    out.push_back(name);
    if (comma == std::string::npos) return out;
    start = comma + 1;
  }
}

void check_table_request(const TableRequest& req, const std::vector<std::string>& valid_columns) {
  if (!req.format.empty() && req.format != "md" && req.format != "csv" && req.format != "json") {
    throw config::ScenarioError(
        fmt::format("--format: expected md, csv or json, got \"{}\"", req.format));
  }
  for (const auto& c : req.columns) {
    if (std::find(valid_columns.begin(), valid_columns.end(), c) != valid_columns.end()) continue;
    std::string list;
    for (const auto& v : valid_columns) list += (list.empty() ? "" : ", ") + v;
    const std::string hint = config::did_you_mean(c, valid_columns);
    throw config::ScenarioError(
        fmt::format("--columns: no summary.csv column \"{}\"{} (this campaign's columns: {})", c,
                    hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint), list));
  }
}

std::string wrap_text(const std::string& text, std::size_t width, std::size_t indent) {
  std::size_t start = std::min(text.find_first_not_of(' '), text.size());
  std::string out, line = text.substr(0, start);  // the text's own indent stays
  while (start <= text.size()) {
    auto end = text.find(' ', start);
    if (end == std::string::npos) end = text.size();
    const std::string word = text.substr(start, end - start);
    const bool words = line.find_first_not_of(' ') != std::string::npos;
    if (words && width_of(line) + 1 + width_of(word) > width) {
      out += line + "\n";
      line = std::string(indent, ' ');
    }
    if (!word.empty()) line += (line.empty() || line.back() == ' ' ? "" : " ") + word;
    start = end + 1;
  }
  return out + line + "\n";
}

namespace {

// A footnote: the text rows share (a note's head) and, per row, what is particular to it.
struct Footnote {
  std::string head;
  std::vector<std::pair<std::size_t, std::string>> tails;  // (row, tail)
};

// A note's head and row-specific tail: split at its last ": " ("design model not followed
// (...): predicted mse_ext 0.19, simulated 0.11"), so rows with the same reason share it.
std::pair<std::string, std::string> split_note(const std::string& text) {
  const auto colon = text.rfind(": ");
  if (colon == std::string::npos || colon == 0) return {text, ""};
  return {text.substr(0, colon), text.substr(colon + 2)};
}

// Replaces the note cells and the long cells of `cols` by references [k]; returns the notes.
std::vector<Footnote> make_footnotes(std::vector<ViewColumn>& cols) {
  std::vector<Footnote> notes;
  std::map<std::string, std::size_t> index;
  for (auto& col : cols) {
    for (std::size_t r = 0; r < col.cells.size(); ++r) {
      std::string& cell = col.cells[r];
      if (col.priority == 0 || (!col.note && width_of(cell) <= kLongCell) || cell.empty() ||
          cell == "–")
        continue;
      auto [head, tail] =
          col.note ? split_note(cell) : std::pair<std::string, std::string>{cell, ""};
      auto [it, added] = index.emplace(head, notes.size());
      if (added) notes.push_back(Footnote{head, {}});
      notes[it->second].tails.emplace_back(r, tail);
      cell = fmt::format("[{}]", it->second + 1);
    }
  }
  return notes;
}

std::string footnote_text(const std::vector<Footnote>& notes,
                          const std::vector<std::string>& row_labels, std::size_t width) {
  std::string out;
  for (std::size_t k = 0; k < notes.size(); ++k) {
    const auto& n = notes[k];
    bool same = true;  // every row's tail the same: printed once with the head
    for (const auto& t : n.tails) same = same && t.second == n.tails.front().second;
    const std::string tail =
        same && !n.tails.front().second.empty() ? ": " + n.tails.front().second : "";
    out += wrap_text(fmt::format("[{}] {}{}{}", k + 1, n.head, tail, same ? "" : ":"), width, 4);
    if (same) continue;
    for (const auto& [r, t] : n.tails) {
      out += wrap_text(fmt::format("    {}: {}", r < row_labels.size() ? row_labels[r] : "", t),
                       width, 6);
    }
  }
  return out;
}

std::size_t table_width(const std::vector<ViewColumn>& cols) {
  std::size_t w = 1;
  for (const auto& c : cols) {
    std::size_t cw = std::max<std::size_t>(3, width_of(c.header));
    for (const auto& s : c.cells) cw = std::max(cw, width_of(s));
    w += cw + 3;
  }
  return w;
}

std::string render(const std::vector<ViewColumn>& cols) {
  std::vector<std::size_t> wid;
  for (const auto& c : cols) {
    std::size_t cw = std::max<std::size_t>(3, width_of(c.header));
    for (const auto& s : c.cells) cw = std::max(cw, width_of(s));
    wid.push_back(cw);
  }
  auto line = [&](auto cell) {
    std::string out = "|";
    for (std::size_t i = 0; i < cols.size(); ++i) {
      const std::string s = cell(i);
      out += " " + s + std::string(wid[i] - width_of(s), ' ') + " |";
    }
    return out + "\n";
  };
  std::string out = line([&](std::size_t i) { return cols[i].header; });
  std::string sep = "|";
  for (const auto w : wid) sep += std::string(w + 2, '-') + "|";
  out += sep + "\n";
  const std::size_t rows = cols.empty() ? 0 : cols.front().cells.size();
  for (std::size_t r = 0; r < rows; ++r)
    out += line([&](std::size_t i) { return cols[i].cells[r]; });
  return out;
}

}  // namespace

std::string fit_table(std::vector<ViewColumn> cols, const std::vector<std::string>& row_labels,
                      std::size_t width, bool can_drop, std::vector<std::string>* kept) {
  // Leave out the lowest-priority column (the rightmost of equals) until the rows fit; the
  // references are numbered again for the columns kept.
  std::vector<std::string> order;
  for (const auto& c : cols) order.push_back(c.name);
  std::vector<std::string> left_out;
  while (can_drop) {
    auto trial = cols;
    make_footnotes(trial);
    if (table_width(trial) <= width) break;
    auto low = cols.end();
    for (auto it = cols.begin(); it != cols.end(); ++it) {
      if (it->priority > 0 && (low == cols.end() || it->priority >= low->priority)) low = it;
    }
    if (low == cols.end()) break;  // only the row's identity is left: shown whole, never wrapped
    left_out.push_back(low->name);
    cols.erase(low);
  }
  auto position = [&](const std::string& name) {
    return std::find(order.begin(), order.end(), name) - order.begin();
  };
  std::sort(left_out.begin(), left_out.end(),
            [&](const std::string& a, const std::string& b) { return position(a) < position(b); });
  if (kept != nullptr) {
    kept->clear();
    for (const auto& c : cols) kept->push_back(c.name);
  }
  const auto notes = make_footnotes(cols);
  std::string out = render(cols);
  if (!notes.empty()) out += "\n" + footnote_text(notes, row_labels, width);
  if (!left_out.empty()) {
    std::string names;
    for (const auto& n : left_out) names += (names.empty() ? "" : ", ") + n;
    out += "\n" +
           wrap_text(
               fmt::format(
                   "Left out to fit {} columns: {} (`--columns` picks any; summary.csv has every "
                   "column).",
                   width, names),
               width, 4);
  }
  return out;
}

namespace {

std::string pm(std::optional<double> v, std::optional<double> ci) {
  if (!v || !std::isfinite(*v)) return "–";
  return ci && std::isfinite(*ci) ? fmt::format("{:.4g} ± {:.2g}", *v, *ci)
                                  : fmt::format("{:.4g}", *v);
}

std::string num(std::optional<double> v) {
  return v && std::isfinite(*v) ? fmt::format("{:.4g}", *v) : "–";
}

template <typename F>
bool any_row(const std::vector<SummaryRow>& rows, F f) {
  return std::any_of(rows.begin(), rows.end(), f);
}

// The default columns (display order; priority: 0 identifies the row, larger goes first).
std::vector<ViewColumn> default_columns(const std::vector<SweepAxis>& sweeps,
                                        const std::vector<SummaryRow>& rows) {
  std::vector<ViewColumn> cols;
  auto add = [&](std::string name, std::string header, int priority, auto cell, bool note = false) {
    ViewColumn c{std::move(name), std::move(header), {}, priority, note};
    for (const auto& r : rows) c.cells.push_back(cell(r));
    cols.push_back(std::move(c));
  };
  for (std::size_t i = 0; i < sweeps.size(); ++i) {
    add(sweeps[i].key, sweeps[i].key, 0, [i](const SummaryRow& r) { return r.sweep_labels.at(i); });
  }
  add("estimator", "estimator", 0, [](const SummaryRow& r) { return r.estimator; });
  add("mse", "mse ± 95% CI", 1, [](const SummaryRow& r) { return pm(r.mse, r.mse_ci95); });
  if (any_row(rows, [](const SummaryRow& r) { return r.mse_ext.has_value(); })) {
    add("mse_ext", "mse_ext ± 95% CI", 3,
        [](const SummaryRow& r) { return pm(r.mse_ext, r.mse_ext_ci95); });
  }
  if (any_row(rows, [](const SummaryRow& r) { return r.predicted_mse_ext.has_value(); })) {
    add("predicted_mse_ext", "pred. mse_ext", 4,
        [](const SummaryRow& r) { return num(r.predicted_mse_ext); });
  }
  if (any_row(rows, [](const SummaryRow& r) { return r.predicted_mse.has_value(); })) {
    add("predicted_mse", "pred. mse", 6, [](const SummaryRow& r) { return num(r.predicted_mse); });
  }
  if (any_row(rows, [](const SummaryRow& r) { return r.mde_percent.has_value(); })) {
    add("mde_percent", "MDE % ± 95% CI", 2,
        [](const SummaryRow& r) { return pm(r.mde_percent, r.mde_ci95); });
  }
  add("status", "status", 1, [](const SummaryRow& r) { return status_text(r); });
  if (any_row(rows, [](const SummaryRow& r) { return r.paired.mse.diff.has_value(); })) {
    add("mse_diff", "Δmse vs ref ± CI", 5,
        [](const SummaryRow& r) { return pm(r.paired.mse.diff, r.paired.mse.diff_ci95); });
  }
  if (!sweeps.empty() &&
      any_row(rows, [](const SummaryRow& r) { return r.paired.case_mse.diff.has_value(); })) {
    add("case_mse_diff", "Δmse vs ref case ± CI", 6, [](const SummaryRow& r) {
      return pm(r.paired.case_mse.diff, r.paired.case_mse.diff_ci95);
    });
  }
  const std::size_t n = rows.empty() ? 0 : rows.front().rmse.size();
  for (std::size_t i = 0; i < n; ++i) {
    add(fmt::format("rmse_x{}", i + 1), fmt::format("rmse_x{}", i + 1), 8,
        [i](const SummaryRow& r) { return num(r.rmse.at(i)); });
  }
  if (any_row(rows, [](const SummaryRow& r) { return !r.model_check.empty(); })) {
    add(
        "model_check", "note", 2, [](const SummaryRow& r) { return r.model_check; }, true);
  }
  return cols;
}

// The chosen summary.csv columns of `t` (every one when `names` is empty).
SummaryText select_columns(const SummaryText& t, const std::vector<std::string>& names) {
  if (names.empty()) return t;
  SummaryText out{names, std::vector<std::vector<std::string>>(t.cells.size())};
  for (const auto& name : names) {
    const auto c = static_cast<std::size_t>(std::find(t.header.begin(), t.header.end(), name) -
                                            t.header.begin());
    for (std::size_t r = 0; r < t.cells.size(); ++r)
      out.cells[r].push_back(c < t.header.size() ? t.cells[r][c] : "");
  }
  return out;
}

// Text columns of summary.csv; every other non-empty cell is a number in JSON.
bool text_column(const std::string& name, const std::vector<SweepAxis>& sweeps) {
  for (const auto& s : sweeps) {
    if (s.key == name) return true;
  }
  for (const char* c : {"estimator", "kind", "status", "paired_reference", "reference_case",
                        "model_check", "stop", "expected_status"}) {
    if (name == c) return true;
  }
  return false;
}

std::string json_rows(const SummaryText& t, const std::vector<SweepAxis>& sweeps) {
  nlohmann::ordered_json arr = nlohmann::ordered_json::array();
  for (const auto& cells : t.cells) {
    nlohmann::ordered_json row = nlohmann::ordered_json::object();
    for (std::size_t i = 0; i < t.header.size(); ++i) {
      const std::string& s = cells[i];
      char* end = nullptr;
      const double v = s.empty() ? 0.0 : std::strtod(s.c_str(), &end);
      if (text_column(t.header[i], sweeps))
        row[t.header[i]] = s;
      else if (s.empty())
        row[t.header[i]] = nullptr;
      else if (end != nullptr && *end == '\0' && std::isfinite(v))
        row[t.header[i]] = v;
      else
        row[t.header[i]] = s;
    }
    arr.push_back(std::move(row));
  }
  return arr.dump(2) + "\n";
}

// The chosen columns as a table shows them: cells as in summary.csv, but `status` as in the
// default table (status_text: "diverged (expected)"), the rows being `rows`.
std::vector<ViewColumn> text_columns(const SummaryText& t, const std::vector<SummaryRow>& rows) {
  std::vector<ViewColumn> cols;
  for (std::size_t i = 0; i < t.header.size(); ++i) {
    const std::string& name = t.header[i];
    ViewColumn c{name, name, {}, name == "estimator" ? 0 : 1, name == "model_check"};
    for (std::size_t r = 0; r < t.cells.size(); ++r) {
      c.cells.push_back(name == "status" && r < rows.size() ? status_text(rows[r]) : t.cells[r][i]);
    }
    cols.push_back(std::move(c));
  }
  return cols;
}

// The line under summary.md's table that names the paired references, when it is there.
std::string paired_line(const std::string& summary_md) {
  const auto at = summary_md.find("\nPaired columns: ");
  if (at == std::string::npos) return "";
  const auto end = summary_md.find('\n', at + 1);
  return summary_md.substr(at + 1, end == std::string::npos ? std::string::npos : end - at - 1);
}

}  // namespace

std::string stdout_table(const TableRequest& req, const std::string& title,
                         const std::vector<SweepAxis>& sweeps, const std::vector<SummaryRow>& rows,
                         Eigen::Index n, const std::string& summary_md, const std::string& extras) {
  const SummaryText chosen = select_columns(summary_text(sweeps, rows, n), req.columns);
  if (req.format == "csv") return summary_text_csv(chosen);
  if (req.format == "json") return json_rows(chosen, sweeps);
  if (req.format == "md" && req.columns.empty()) return summary_md + extras;
  const std::string head = fmt::format("# {}\n\n", title);
  if (req.format == "md") return head + render(text_columns(chosen, rows)) + extras;
  const std::string fitted_head = wrap_text("# " + title, req.width, 2) + "\n";
  std::vector<std::string> labels;
  for (const auto& r : rows) {
    std::string where;
    for (std::size_t i = 0; i < r.sweep_labels.size() && i < sweeps.size(); ++i) {
      where += fmt::format("{} = {}, ", sweeps[i].key, r.sweep_labels[i]);
    }
    labels.push_back(fmt::format("{}\"{}\"", where, r.estimator));
  }
  const bool chosen_columns = !req.columns.empty();
  auto cols = chosen_columns ? text_columns(chosen, rows) : default_columns(sweeps, rows);
  std::vector<std::string> kept;
  std::string out =
      fitted_head + fit_table(std::move(cols), labels, req.width, !chosen_columns, &kept);
  const bool paired = std::find(kept.begin(), kept.end(), "mse_diff") != kept.end();
  const std::string pl = paired_line(summary_md);
  // The line also says when a reference has no values to pair with (every Δ column empty).
  const bool empty_reference = pl.find("paired columns are empty") != std::string::npos;
  if (!chosen_columns && (paired || empty_reference) && !pl.empty())
    out += "\n" + wrap_text(pl, req.width, 0);
  std::size_t start = 0;  // the extras, each line wrapped
  while (start < extras.size()) {
    const auto end = extras.find('\n', start);
    const std::string l =
        extras.substr(start, end == std::string::npos ? std::string::npos : end - start);
    out += l.empty() ? "\n" : wrap_text(l, req.width, 0);
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return out;
}

}  // namespace ncosim::sim
