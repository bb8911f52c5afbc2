// sim/analysis/compare_manifest.cc — the identity of a compared folder and what differs between two
// (sim/analysis/compare_manifest.h).
#include "sim/analysis/compare_manifest.h"

#include <fmt/format.h>

#include <filesystem>
#include <optional>
#include <set>

#include "sim/scenario/scenario.h"
#include "sim/store/store.h"

namespace ncosim::sim {

namespace {

// How and when a campaign ran, not what it ran: never reported (command_line always differs in
// --out; runs_done .. shard are said by the partial-campaign warning; inputs have their own lines).
const std::set<std::string>& not_compared() {
  static const std::set<std::string> keys{
      "command_line",  "date",     "wall_seconds", "threads", "ranks",     "store", "runs_done",
      "runs_expected", "complete", "stopped",      "shard",   "links_csv", "inputs"};
  return keys;
}

// At most `width` characters (a scenario title, a long override list): the rest as "...".
std::string shortened(const std::string& s, std::size_t width = 80) {
  return s.size() <= width ? s : s.substr(0, width - 3) + "...";
}

// A manifest value as a user wrote it: a string bare, anything else as compact JSON.
std::string rendered(const nlohmann::json& v) {
  return v.is_string() ? v.get<std::string>() : v.dump();
}

}  // namespace

void read_folder_identity(const nlohmann::json& manifest, RunFolder& f) {
  for (auto it = manifest.begin(); it != manifest.end(); ++it)
    f.fields[it.key()] = rendered(it.value());
  if (const auto it = manifest.find("scenario_text_hash");
      it != manifest.end() && it->is_string()) {
    f.text_hash = it->get<std::string>();
  }
  const std::string store = (std::filesystem::path(f.dir) / "runs.sqlite").string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(store, ec)) return;
  try {
    const auto meta = RunStore::open(store, false).meta();
    const auto text = meta.find("scenario_text");
    if (text == meta.end()) return;
    f.text = text->second;
    if (f.text_hash) return;
    // A manifest of an older ncosim: the text hash from the text and --set the store holds.
    std::vector<std::string> sets;
    if (const auto o = meta.find("overrides"); o != meta.end() && !o->second.empty()) {
      sets = nlohmann::json::parse(o->second).get<std::vector<std::string>>();
    }
    f.text_hash = scenario_text_hash(f.text.value(), sets);
  } catch (const std::exception&) {
    // A damaged or foreign store: compare then goes by the manifest alone (export says why).
    f.text.reset();
  }
}

bool same_scenario_text(const RunFolder& base, const RunFolder& fresh) {
  if (base.text_hash && fresh.text_hash) return *base.text_hash == *fresh.text_hash;
  return base.scenario_hash == fresh.scenario_hash;
}

std::string first_differing_line(const std::string& a, const std::string& b) {
  // The line starting at `from` (nullopt past the end of the text) and where the next one starts.
  auto line_at = [](const std::string& s, std::size_t& from) -> std::optional<std::string> {
    if (from > s.size()) return std::nullopt;
    const std::size_t end = s.find('\n', from);
    std::string line = s.substr(from, end == std::string::npos ? std::string::npos : end - from);
    from = end == std::string::npos ? s.size() + 1 : end + 1;
    return line;
  };
  auto text = [](const std::optional<std::string>& l) {
    return l ? "`" + shortened(*l, 60) + "`" : "(end of file)";
  };
  std::size_t pa = 0, pb = 0;
  for (int line = 1; pa <= a.size() || pb <= b.size(); ++line) {
    const auto la = line_at(a, pa), lb = line_at(b, pb);
    if (la != lb) return fmt::format("line {}: {} -> {}", line, text(la), text(lb));
  }
  return "";
}

std::vector<std::string> manifest_differences(const RunFolder& base, const RunFolder& fresh) {
  std::vector<std::string> out;
  if (base.text && fresh.text && *base.text != *fresh.text) {
    out.push_back("scenario text: " + first_differing_line(*base.text, *fresh.text));
  }
  std::set<std::string> keys;
  for (const auto& [k, v] : base.fields) keys.insert(k);
  for (const auto& [k, v] : fresh.fields) keys.insert(k);
  auto get = [](const RunFolder& f, const std::string& k) {
    const auto it = f.fields.find(k);
    return it == f.fields.end() ? std::string("(absent)") : shortened(it->second);
  };
  for (const auto& k : keys) {
    if (not_compared().count(k) != 0) continue;
    const std::string b = get(base, k), n = get(fresh, k);
    if (b != n) out.push_back(fmt::format("{}: {} -> {}", k, b, n));
  }
  if (base.inputs && fresh.inputs) {
    std::set<std::string> files;
    for (const auto& [file, h] : *base.inputs) files.insert(file);
    for (const auto& [file, h] : *fresh.inputs) files.insert(file);
    auto hash = [](const std::map<std::string, std::string>& m, const std::string& file) {
      const auto it = m.find(file);
      return it == m.end() ? std::string("(not read)") : it->second;
    };
    for (const auto& file : files) {
      const std::string b = hash(*base.inputs, file), n = hash(*fresh.inputs, file);
      if (b != n) out.push_back(fmt::format("inputs '{}': {} -> {}", file, b, n));
    }
  }
  return out;
}

}  // namespace ncosim::sim
