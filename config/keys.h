// config/keys.h — a component's keys declared as data (issue 26 part 1): name, type, unit,
// default (or required), allowed range or values and a one-line help. A kind's reader gets its
// values through its declarations (KeyReader): the default lives only in the declaration, and the
// type and range are checked here, once, with the FILE:LINE: key 'PATH': messages of Table.
// Checks beyond a range (a matrix's shape against the model, PSD, a pmf's sum) stay in the reader,
// after the generic read. `ncosim list --keys` and scenarios/README.md's key tables print them.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "config/config.h"

namespace ncosim::config {

enum class KeyType {
  kNumber,   // a finite number
  kInteger,  // an integer
  kBoolean,  // true or false
  kString,   // any string (a file name, a component name)
  kChoice,   // one of the declared values
  kNumbers,  // an array of numbers (a bare number is one)
  kVector,   // the same, read as an Eigen vector
  kMatrix,   // an array of rows, all of one length (a bare number is 1x1)
  kRagged,   // an array of arrays of numbers, rows of any length
  kTable,    // a sub-table, read by its own reader
  kTables,   // an array of tables
  kArray,    // an array of values of any type, each read by the kind's own code (sweep values)
  kAny,      // read by the kind's own code (several accepted types); `type_text` names them
};

// "number", "integer", ... as printed in docs.
std::string_view key_type_name(KeyType type);

class Keys;

// One declared key. Built by chaining: Key::number("loss").probability().or_default(0.0)
//   .help("probability that a packet is lost").
class Key {
 public:
  using Value =
      std::variant<std::monostate, double, std::int64_t, bool, std::string, std::vector<double>>;

  static Key number(std::string name) { return Key(std::move(name), KeyType::kNumber); }
  static Key integer(std::string name) { return Key(std::move(name), KeyType::kInteger); }
  static Key boolean(std::string name) { return Key(std::move(name), KeyType::kBoolean); }
  static Key string(std::string name) { return Key(std::move(name), KeyType::kString); }
  static Key choice(std::string name, std::vector<std::string> values);
  static Key numbers(std::string name) { return Key(std::move(name), KeyType::kNumbers); }
  static Key vector(std::string name) { return Key(std::move(name), KeyType::kVector); }
  static Key matrix(std::string name) { return Key(std::move(name), KeyType::kMatrix); }
  static Key ragged(std::string name) { return Key(std::move(name), KeyType::kRagged); }
  static Key table(std::string name) { return Key(std::move(name), KeyType::kTable); }
  static Key tables(std::string name) { return Key(std::move(name), KeyType::kTables); }
  static Key array(std::string name) { return Key(std::move(name), KeyType::kArray); }
  // A key read by the kind's own code; `type_text` says what it accepts ("number or string").
  static Key any(std::string name, std::string type_text);

  // --- builders ---
  Key& help(std::string text);
  Key& unit(std::string text);  // "s", "periods", "m", "dBm"; "" when none
  // The default when the key is absent (the key is then optional).
  Key& or_default(double v);
  Key& or_default(int v) { return or_default(static_cast<std::int64_t>(v)); }
  Key& or_default(std::int64_t v);
  Key& or_default(bool v);
  Key& or_default(const char* v) { return or_default(std::string(v)); }
  Key& or_default(std::string v);
  Key& or_default(std::vector<double> v);
  // Optional, with a default the reader computes (`text` says which: "the last cdf value",
  // "identity"); read with KeyReader::has / opt_*. A plain getter on such an absent key is the
  // "got nothing (the key is required)" error (a key required only with another one).
  Key& optional(std::string text = "");
  // Range: inclusive min/max, exclusive above/below. For arrays (numbers, vector, matrix,
  // ragged) the range holds for every entry.
  Key& min(double v);
  Key& max(double v);
  Key& above(double v);
  Key& below(double v);
  Key& range(double lo, double hi) { return min(lo).max(hi); }
  Key& probability() { return range(0.0, 1.0).noun("a probability", "probabilities"); }
  // How the range message names the value: "expected {noun} in [0, 1], got 2" ("a number" /
  // "an integer" by default; `plural` for array entries, "numbers" by default).
  Key& noun(std::string singular, std::string plural = "");
  // The whole "expected ..." phrase of a range error, when a bound is not a plain number
  // ("an integer in 1..1000000 (1e6)"); of an entries error and an array's type error too ("a
  // non-empty array of values").
  Key& says(std::string phrase);
  // A table key's own keys (docs print them as `reference.kind`, ...); read the sub-table with
  // KeyReader(sub, key.fields()).
  Key& fields(const Keys& keys);
  // Besides values of its type, the key accepts these strings (C = "output", rate = "saturated");
  // the type's getters refuse a string, KeyReader::word reads one. Docs print the type as
  // `matrix or "output"`.
  Key& or_words(std::vector<std::string> words);
  // How many entries an array key holds: numbers and vectors their numbers (a bare number is one),
  // matrices and ragged arrays their rows, tables and arrays their elements; `hi` 0 = no maximum.
  Key& entries(std::size_t lo, std::size_t hi);
  Key& entries(std::size_t n) { return entries(n, n); }
  // A matrix's or ragged array's numbers per row.
  Key& columns(std::size_t n);

