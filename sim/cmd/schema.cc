// sim/cmd/schema.cc — the scenario format as a JSON Schema (sim/cmd/schema.h).
#include "sim/cmd/schema.h"

#include <fmt/format.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <variant>

#include "sim/scenario/scenario_keys.h"

namespace ncosim::sim {

namespace {

using Json = nlohmann::ordered_json;

// A number with the key's range (for arrays: every entry).
Json number_schema(const config::Key& k, const char* type) {
  Json s{{"type", type}};
  // Integer bounds as integers (1, not 1.0).
  auto bound = [&](double v) {
    return k.type() == config::KeyType::kInteger ? Json(static_cast<std::int64_t>(v)) : Json(v);
  };
  if (k.lo()) s[k.lo_open() ? "exclusiveMinimum" : "minimum"] = bound(*k.lo());
  if (k.hi()) s[k.hi_open() ? "exclusiveMaximum" : "maximum"] = bound(*k.hi());
  return s;
}

Json object_schema(const config::Keys& keys);

// minItems / maxItems of an array key's entries (a bare number counts as one).
void add_entries(Json& array, const config::Key& k) {
  if (k.min_entries() > 0) array["minItems"] = k.min_entries();
  if (k.max_entries() > 0) array["maxItems"] = k.max_entries();
}

// Whether a bare number (an array of one) is allowed.
bool one_allowed(const config::Key& k) {
  return k.min_entries() <= 1 && (k.max_entries() == 0 || k.max_entries() >= 1);
}

Json typed_schema(const config::Key& k) {
  const Json number = number_schema(k, "number");
  Json array_of_numbers{{"type", "array"}, {"items", number}};
  switch (k.type()) {
    case config::KeyType::kNumber:
      return number;
    case config::KeyType::kInteger:
      return number_schema(k, "integer");
    case config::KeyType::kBoolean:
      return Json{{"type", "boolean"}};
    case config::KeyType::kString:
      return Json{{"type", "string"}};
    case config::KeyType::kChoice:
      return Json{{"type", "string"}, {"enum", k.values()}};
    case config::KeyType::kNumbers:
    case config::KeyType::kVector: {  // a bare number is an array of one
      add_entries(array_of_numbers, k);
      if (!one_allowed(k)) return array_of_numbers;
      return Json{{"anyOf", Json::array({number, array_of_numbers})}};
    }
    case config::KeyType::kMatrix: {  // an array of rows, or a bare number (1x1)
      Json row = array_of_numbers;
      row["minItems"] = 1;
      if (k.columns() > 0) row["minItems"] = row["maxItems"] = k.columns();
      Json rows{{"type", "array"}, {"minItems", 1}, {"items", row}};
      add_entries(rows, k);
      if (!one_allowed(k) || k.columns() > 1) return rows;
      return Json{{"anyOf", Json::array({number, rows})}};
    }
    case config::KeyType::kRagged: {
      Json row = array_of_numbers;
      if (k.columns() > 0) row["minItems"] = row["maxItems"] = k.columns();
      Json rows{{"type", "array"}, {"items", row}};
      add_entries(rows, k);
      return rows;
    }
    case config::KeyType::kTable:
      return k.fields() != nullptr ? object_schema(*k.fields()) : Json{{"type", "object"}};
    case config::KeyType::kTables: {
      Json tables{
          {"type", "array"},
          {"items", k.fields() != nullptr ? object_schema(*k.fields()) : Json{{"type", "object"}}}};
      add_entries(tables, k);
      return tables;
    }
    case config::KeyType::kArray: {
      Json array{{"type", "array"}};
      add_entries(array, k);
      return array;
    }
    case config::KeyType::kAny:
      return Json::object();
  }
  return Json::object();
}

// The key's type, or one of its words.
Json type_schema(const config::Key& k) {
  Json typed = typed_schema(k);
  if (k.words().empty()) return typed;
  const Json words{{"type", "string"}, {"enum", k.words()}};
  if (typed.contains("anyOf")) {
    typed["anyOf"].push_back(words);
    return typed;
  }
  return Json{{"anyOf", Json::array({typed, words})}};
}

Json default_value(const config::Key::Value& v) {
  struct Visit {
    Json operator()(std::monostate) const { return nullptr; }
    Json operator()(double x) const { return x; }
    Json operator()(std::int64_t x) const { return x; }
    Json operator()(bool x) const { return x; }
    Json operator()(const std::string& x) const { return x; }
    Json operator()(const std::vector<double>& x) const { return x; }
  };
  return std::visit(Visit{}, v);
}

// "help [unit] (default: D; allowed: R)".
std::string description(const config::Key& k) {
  std::string text = k.help_text();
  if (!k.unit_text().empty()) text += fmt::format(" [{}]", k.unit_text());
  std::string notes;
  if (k.required())
    notes = "required";
  else if (!k.default_text().empty())
    notes = "default: " + k.default_text();
  if (!k.range_text().empty())
    notes += (notes.empty() ? "" : "; ") + ("allowed: " + k.range_text());
  if (!k.shape_text().empty()) notes += (notes.empty() ? "" : "; ") + k.shape_text();
  if (k.type() == config::KeyType::kAny) notes += (notes.empty() ? "" : "; ") + k.type_text();
  return notes.empty() ? text : fmt::format("{} ({})", text, notes);
}

Json key_schema(const config::Key& k) {
  Json s = type_schema(k);
  s["description"] = description(k);
  const Json d = default_value(k.default_value());
  if (!d.is_null()) s["default"] = d;
  return s;
}

// The properties and required keys of `keys` added to object schema `s` (a group of which one
// is required: an anyOf of required lists in s's allOf).
void add_keys(Json& s, const config::Keys& keys) {
  for (const config::Key& k : keys.list()) {
    s["properties"][k.name()] = key_schema(k);
    if (k.required()) {
      Json& req = s["required"];
      if (std::find(req.begin(), req.end(), Json(k.name())) == req.end()) req.push_back(k.name());
    }
  }
  for (const auto& group : keys.one_of()) {
    Json any = Json::array();
    for (const auto& name : group) any.push_back(Json{{"required", Json::array({name})}});
    s["allOf"].push_back(Json{{"anyOf", any}});
  }
}

// A table of declared fields: closed (its reader rejects other keys).
Json object_schema(const config::Keys& keys) {
  Json s{{"type", "object"}, {"properties", Json::object()}};
  add_keys(s, keys);
  s["additionalProperties"] = false;
  return s;
}

Json section_schema(const Section& sec) {
  Json s{{"type", "object"}, {"description", sec.help}, {"properties", Json::object()}};
  s["required"] = Json::array();
  if (sec.keys != nullptr) add_keys(s, *sec.keys);
  if (!sec.kind_key.empty()) {
    std::vector<std::string> names;
    for (const auto& kind : sec.kinds) names.push_back(kind.name);
    Json& kk = s["properties"][sec.kind_key];
    kk["type"] = "string";
    kk["enum"] = names;
    Json all = Json::array();
    for (const auto& kind : sec.kinds) {
      Json cond{{"properties", {{sec.kind_key, {{"const", kind.name}}}}}};
      if (kind.name != sec.default_kind) cond["required"] = Json::array({sec.kind_key});
      Json then{{"description", kind.help}, {"properties", s["properties"]}};
      then["required"] = s["required"];
      if (kind.keys != nullptr) add_keys(then, *kind.keys);
      if (then["required"].empty()) then.erase("required");
      // A kind that declared its keys (even none, as the periodic policy) closes its table; one
      // registered without declarations (an extension's) leaves it open.
      if (sec.closed && kind.declared) then["additionalProperties"] = false;
      all.push_back(Json{{"if", cond}, {"then", then}});
    }
    for (auto& rule : all) s["allOf"].push_back(std::move(rule));
  } else if (sec.closed && sec.keys != nullptr) {
    s["additionalProperties"] = false;
  }
  if (s["required"].empty()) s.erase("required");
  if (!sec.array) return s;
  Json arr{{"type", "array"}, {"description", sec.help}, {"items", s}};
  if (sec.required) arr["minItems"] = 1;
  return arr;
}

}  // namespace

nlohmann::ordered_json scenario_schema() {
  Json root{{"$schema", "http://json-schema.org/draft-07/schema#"},
            {"title", "ncosim scenario"},
            {"description",
             "A scenario of ncosim (scenarios/README.md), generated by `ncosim schema` from the "
             "declared keys of every section and kind."},
            {"type", "object"},
            {"properties", Json::object()}};
  Json required = Json::array();
  root["properties"]["title"] = key_schema(top_level_keys().at("title"));
  for (const Section& sec : scenario_sections()) {
    root["properties"][sec.key] = section_schema(sec);
    if (sec.required) required.push_back(sec.key);
  }
  root["required"] = required;
  root["additionalProperties"] = false;
  return root;
}

int cmd_schema(const std::string& out) {
  const std::string text = scenario_schema().dump(2) + "\n";
  if (out.empty()) {
    std::cout << text;
    return 0;
  }
  // Written beside and renamed in: an interrupted or failed write leaves no half-written file.
  const std::string tmp = fmt::format("{}.tmp.{}", out, static_cast<long>(::getpid()));
  {
    std::ofstream f(tmp, std::ios::binary);
    f << text;
    f.flush();
    if (!f.good()) {
      std::error_code ec;
      std::filesystem::remove(tmp, ec);
      throw std::runtime_error(fmt::format("cannot write the schema to {}", out));
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, out, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw std::runtime_error(fmt::format("cannot write the schema to {}", out));
  }
  return 0;
}

}  // namespace ncosim::sim
