// sim/present/report_parts.h — pieces of `ncosim report` (sim/present/report.h) that read the
// output folder's other files: the design table (design.json), the manifest table and the
// scenario section (the text the campaign ran, from runs.sqlite, and whether the file on disk
// still holds it); and the small text helpers they share with report.cc. Every text is
// HTML-escaped.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

namespace ncosim::sim {

// HTML text escaping (&, <, >, ", ').
std::string html_escape(const std::string& s);

}  // namespace ncosim::sim

namespace ncosim::sim::report_parts {

// The file's bytes, or nullopt when it cannot be read.
std::optional<std::string> try_read(const std::filesystem::path& p);

// A column name, escaped, that may break after its underscores (flops_per_period over three
// lines of a narrow header).
std::string header_text(const std::string& name);

// A JSON value as a table cell's text: a string as is, null empty, a float to 6 digits.
std::string json_text(const nlohmann::json& v);

// <table> of design.json's estimators (one folded table for several cases), or a sentence
// saying why there is none.
std::string design_section(const std::string& dir);

// <h2 id="manifest"> and the manifest as a two-column table.
std::string manifest_section(const nlohmann::json& man);

// <h2 id="scenario">, the scenario text the campaign ran and one sentence about the file on disk.
std::string scenario_section(const std::string& dir, const nlohmann::json& man);

}  // namespace ncosim::sim::report_parts
