// sim/files/csv.h — the CSV files ncosim writes, read back (`plot`, `report`, `compare`): RFC 4180
// records (quoted fields may hold commas, quotes and line breaks; "" is a quote), each with the
// line it starts on, read all at once or one at a time from a stream, and a table view with a
// header.
#pragma once

#include <istream>
#include <optional>
#include <string>
#include <vector>

namespace ncosim::sim {

struct CsvRecord {
  std::vector<std::string> fields;
  int line = 0;  // 1-based line where the record starts
};
// Every record of `text`; lines ending in \n or \r\n; blank lines skipped. Throws ScenarioError
// naming `what` and the line on an unterminated quoted field.
std::vector<CsvRecord> read_csv_records(const std::string& text, const std::string& what);

// The same records one at a time from a stream: memory for one record, not the file.
class CsvReader {
 public:
  CsvReader(std::istream& in, std::string what) : in_(*in.rdbuf()), what_(std::move(what)) {}
  // From now on, fields whose index is not true in `keep` are counted but stored empty (a wide
  // file read for a few columns).
  void keep_only(std::vector<bool> keep) { keep_ = std::move(keep); }
  // The next record into `rec` (false at the end). Throws ScenarioError as read_csv_records.
  bool next(CsvRecord& rec);

 private:
  std::streambuf& in_;
  std::string what_;
  std::vector<bool> keep_;
  int line_ = 1;
};

// A CSV file with a header line.
struct CsvTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;  // every row has header.size() fields
  int column(const std::string& name) const;   // -1 when absent
};
// Throws ScenarioError naming `what` and the line on malformed input (unterminated quote, a row
// with a different number of fields, no header).
CsvTable parse_csv(const std::string& text, const std::string& what);

// CSV field quoting (RFC 4180) and number formatting (empty for nullopt / non-finite).
std::string csv_field(const std::string& s);
std::string fmt_number(std::optional<double> v);

}  // namespace ncosim::sim
