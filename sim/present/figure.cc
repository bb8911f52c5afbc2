// sim/present/figure.cc — see sim/present/figure.h.
#include "sim/present/figure.h"

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "config/config.h"

namespace ncosim::sim {

namespace fs = std::filesystem;

const char* figure_kind_name(FigureKind k) {
  switch (k) {
    case FigureKind::kPerEstimator:
      return "per_estimator";
    case FigureKind::kAgainstKey:
      return "against_key";
    case FigureKind::kPanels:
      return "panels";
    case FigureKind::kTrace:
      return "trace";
  }
  return "?";
}

std::string gnuplot_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) {
    if (c == '\'') {
      out += "''";
    } else if (c == '\n' || c == '\r' || c == '\t') {
      out += ' ';
    } else {
      out += c;
    }
  }
  return out + "'";
}

std::string gnuplot_colour(std::size_t e) {
  static const char* colours[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e",
                                  "#17becf", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22"};
  return fmt::format("lc rgb '{}'", colours[e % 10]);
}

// The gnuplot script around a body: one pass per output format, images named <name>.<format>.
std::string gnuplot_script(const std::string& name, const std::string& what, int width, int height,
                           const std::string& body) {
  return fmt::format(
      "# {0}.gp — {1}, written by `ncosim plot`.\n"
      "# Run in this folder: gnuplot {0}.gp   (one format: gnuplot -e \"formats='svg'\" {0}.gp)\n"
      "set encoding utf8\n"
      "if (!exists(\"formats\")) formats = 'png svg'\n"
      "set datafile missing '?'\n"
      "do for [fmt in formats] {{\n"
      "  if (fmt eq 'png') {{ set terminal pngcairo size {2},{3} noenhanced font 'Sans,10'; set "
      "output '{0}.png' }}\n"
      "  if (fmt eq 'svg') {{ set terminal svg size {2},{3} noenhanced font 'Sans,10' background "
      "'#ffffff'; "
      "set output '{0}.svg' }}\n"
      "  reset\n"
      "  set datafile missing '?'\n"
      "{4}"
      "  unset multiplot\n"
      "  set output\n"
      "}}\n",
      name, figure_text::comment(what), width, height, body);
}

namespace figure_text {

std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in)
    throw config::ScenarioError(
        fmt::format("{}: cannot read (is this an ncosim output folder?)", p.string()));
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::optional<double> number(const std::string& s) {
  if (s.empty()) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(s.c_str(), &end);
  if (end != s.c_str() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

// The field as written in the CSV, or '?' (gnuplot's missing value) when it is not a number.
std::string dat_field(const std::string& s) { return number(s) ? s : std::string("?"); }

// One-line comment text for a .dat file.
std::string comment(const std::string& s) {
  std::string out;
  for (char c : s) out += (c == '\n' || c == '\r') ? ' ' : c;
  return out;
}

std::string scenario_title(const std::string& dir) {
  std::ifstream in(fs::path(dir) / "manifest.json");
  if (!in) return "";
  try {
    const auto j = nlohmann::json::parse(in);
    if (j.contains("title") && j["title"].is_string()) return j["title"].get<std::string>();
  } catch (const std::exception&) {
  }
  return "";
}

std::string tics(const std::vector<std::string>& labels) {
  std::string out = "(";
  for (std::size_t i = 0; i < labels.size(); ++i)
    out += fmt::format("{}{} {}", i ? ", " : "", gnuplot_quote(labels[i]), i);
  return out + ")";
}

}  // namespace figure_text

}  // namespace ncosim::sim
