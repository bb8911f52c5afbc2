// config/config.h — typed, checked reading of scenario tables (TOML) with precise errors.
// Every getter records the key as known; Table::finish() rejects keys that no reader
// asked for, with a did-you-mean. Every error is a ScenarioError whose message reads
// `FILE:LINE: key 'PATH': expected ..., got ...` (the line of the offending value). A value
// that came from the command line carries its origin instead of FILE:LINE
// (`--set: key 'PATH': ...`): its node's source path is the option name (kCommandLineOrigin).
#pragma once

#include <toml++/toml.h>

#include <Eigen/Dense>
#include <cstdint>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace ncosim::config {

// Bad user input: the message is complete and ready to print. One error, or several independent
// ones of one input (every key-level error of a scenario, sim/scenario/key_check.h): what() then
// holds the first kMaxShown, one per line, and a last line "and N more errors (M in all; ...)".
class ScenarioError : public std::runtime_error {
 public:
  static constexpr std::size_t kMaxShown = 20;

  explicit ScenarioError(const std::string& message)
      : std::runtime_error(message),
        messages_(std::make_shared<const std::vector<std::string>>(1, message)) {}
  // `messages` (at least one), each a complete message, in the order to print.
  explicit ScenarioError(std::vector<std::string> messages);

  // Every error, the ones beyond kMaxShown included (one for a single error).
  const std::vector<std::string>& messages() const { return *messages_; }

 private:
  std::shared_ptr<const std::vector<std::string>> messages_;
};

// `text` safe to print: control characters, DEL and bytes that are not well-formed UTF-8 become
// \xNN (newlines and tabs too unless `keep_newlines`), so no byte can cut or garble a message.
std::string escape_text(std::string_view text, bool keep_newlines = false);

// "FILE:LINE: key 'PATH': MESSAGE" (FILE:LINE omitted parts when unknown).
std::string format_error(const std::string& file, int line, const std::string& path,
                         const std::string& message);

// Source paths that start with this prefix name a command-line option ("--set", "--runs"),
// not a file: errors at such values omit the line.
inline constexpr std::string_view kCommandLineOrigin = "--";
// The source name of a scenario given as a Python dict (python/): errors omit the line.
inline constexpr std::string_view kDictOrigin = "<dict>";

// Closest candidate by edit distance, or "" when none is close enough.
std::string did_you_mean(std::string_view word, const std::vector<std::string>& candidates);

// One error of an input and its line (0 when it has none): several are sorted into file order.
struct LineError {
  int line = 0;
  std::string message;
};
// The messages of `errors` sorted by line (stable), ready for ScenarioError(messages).
std::vector<std::string> in_file_order(std::vector<LineError> errors);

class Table {
 public:
  // `file` names the source used in messages; `path` is the key path of this table
  // ("" for the root, "plant", "link[1]").
  Table(const toml::table& table, std::string path, std::string file);

  const std::string& path() const { return path_; }
  const std::string& file() const { return file_; }
  int line() const;
  std::string key_path(std::string_view key) const;

  bool has(std::string_view key) const;

  double number(std::string_view key) const;
  double number_or(std::string_view key, double fallback) const;
  std::optional<double> opt_number(std::string_view key) const;

  std::int64_t integer(std::string_view key) const;
  std::int64_t integer_or(std::string_view key, std::int64_t fallback) const;

  bool boolean_or(std::string_view key, bool fallback) const;

  std::string string(std::string_view key) const;
  std::string string_or(std::string_view key, std::string_view fallback) const;
  bool is_string(std::string_view key) const;  // the key holds a string
  // A string that must be one of `choices` (the error lists them).
  std::string choice_or(std::string_view key, std::string_view fallback,
                        const std::vector<std::string>& choices) const;

  // A matrix: an array of rows (arrays of numbers), all of one length. A bare number
  // is read as a 1x1 matrix.
  Eigen::MatrixXd matrix(std::string_view key) const;
  // A vector: an array of numbers (a bare number is a vector of size 1).
  Eigen::VectorXd vector(std::string_view key) const;
  std::vector<double> numbers(std::string_view key) const;
  // An array of arrays of numbers, rows of any length.
  std::vector<std::vector<double>> ragged(std::string_view key) const;

  Table table(std::string_view key) const;
  std::optional<Table> opt_table(std::string_view key) const;
  std::vector<Table> tables(std::string_view key) const;  // array of tables; empty if absent

  // Errors at this key's value (its line), or at this table.
  [[noreturn]] void fail(std::string_view key, const std::string& message) const;
  [[noreturn]] void fail_here(const std::string& message) const;
  // The line of this key's value (of this table when absent or set on the command line).
  int line_of(std::string_view key) const;

  // Rejects keys of this table that no getter asked for (every one, in file order). Call once
  // all keys are read.
  void finish() const;
  // The keys of this table that are not among `known`, each an "unknown key" message (with a
  // did-you-mean among `known`) and its line, in file order.
  std::vector<LineError> unknown_keys(const std::vector<std::string>& known) const;

  // Marks a key as known without reading it (a key read by another component).
  void allow(std::string_view key) const;
  // The TOML table itself, for a reader that takes every key as it comes (a Python estimator's
  // parameters, python/); it must allow() what it takes.
  const toml::table& raw() const { return *table_; }

 private:
  const toml::node* get(std::string_view key) const;
  [[noreturn]] void type_error(std::string_view key, const std::string& expected) const;
  // "FILE:LINE: key 'PATH': " prefix parts for a value node of this table.
  std::pair<std::string, int> location(const toml::node& node) const;

  const toml::table* table_;
  std::string path_;
  std::string file_;
  std::shared_ptr<std::set<std::string, std::less<>>> known_;
};

// Describes a TOML value briefly for "got ..." messages (e.g. `a string "x"`, `1.2`).
std::string describe(const toml::node& node);
// A value in one-line TOML syntax with numbers in their shortest exact form: "[0.9, 0.05]",
// not toml++'s "[ 0.90000000000000002, 0.050000000000000003 ]".
std::string compact_toml(const toml::node& node);

// Range/shape helpers raising ScenarioError at `key`.
void require_shape(const Table& t, std::string_view key, const Eigen::MatrixXd& m,
                   Eigen::Index rows, Eigen::Index cols);
void require_psd(const Table& t, std::string_view key, const Eigen::MatrixXd& m);
void require_probability(const Table& t, std::string_view key, double p);
// Non-negative entries summing to at most 1 (+1e-9).
void require_subprobability(const Table& t, std::string_view key, const std::vector<double>& pmf);

}  // namespace ncosim::config
