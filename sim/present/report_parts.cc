// sim/present/report_parts.cc — see sim/present/report_parts.h.
#include "sim/present/report_parts.h"

#include <fmt/format.h>

#include <fstream>
#include <sstream>

#include "sim/store/store.h"

namespace ncosim::sim {

std::string html_escape(const std::string& s) {
  std::string out;
  out.reserve(s.size() + s.size() / 8);
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

}  // namespace ncosim::sim

namespace ncosim::sim::report_parts {

namespace fs = std::filesystem;

std::optional<std::string> try_read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// A column name that may break after its underscores (flops_per_period over three lines).
std::string header_text(const std::string& name) {
  std::string out;
  for (const char ch : html_escape(name)) {
    out += ch;
    if (ch == '_') out += "<wbr/>";
  }
  return out;
}

std::string json_text(const nlohmann::json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_null()) return "";
  if (v.is_number_float()) return fmt::format("{:.6g}", v.get<double>());
  return v.dump();
}

std::string design_section(const std::string& dir) {
  const auto text = try_read(fs::path(dir) / "design.json");
  if (!text) return "<p>No design.json in this folder.</p>\n";
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(*text);
  } catch (const std::exception& e) {
    return fmt::format("<p class=\"warn\">design.json could not be read: {}</p>\n",
                       html_escape(e.what()));
  }
  static const char* fields[] = {
      "name",   "kind",
      "status",  // next to the name, wrapped: never behind a scroll
      "method", "stored_gains",  "predicted_mse", "predicted_mse_ext", "flops_per_period",
      "stable", "design_seconds"};
  std::vector<std::pair<std::string, const nlohmann::json*>> groups;
  if (j.contains("cases") && j["cases"].is_array()) {
    for (const auto& c : j["cases"]) {
      std::string label;
      if (c.contains("sweep")) {
        for (const auto& [k, v] : c["sweep"].items())
          label += (label.empty() ? "" : ", ") + k + " = " + json_text(v);
      }
      groups.emplace_back(label, &c["estimators"]);
    }
  } else if (j.contains("estimators")) {
    groups.emplace_back("", &j["estimators"]);
  }
  std::string h = "<div class=\"scroll\"><table>\n<tr>";
  if (groups.size() > 1) h += "<th class=\"t\">case</th>";
  for (const char* f : fields) h += fmt::format("<th class=\"t\">{}</th>", header_text(f));
  h += "</tr>\n";
  for (const auto& [label, ests] : groups) {
    if (ests == nullptr || !ests->is_array()) continue;
    for (const auto& e : *ests) {
      const bool bad =
          e.contains("status") && e["status"].is_string() && e["status"].get<std::string>() != "ok";
      h += bad ? "<tr class=\"bad\">" : "<tr>";
      if (groups.size() > 1) h += fmt::format("<td class=\"t\">{}</td>", html_escape(label));
      for (const char* f : fields) {
        h += fmt::format("<td class=\"t{}\">{}</td>", std::string(f) == "status" ? " status" : "",
                         e.contains(f) ? html_escape(json_text(e[f])) : "");
      }
      h += "</tr>\n";
    }
  }
  h += "</table></div>\n";
  if (groups.size() > 1) {
    h = fmt::format("<details><summary>design of every case ({} cases)</summary>\n{}</details>\n",
                    groups.size(), h);
  }
  return h;
}

// The manifest as a two-column table.
std::string manifest_section(const nlohmann::json& man) {
  std::string h = "<h2 id=\"manifest\">Manifest</h2>\n";
  if (man.empty()) return h + "<p>No manifest.json in this folder.</p>\n";
  h += "<table>\n";
  for (const auto& [k, v] : man.items()) {
    h += fmt::format("<tr><th class=\"t\">{}</th><td class=\"t\">{}</td></tr>\n", html_escape(k),
                     html_escape(json_text(v)));
  }
  return h + "</table>\n";
}

