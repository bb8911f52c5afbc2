#!/usr/bin/python3
"""tests/schema/unknown_keys_test.py — an unknown key in every section and every registered kind is
refused by `ncosim check` and by the JSON Schema alike (issue 40 part 4).

Usage: unknown_keys_test.py NCOSIM SOURCE_DIR

The sections and kinds come from `ncosim list --keys` (the registries and the sections' declared
keys, not the schema). For each, tests/cli/data/base.toml gets a table of that section and kind
holding the key `bogus_key`: the kind key given, and for a section's default kind (the periodic
policy, the lti plant, the none input) also left out; a kind's table keys with declared fields
(plant.disturbance, plant.disturbance.sine, plant.mode, input.reference) get one inside too. Then
`ncosim check` must exit 2 with `key 'PATH.bogus_key': unknown key` among its errors, and the
schema must report 'bogus_key' as an additional property of PATH.

Uses Debian's python3-jsonschema; a missing module fails the test (never a skip).
"""
import copy
import json
import pathlib
import re
import subprocess
import sys
import tempfile
import tomllib

try:
    import jsonschema
except ImportError:
    print("unknown_keys_test: the Python module jsonschema is missing: install Debian's "
          "python3-jsonschema (scripts/bootstrap.sh installs it)", file=sys.stderr)
    sys.exit(1)

