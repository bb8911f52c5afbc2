// sim/present/table_view.h — what `ncosim run` prints on stdout (issue 28, part 1). By default a
// table that fits the terminal (table_width: COLUMNS, else the terminal's width, else 120): the
// essential columns of summary.csv, long notes
// (model_check, any long text) as numbered footnotes under the table, printed once when rows
// share them, lower-priority columns left out (and named) when a row would still be too wide.
// `--columns a,b,c` picks summary.csv columns; `--format md|csv|json` prints the Markdown table,
// summary.csv's text or an array of row objects instead. The files summary.md and summary.csv
// always keep every column (sim/analysis/output.h).
#pragma once

#include <string>
#include <vector>

#include "sim/analysis/output.h"

namespace ncosim::sim {

// The width of a table when stdout is not a terminal and COLUMNS is not set (a log, a pipe).
inline constexpr std::size_t kDefaultTableWidth = 120;
// The narrowest width honoured (a smaller COLUMNS or terminal gives this).
inline constexpr std::size_t kNarrowestTableWidth = 40;

// The width the table on `fd` fits: the environment's COLUMNS when it holds a positive integer
// (as ls and Python's shutil do; a user's request even into a pipe), else the terminal's width
// when `fd` is a terminal (TIOCGWINSZ), else kDefaultTableWidth; never below
// kNarrowestTableWidth. `columns_env` is COLUMNS' value (null: unset).
std::size_t table_width(const char* columns_env, int fd);

// The stdout options of `run`.
struct TableRequest {
  std::vector<std::string> columns;  // --columns: summary.csv names; empty: the fitted default
  std::string format;                // --format: "" (the fitted table), "md", "csv", "json"
  std::size_t width = kDefaultTableWidth;  // the terminal width the default table fits
  bool machine() const { return format == "csv" || format == "json"; }
};

// "a,b,c" -> {"a", "b", "c"} (spaces around names dropped). Throws ScenarioError naming --columns
// for an empty list or name.
std::vector<std::string> parse_column_list(const std::string& text);

// Throws ScenarioError naming --columns (the unknown name and every valid one) or --format.
void check_table_request(const TableRequest& req, const std::vector<std::string>& valid_columns);

// One column of a terminal table: the header, one cell per row, and how it may be shown.
struct ViewColumn {
  std::string name;    // the summary.csv column (named when left out)
  std::string header;  // as shown
  std::vector<std::string> cells;
  int priority = 0;   // 0: never left out (identifies the row); larger: left out first
  bool note = false;  // long text: every cell becomes a footnote reference [k]
};

// The columns as a table of at most `width` characters per line (none left out when
// `can_drop` is false): footnotes for notes and for cells longer than kLongCell, one per
// distinct text (a note's row-specific tail after its last ": " listed per row, by
// `row_labels`), and a line (wrapped at `width`) naming the columns left out. Never wraps a
// table row. `kept` (optional) receives the names of the columns shown.
inline constexpr std::size_t kLongCell = 28;
std::string fit_table(std::vector<ViewColumn> cols, const std::vector<std::string>& row_labels,
                      std::size_t width, bool can_drop, std::vector<std::string>* kept = nullptr);

// Everything `run` prints on stdout before its closing line. `summary_md` is summary.md's text;
// `extras` the lines it has after the table (stopping rule, partial results).
std::string stdout_table(const TableRequest& req, const std::string& title,
                         const std::vector<SweepAxis>& sweeps, const std::vector<SummaryRow>& rows,
                         Eigen::Index n, const std::string& summary_md, const std::string& extras);

// `text` wrapped at spaces to lines of at most `width` characters, continuation lines indented
// by `indent` spaces (a word longer than a line stays whole).
std::string wrap_text(const std::string& text, std::size_t width, std::size_t indent);

}  // namespace ncosim::sim
