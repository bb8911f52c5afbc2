// sim/cmd/ladder_scenario.cc — the scenario files of `ncosim ladder` (sim/cmd/ladder_scenario.h).
#include "sim/cmd/ladder_scenario.h"

#include <fmt/format.h>

#include <algorithm>
#include <climits>
#include <filesystem>
#include <sstream>

#include "config/config.h"
#include "sim/scenario/scenario_document.h"

namespace ncosim::sim {

namespace fs = std::filesystem;

namespace {

// Where a node was written in `file` (line, column); what an option set sorts after it.
std::pair<int, int> position(const toml::node& n, const std::string& file) {
  const toml::source_region& s = n.source();
  if (s.path == nullptr || *s.path != file || s.begin.line == 0) return {INT_MAX, INT_MAX};
  return {static_cast<int>(s.begin.line), static_cast<int>(s.begin.column)};
}

// An array written as [[key]] tables: every element a table (also one the file wrote inline,
// `link = [{...}]`, the same document).
bool table_array(const toml::node& n) {
  const toml::array* a = n.as_array();
  if (a == nullptr || a->empty()) return false;
  return std::all_of(a->begin(), a->end(), [](const toml::node& e) { return e.is_table(); });
}

bool section(const toml::node& n) {
  return (n.is_table() && !n.as_table()->is_inline()) || table_array(n);
}

std::pair<int, int> section_position(const toml::node& n, const std::string& file) {
  if (const toml::array* a = n.as_array(); a != nullptr && !a->empty())
    return position(*a->get(0), file);
  return position(n, file);
}

// A TOML basic string: "..." with \\, \" and control characters escaped.
std::string toml_string(std::string_view v) {
  std::string out = "\"";
  for (const char c : v) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
          out += fmt::format("\\u{:04X}", static_cast<unsigned char>(c));
        else
          out += c;
    }
  }
  return out + "\"";
}

std::string key_text(std::string_view k) {
  const bool bare = !k.empty() && std::all_of(k.begin(), k.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '-';
  });
  return bare ? std::string(k) : toml_string(k);
}

// The entries of `t` in the file's order (`sections`: the tables and [[arrays]], else the rest).
std::vector<std::pair<std::string, const toml::node*>> entries(const toml::table& t,
                                                               const std::string& file,
                                                               bool sections) {
  std::vector<std::pair<std::string, const toml::node*>> out;
  for (auto&& [k, v] : t) {
    if (section(v) == sections) out.emplace_back(std::string(k.str()), &v);
  }
  std::stable_sort(out.begin(), out.end(), [&](const auto& a, const auto& b) {
    return section_position(*a.second, file) < section_position(*b.second, file);
  });
  return out;
}

std::string value_text(const toml::node& n, const std::string& file) {
  if (auto d = n.value_exact<double>()) {
    std::string text = fmt::format("{}", *d);
    if (text.find_first_of(".eEn") == std::string::npos) text += ".0";  // keep it a float
    return text;
  }
  if (auto i = n.value_exact<std::int64_t>()) return fmt::format("{}", *i);
  if (auto b = n.value_exact<bool>()) return *b ? "true" : "false";
  if (auto str = n.value_exact<std::string>()) return toml_string(*str);
  if (const toml::array* a = n.as_array()) {
    std::string out = "[";
    for (std::size_t i = 0; i < a->size(); ++i)
      out += (i ? ", " : "") + value_text(*a->get(i), file);
    return out + "]";
  }
  if (const toml::table* t = n.as_table()) {
    std::string out;
    for (const bool sections : {false, true}) {
      for (const auto& [k, v] : entries(*t, file, sections))
        out += fmt::format("{}{} = {}", out.empty() ? "" : ", ", key_text(k), value_text(*v, file));
    }
    return out.empty() ? "{}" : "{ " + out + " }";
  }
  std::ostringstream os;  // dates and times
  os << toml::toml_formatter{n};
  return os.str();
}

void emit_table(std::string& out, const toml::table& t, const std::string& path,
                const std::string& file);

// The [header] or [[header]] tables of `t`'s sections, below `path`.
void emit_sections(std::string& out, const toml::table& t, const std::string& path,
                   const std::string& file) {
  for (const auto& [k, v] : entries(t, file, true)) {
    const std::string sub = path.empty() ? key_text(k) : path + "." + key_text(k);
    if (const toml::array* a = v->as_array()) {
      for (const toml::node& e : *a) {
        out += fmt::format("\n[[{}]]\n", sub);
        emit_table(out, *e.as_table(), sub, file);
      }
    } else {
      out += fmt::format("\n[{}]\n", sub);
      emit_table(out, *v->as_table(), sub, file);
    }
  }
}

void emit_table(std::string& out, const toml::table& t, const std::string& path,
                const std::string& file) {
  for (const auto& [k, v] : entries(t, file, false))
    out += fmt::format("{} = {}\n", key_text(k), value_text(*v, file));
  emit_sections(out, t, path, file);
}

void rebase(toml::node& n, const config::InputFiles& inputs, const fs::path& scenario_dir,
            const fs::path& out_dir) {
  if (toml::table* t = n.as_table()) {
    for (auto&& [k, v] : *t) rebase(v, inputs, scenario_dir, out_dir);
  } else if (toml::array* a = n.as_array()) {
    for (toml::node& e : *a) rebase(e, inputs, scenario_dir, out_dir);
  } else if (auto* s = n.as_string()) {
    const fs::path p(s->get());
    if (p.empty() || p.is_absolute() || inputs.count(p.lexically_normal().string()) == 0) return;
    const fs::path target = fs::absolute(scenario_dir / p).lexically_normal();
    s->get() = target.lexically_relative(fs::absolute(out_dir).lexically_normal()).string();
  }
}

}  // namespace

toml::table ladder_document(const std::string& file, const std::string& text,
                            const std::vector<std::string>& sets, std::int64_t runs,
                            std::int64_t periods, const std::optional<std::uint64_t>& seed) {
  return parse_document(text, file, sets, RunOverrides{runs, periods, seed});
}

void rebase_input_paths(toml::table& doc, const config::InputFiles& inputs,
                        const std::string& scenario_dir, const std::string& out_dir) {
  for (auto&& [k, v] : doc) rebase(v, inputs, scenario_dir, out_dir);
}

std::string scenario_text(const toml::table& doc, const std::string& file,
                          const std::map<std::size_t, std::string>& replace,
                          const std::vector<std::string>& drop) {
  const auto dropped = [&](const std::string& k) {
    return std::find(drop.begin(), drop.end(), k) != drop.end();
  };
  std::string out;
  for (const auto& [k, v] : entries(doc, file, false)) {
    if (!dropped(k)) out += fmt::format("{} = {}\n", key_text(k), value_text(*v, file));
  }
  for (const auto& [k, v] : entries(doc, file, true)) {
    if (dropped(k)) continue;
    const std::string head = key_text(k);
    const toml::array* a = v->as_array();
    if (a == nullptr) {
      out += fmt::format("\n[{}]\n", head);
      emit_table(out, *v->as_table(), head, file);
      continue;
    }
    for (std::size_t i = 0; i < a->size(); ++i) {
      const auto it = k == "link" ? replace.find(i) : replace.end();
      if (it != replace.end()) {
        out += "\n" + it->second;
        if (!it->second.empty() && it->second.back() != '\n') out += "\n";
        continue;
      }
      out += fmt::format("\n[[{}]]\n", head);
      emit_table(out, *a->get(i)->as_table(), head, file);
    }
  }
  return out;
}

}  // namespace ncosim::sim
