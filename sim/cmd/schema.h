// sim/cmd/schema.h — a JSON Schema (draft-07) of the whole scenario format, made from the declared
// keys (sim/scenario/scenario_keys.h, config/keys.h): `ncosim schema`. Editors with a TOML language
// server (taplo, Even Better TOML) use it to complete and check scenario files (README.md).
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace ncosim::sim {

// Per section an object schema; per kind a subschema selected by the section's kind key
// (if/then on a const), additionalProperties false where the reader rejects unknown keys and the
// kind declares its keys; types, enums, minimum/maximum and descriptions (help, unit, default).
nlohmann::ordered_json scenario_schema();

// `ncosim schema [--out FILE]`: the schema as indented JSON on stdout or into FILE (exit status;
// std::runtime_error when FILE cannot be written).
int cmd_schema(const std::string& out);

}  // namespace ncosim::sim
