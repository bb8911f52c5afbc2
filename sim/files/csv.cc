// sim/files/csv.cc — see sim/files/csv.h.
#include "sim/files/csv.h"

#include <fmt/format.h>

#include <cmath>
#include <sstream>

#include "config/config.h"

namespace ncosim::sim {

bool CsvReader::next(CsvRecord& rec) {
  using traits = std::streambuf::traits_type;
  rec.fields.clear();
  rec.line = line_;
  std::string field;
  bool quoted = false, any = false;
  auto kept = [&] {
    return keep_.empty() || (rec.fields.size() < keep_.size() && keep_[rec.fields.size()]);
  };
  bool keep = kept();
  while (true) {
    const auto ci = in_.sbumpc();
    if (traits::eq_int_type(ci, traits::eof())) {
      if (quoted)
        throw config::ScenarioError(
            config::format_error(what_, rec.line, "", "unterminated quoted field"));
      if (!any && field.empty()) return false;
      rec.fields.push_back(std::move(field));
      return true;
    }
    const char c = traits::to_char_type(ci);
    if (quoted) {
      if (c == '"') {
        if (traits::eq_int_type(in_.sgetc(), traits::to_int_type('"'))) {
          if (keep) field += '"';
          in_.sbumpc();
        } else {
          quoted = false;
        }
      } else {
        if (c == '\n') ++line_;
        if (keep) field += c;
      }
      continue;
    }
    if (c == '"') {
      quoted = true;
      any = true;
    } else if (c == ',') {
      rec.fields.push_back(std::move(field));
      field.clear();
      keep = kept();
      any = true;
    } else if (c == '\n' || c == '\r') {
      if (c == '\r' && traits::eq_int_type(in_.sgetc(), traits::to_int_type('\n'))) in_.sbumpc();
      ++line_;
      if (any || !field.empty()) {
        rec.fields.push_back(std::move(field));
        return true;
      }
      rec.line = line_;  // a blank line: skipped
    } else {
      if (keep) field += c;
      any = true;
    }
  }
}

std::vector<CsvRecord> read_csv_records(const std::string& text, const std::string& what) {
  std::istringstream in(text);
  CsvReader reader(in, what);
  std::vector<CsvRecord> out;
  for (CsvRecord rec; reader.next(rec);) out.push_back(std::move(rec));
  return out;
}

int CsvTable::column(const std::string& name) const {
  for (std::size_t i = 0; i < header.size(); ++i) {
    if (header[i] == name) return static_cast<int>(i);
  }
  return -1;
}

CsvTable parse_csv(const std::string& text, const std::string& what) {
  std::vector<CsvRecord> records = read_csv_records(text, what);
  if (records.empty())
    throw config::ScenarioError(
        config::format_error(what, 0, "", "empty file (expected a header line)"));
  CsvTable t;
  t.header = std::move(records.front().fields);
  for (std::size_t i = 1; i < records.size(); ++i) {
    auto& r = records[i];
    if (r.fields.size() == 1 && r.fields[0].empty()) continue;  // a line holding only ""
    if (r.fields.size() != t.header.size()) {
      throw config::ScenarioError(
          config::format_error(what, r.line, "",
                               fmt::format("expected {} fields (as the header), got {}",
                                           t.header.size(), r.fields.size())));
    }
    t.rows.push_back(std::move(r.fields));
  }
  return t;
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

std::string fmt_number(std::optional<double> v) {
  if (!v || !std::isfinite(*v)) return "";
  return fmt::format("{:.6g}", *v);
}

}  // namespace ncosim::sim