# Registry prefix of `ncosim list --keys` -> (section, kind key, default kind or None).
KINDS = {
    "plant": ("plant", "kind", "lti"),
    "link": ("link", "kind", None),
    "input": ("input", "kind", "none"),
    "estimator": ("estimator", "kind", None),
    "send_policy": ("sensor", "policy", "periodic"),
    "network": ("network", "kind", None),
}
BOGUS = "bogus_key"


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{json.dumps(k)} = {toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(v)


def dumps(doc):
    """TOML text of `doc`: scalars first, then tables and arrays of tables (one level of
    headers; deeper tables inline)."""
    lines = [f"{json.dumps(k)} = {toml_value(v)}" for k, v in doc.items()
             if not isinstance(v, dict) and not (isinstance(v, list) and v and
                                                  all(isinstance(x, dict) for x in v))]
    for k, v in doc.items():
        if isinstance(v, dict):
            lines.append(f"\n[{json.dumps(k)}]")
            lines += [f"{json.dumps(a)} = {toml_value(b)}" for a, b in v.items()]
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for t in v:
                lines.append(f"\n[[{json.dumps(k)}]]")
                lines += [f"{json.dumps(a)} = {toml_value(b)}" for a, b in t.items()]
    return "\n".join(lines) + "\n"


def listing(ncosim):
    """{"plant.lti": {key name: type}} from `ncosim list --keys` (fields as "table.field")."""
    out = subprocess.run([ncosim, "list", "--keys"], capture_output=True, text=True, check=True)
    kinds, current = {}, None
    for line in out.stdout.splitlines():
        m = re.match(r"^([a-z_]+\.[A-Za-z0-9_]+): ", line)
        if m:
            current = kinds.setdefault(m.group(1), {})
            continue
        m = re.match(r"^  (\S+) +(\S+)", line)
        if m and current is not None:
            current[m.group(1)] = m.group(2)
    return kinds


def field_tables(keys):
    """The sub-table paths of a kind's keys with fields ("disturbance", "disturbance.sine")."""
    paths = set()
    for name in keys:
        parts = name.split(".")
        for i in range(1, len(parts)):
            paths.add(".".join(parts[:i]))
    return sorted(p for p in paths if keys.get(p) in ("table", "tables"))


def nested(keys, path):
    """(value holding BOGUS at sub-table `path`, the path's key-path suffix)."""
    parts = path.split(".")
    inner, suffix = {BOGUS: 1}, ""
    for i in range(len(parts), 0, -1):
        is_array = keys[".".join(parts[:i])] == "tables"
        inner = {parts[i - 1]: [inner] if is_array else inner}
    for i in range(1, len(parts) + 1):
        suffix += "." + parts[i - 1] + ("[0]" if keys[".".join(parts[:i])] == "tables" else "")
    return inner[parts[0]], suffix


def cases(kinds, base, top_types):
    """(name, document, key path of the table holding BOGUS) for every section and kind."""
    yield "top level", dict(base, **{BOGUS: 1}), ""
    for name, keys in kinds.items():
        prefix, kind = name.split(".", 1)
        if prefix == "section":
            if kind == "top":
                continue
            doc = copy.deepcopy(base)
            is_array = top_types.get(kind) == "tables"
            if kind not in doc and any(kind == k[0] for k in KINDS.values()):
                continue  # a table of a kinded section without its kind: its kinds cover it
            if kind in doc:
                table = doc[kind][0] if is_array else doc[kind]
                path = f"{kind}[0]" if is_array else kind
            else:
                table = {}
                doc[kind] = [table] if is_array else table
                path = f"{kind}[0]" if is_array else kind
            table[BOGUS] = 1
            yield name, doc, path
            for sub in field_tables(keys):
                doc = copy.deepcopy(base)
                value, suffix = nested(keys, sub)
                if kind in doc:
                    target = doc[kind][0] if is_array else doc[kind]
                else:
                    target = {}
                    doc[kind] = [target] if is_array else target
                target[sub.split(".")[0]] = value
                yield f"{name} {sub}", doc, path + suffix
            continue
        section, kind_key, default = KINDS[prefix]
        is_array = top_types[section] == "tables"
        variants = [{kind_key: kind}] + ([{}] if kind == default else [])
        for variant in variants:
            for sub in [None] + field_tables(keys):
                doc = copy.deepcopy(base)
                table = dict(variant)
                suffix = ""
                if sub is None:
                    table[BOGUS] = 1
                else:
                    value, suffix = nested(keys, sub)
                    table[sub.split(".")[0]] = value
                if is_array:
                    doc.setdefault(section, []).append(table)
                    path = f"{section}[{len(doc[section]) - 1}]"
                else:
                    doc[section] = table
                    path = section
                label = f"{name}{'' if variant else ' (default kind left out)'}"
                yield label + (f" {sub}" if sub else ""), doc, path + suffix


def schema_flags(validator, doc, path):
    """Whether the schema reports BOGUS as an additional property of key path `path`."""
    want = [int(p) if p.isdigit() else p for p in re.findall(r"[^.\[\]]+", path)]
    stack = list(validator.iter_errors(doc))
    while stack:
        e = stack.pop()
        stack.extend(e.context or [])
        if (e.validator == "additionalProperties" and f"'{BOGUS}'" in e.message and
                list(e.absolute_path) == want):
            return True
    return False


def main():
    ncosim, source = sys.argv[1], pathlib.Path(sys.argv[2])
    schema = json.loads(subprocess.run([ncosim, "schema"], capture_output=True, text=True,
                                       check=True).stdout)
    validator = jsonschema.Draft7Validator(schema)
    base = tomllib.loads((source / "tests/cli/data/base.toml").read_text())
    kinds = listing(ncosim)
    top_types = kinds.get("section.top", {})
    if len(kinds) < 30 or not top_types:
        print(f"unknown_keys_test: `ncosim list --keys` listed only {len(kinds)} kinds")
        return 1
    failures = count = 0
    seen = set()
    with tempfile.TemporaryDirectory() as tmp:
        for label, doc, path in cases(kinds, base, top_types):
            count += 1
            seen.add(label.split(" ")[0])
            print(f"  {label}: {path or '(root)'}")
            file = pathlib.Path(tmp) / "unknown.toml"
            file.write_text(dumps(doc))
            key = f"{path}.{BOGUS}" if path else BOGUS
            out = subprocess.run([ncosim, "check", str(file)], capture_output=True, text=True)
            wanted = re.compile(rf": key '{re.escape(key)}': unknown key")
            if out.returncode != 2 or not wanted.search(out.stderr):
                print(f"FAIL {label}: `ncosim check` exited {out.returncode} without "
                      f"\"key '{key}': unknown key\":\n{out.stderr.strip()}")
                failures += 1
            if not schema_flags(validator, doc, path):
                print(f"FAIL {label}: the schema does not refuse '{BOGUS}' at {path or '(root)'}")
                failures += 1
    kinded = {f"section.{k[0]}" for k in KINDS.values()} - {f"section.{k}" for k in base}
    missing = set(kinds) - seen - {"section.top"} - kinded
    for m in sorted(missing):
        print(f"FAIL {m}: no file generated")
        failures += 1
    print(f"{count} files with an unknown key ({len(seen)} sections and kinds): "
          f"{failures} failures")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