  // --- the declaration ---
  const std::string& name() const { return name_; }
  KeyType type() const { return type_; }
  const std::string& unit_text() const { return unit_; }
  const std::string& help_text() const { return help_; }
  const std::vector<std::string>& values() const { return values_; }
  const Value& default_value() const { return default_; }
  bool required() const { return !optional_ && std::holds_alternative<std::monostate>(default_); }
  std::string type_text() const;     // "number", "choice", the text of any()
  std::string default_text() const;  // "0.5", "\"period\"", "[1.0]", the optional() text, ""
  std::string range_text() const;    // "[0, 1]", "0..1000000", "> 0", "" when unbounded
  std::optional<double> lo() const { return lo_; }
  std::optional<double> hi() const { return hi_; }
  bool lo_open() const { return lo_open_; }
  bool hi_open() const { return hi_open_; }
  const Keys* fields() const { return fields_.get(); }  // null when none
  const std::vector<std::string>& words() const { return words_; }
  const std::string& says_text() const { return says_; }    // "" when the range phrase is generic
  std::size_t min_entries() const { return min_entries_; }  // 0 = no minimum
  std::size_t max_entries() const { return max_entries_; }  // 0 = no maximum
  std::size_t columns() const { return columns_; }          // 0 = any
  // "3 numbers", "at least 1 value", "2..64 tables", "rows of 3 numbers"; "" when unconstrained.
  std::string shape_text() const;
  // "expected 3 numbers, got 2" (`got`: the count found).
  std::string entries_error(std::size_t got) const;
  // "expected rows of 3 numbers, got 2 in row 1".
  std::string columns_error(std::size_t got, std::size_t row) const;

  // Does `v` satisfy the range? (true when unbounded)
  bool in_range(double v) const;
  // "expected a probability in [0, 1], got 2" (`index` names an array entry: " at index 3").
  std::string range_error(double v, const std::string& index = "") const;

 private:
  Key(std::string name, KeyType type) : name_(std::move(name)), type_(type) {}

  std::string name_;
  KeyType type_;
  std::string unit_;
  std::string help_;
  std::vector<std::string> values_;
  Value default_;
  bool optional_ = false;
  std::string optional_text_;
  std::string any_text_;
  std::optional<double> lo_, hi_;
  bool lo_open_ = false, hi_open_ = false;
  std::string noun_, plural_, says_;
  std::shared_ptr<const Keys> fields_;
  std::vector<std::string> words_;
  std::size_t min_entries_ = 0, max_entries_ = 0, columns_ = 0;
};

// The ordered keys of one component (a kind, a section).
class Keys {
 public:
  Keys() = default;
  Keys(std::initializer_list<Key> keys);
  Keys(std::vector<Key> keys) : keys_(std::move(keys)) {}

  // A declaration by name; a std::logic_error when undeclared (a bug in the reader).
  const Key& at(std::string_view name) const;
  const Key* find(std::string_view name) const;
  const std::vector<Key>& list() const { return keys_; }
  bool empty() const { return keys_.empty(); }
  // These keys followed by `more` (shared declarations, e.g. a Markov chain's `step`).
  Keys operator+(const Keys& more) const;
  // At least one of these optional keys must be given (a delay link's pmf or delivery): the reader
  // requires one; the key check and the schema say so before it runs.
  Keys& require_one_of(std::vector<std::string> names);
  const std::vector<std::vector<std::string>>& one_of() const { return one_of_; }
  // "expected `pmf` or `delivery`, got neither".
  static std::string one_of_error(const std::vector<std::string>& names);

 private:
  std::vector<Key> keys_;
  std::vector<std::vector<std::string>> one_of_;
};

// Reads a Table through declarations (`keys` must outlive the reader: a static of the kind): the
// getter's type must match the declaration (else a std::logic_error: a bug in the reader), an
// absent key takes the declared default (or is an error when required), a present one is type- and
// range-checked. Marks keys as read (for Table::finish) exactly as the Table getters do.
class KeyReader {
 public:
  KeyReader(const Table& table, const Keys& keys) : t_(table), keys_(keys) {}

  const Table& table() const { return t_; }
  const Keys& keys() const { return keys_; }
  bool has(std::string_view key) const;

  double number(std::string_view key) const;
  std::optional<double> opt_number(std::string_view key) const;
  std::int64_t integer(std::string_view key) const;
  std::optional<std::int64_t> opt_integer(std::string_view key) const;
  bool boolean(std::string_view key) const;
  std::string string(std::string_view key) const;  // a string or a choice
  std::optional<std::string> opt_string(std::string_view key) const;
  std::vector<double> numbers(std::string_view key) const;
  Eigen::VectorXd vector(std::string_view key) const;
  Eigen::MatrixXd matrix(std::string_view key) const;
  std::vector<std::vector<double>> ragged(std::string_view key) const;
  Table table(std::string_view key) const;
  std::optional<Table> opt_table(std::string_view key) const;
  std::vector<Table> tables(std::string_view key) const;
  // The string of a key declared with or_words(): nullopt when the value is not a string (read it
  // with the getter of its type), the word when it is one, else the error listing them.
  std::optional<std::string> word(std::string_view key) const;
  // An array of values of any type (KeyType::kArray), its entries counted; nullptr when absent and
  // optional.
  const toml::array* array(std::string_view key) const;

  [[noreturn]] void fail(std::string_view key, const std::string& message) const {
    t_.fail(key, message);
  }

 private:
  const Key& declared(std::string_view key, std::initializer_list<KeyType> types) const;
  void check(const Key& k, double v, const std::string& index = "") const;
  void check_entries(const Key& k, std::size_t count) const;
  void check_columns(const Key& k, const std::vector<std::vector<double>>& rows) const;
  // The declared default of an absent key (required: the "got nothing" error of `expected`).
  const Key::Value& fallback(const Key& k, const std::string& expected) const;

  const Table& t_;
  const Keys& keys_;
};

// One registry entry's keys as text: a Markdown table (`markdown`) or aligned plain text. A table
// key's fields follow it, named `table.field`.
std::string format_keys(const Keys& keys, bool markdown);

}  // namespace ncosim::config
