// sim/csv.cc — see sim/csv.h.
#include "sim/csv.h"

#include <fmt/format.h>

#include "config/config.h"

namespace ncosim::sim {

std::vector<CsvRecord> read_csv_records(const std::string& text, const std::string& what) {
  std::vector<CsvRecord> out;
  CsvRecord rec;
  rec.line = 1;
  std::string field;
  bool quoted = false, any = false;
  int line = 1;
  auto end_record = [&] {
    if (any || !field.empty()) {
      rec.fields.push_back(std::move(field));
      out.push_back(std::move(rec));
    }
    field.clear();
    rec = CsvRecord{};
    any = false;
  };
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"') {
        if (i + 1 < text.size() && text[i + 1] == '"') {
          field += '"';
          ++i;
        } else {
          quoted = false;
        }
      } else {
        if (c == '\n') ++line;
        field += c;
      }
      continue;
    }
    if (c == '"') {
      quoted = true;
      any = true;
    } else if (c == ',') {
      rec.fields.push_back(std::move(field));
      field.clear();
      any = true;
    } else if (c == '\n' || c == '\r') {
      if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
      end_record();
      rec.line = ++line;
    } else {
      field += c;
      any = true;
    }
  }
  if (quoted) throw ScenarioError(format_error(what, rec.line, "", "unterminated quoted field"));
  end_record();
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
  if (records.empty()) throw ScenarioError(format_error(what, 0, "", "empty file (expected a header line)"));
  CsvTable t;
  t.header = std::move(records.front().fields);
  for (std::size_t i = 1; i < records.size(); ++i) {
    auto& r = records[i];
    if (r.fields.size() == 1 && r.fields[0].empty()) continue;  // a line holding only ""
    if (r.fields.size() != t.header.size()) {
      throw ScenarioError(format_error(
          what, r.line, "", fmt::format("expected {} fields (as the header), got {}", t.header.size(), r.fields.size())));
    }
    t.rows.push_back(std::move(r.fields));
  }
  return t;
}

}  // namespace ncosim::sim