namespace {

// The scenario file named in the manifest: as given, or relative to the folders above DIR.
std::optional<std::pair<std::string, std::string>> scenario_text(const std::string& dir,
                                                                 const std::string& name) {
  if (name.empty()) return std::nullopt;
  std::vector<fs::path> tries{fs::path(name)};
  fs::path up = fs::absolute(dir);
  for (int i = 0; i < 4 && up.has_parent_path() && up != up.parent_path(); ++i) {
    up = up.parent_path();
    tries.push_back(up / name);
  }
  for (const auto& p : tries) {
    if (const auto t = try_read(p)) return std::make_pair(p.string(), *t);
  }
  return std::nullopt;
}

// The scenario the campaign ran, from the run store's campaign table (scenario_text, and
// scenario_path to compare with the file on disk now); nullopt without a readable store (a
// folder written before the run store).
struct StoredScenario {
  std::string text, path;
};

std::optional<StoredScenario> stored_scenario(const std::string& dir) {
  const std::string sp = store_path(dir);
  if (!fs::exists(sp)) return std::nullopt;
  try {
    const auto meta = RunStore::open(sp, false).meta();
    const auto text = meta.find("scenario_text");
    if (text == meta.end()) return std::nullopt;
    const auto path = meta.find("scenario_path");
    return StoredScenario{text->second, path == meta.end() ? "" : path->second};
  } catch (const StoreError&) {
    return std::nullopt;
  }
}

// One sentence comparing the stored text with the file at its path now.
std::string disk_note(const StoredScenario& st) {
  const auto now = st.path.empty() ? std::nullopt : try_read(st.path);
  if (!now) {
    return fmt::format(
        "<p class=\"warn\" id=\"scenario-disk\">The scenario file {} is no longer there; the text "
        "below is the one the campaign ran.</p>\n",
        html_escape(st.path.empty() ? "(path not stored)" : st.path));
  }
  if (*now != st.text) {
    return fmt::format(
        "<p class=\"warn\" id=\"scenario-disk\">The scenario file {} has changed since the "
        "campaign "
        "ran; the text below is the one the campaign ran, not the file as it is now.</p>\n",
        html_escape(st.path));
  }
  return fmt::format(
      "<p class=\"sub\" id=\"scenario-disk\">The scenario file {} is unchanged since the campaign "
      "ran.</p>\n",
      html_escape(st.path));
}

std::string overrides_note(const nlohmann::json& man) {
  return man.contains("overrides") && !man["overrides"].empty()
             ? ", before the overrides " + html_escape(json_text(man["overrides"]))
             : "";
}

}  // namespace

// The scenario text the campaign ran (from runs.sqlite) with whether the file on disk still
// holds it; without a store, the file named in the manifest as read now (or a warning when it is
// not found), saying that it may not be what the campaign ran.
std::string scenario_section(const std::string& dir, const nlohmann::json& man) {
  std::string h = "<h2 id=\"scenario\">Scenario</h2>\n";
  if (const auto st = stored_scenario(dir)) {
    h +=
        fmt::format("<p class=\"sub\">The scenario text the campaign ran, from runs.sqlite{}</p>\n",
                    overrides_note(man));
    return h + disk_note(*st) + fmt::format("<pre>{}</pre>\n", html_escape(st->text));
  }
  const std::string sname = man.contains("scenario") ? json_text(man["scenario"]) : "";
  if (const auto sc = scenario_text(dir, sname)) {
    h += fmt::format(
        "<p class=\"warn\" id=\"scenario-disk\">No run store (runs.sqlite) in this folder: the "
        "scenario file {} as read when this report was written{}, which may differ from the text "
        "the "
        "campaign ran.</p>\n<pre>{}</pre>\n",
        html_escape(sc->first), overrides_note(man), html_escape(sc->second));
  } else {
    h += fmt::format(
        "<p class=\"warn\" id=\"scenario-disk\">No run store (runs.sqlite) in this folder, and the "
        "scenario file '{}' was not found from here (relative paths are read from the current "
        "folder and "
        "the folders above the output folder).</p>\n",
        html_escape(sname));
  }
  return h;
}

}  // namespace ncosim::sim::report_parts
