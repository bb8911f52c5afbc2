#!/usr/bin/python3
"""tests/schema/schema_test.py — `ncosim schema` checked by an independent validator.

Usage: schema_test.py NCOSIM SOURCE_DIR

1. `ncosim schema` writes a draft-07 JSON Schema (checked against the draft-07 meta-schema).
2. Every shipped scenario (scenarios/*.toml and below, results/**/*.toml, the tests' good
   scenario files tests/cli/data/*.toml) converted to JSON (tomllib) validates.
3. Every bad edit of the cli error tests that is a schema matter (tests/cli/cli_test.cc: an
   unknown key, a wrong type, a value out of range, an unknown kind or value) is rejected.

Uses Debian's python3-jsonschema; a missing module fails the test (never a skip).
"""
import json
import pathlib
import subprocess
import sys
import tempfile
import tomllib

try:
    import jsonschema
except ImportError:
    print("schema_test: the Python module jsonschema is missing: install Debian's "
          "python3-jsonschema (scripts/bootstrap.sh installs it)", file=sys.stderr)
    sys.exit(1)

# (text in tests/cli/data/base.toml, its replacement, what is wrong): each makes a scenario
# that `ncosim run` rejects (tests/cli/cli_test.cc) and that the schema must reject too.
BAD_EDITS = [
    ("history = 2", "histroy = 2", "unknown estimator key"),
    ("history = 2", "history = 0", "history out of range (1..1000)"),
    ("history = 2", "history = 1001", "history out of range (1..1000)"),
    ("history = 2", "history = 2.5", "history not an integer"),
    ("history = 2", 'expected_status = "diverge"\nhistory = 2', "expected_status not a status"),
    ("history = 2", "expected_status = 1\nhistory = 2", "expected_status not a string"),
    ('grouping = "S2"', 'design = "cll"\ngrouping = "S2"', "unknown jump design"),
    ('grouping = "S2"', 'grouping = "S5"', "unknown grouping"),
    ("max_delay = 1\n\n[[estimator]]", "max_delay = 63\n\n[[estimator]]", "max_delay > 62"),
    ('kind = "kalman_extended"', 'kind = "kalman"', "unknown estimator kind"),
    ('kind = "kalman_extended"', 'kind = "kalman_extended"\nhistory = 2',
     "a jump key on kalman_extended"),
    ('[[sensor]]\nname = "y1"', '[[sensr]]\nname = "y1"', "unknown top-level table"),
    ('kind = "lti"', 'kind = "ltx"', "unknown plant kind"),
    ('kind = "delay"', 'kind = "dealy"', "unknown link kind"),
    ('kind = "white"', 'kind = "whte"', "unknown input kind"),
    ("runs = 4", "runs = 0", "run.runs out of range"),
    ("seed = 7", "sed = 7", "unknown [run] key"),
    ("seed = 7", "seed = -1", "negative seed"),
    ("periods = 2000", 'periods = "2000"', "periods not an integer"),
    ('title = "cli test base"', "title = 3", "title not a string"),
    ("seed = 7", 'seed = 7\nrecentre = "sometimes"', "unknown recentre value"),
    ("seed = 7", "seed = 7\nerror_curve = 1", "error_curve not a boolean"),
    ('name = "Kalman"', "name = 3", "estimator name not a string"),
    ('name = "Kalman"', 'name = "Kalman"\nP0 = "big"', "P0 not a matrix"),
    ('name = "Kalman"', 'name = "Kalman"\nxhat0 = [[1.0], [2.0]]', "xhat0 not a vector"),
    ('link = "net1"', 'link = "net1"\nevery = 0', "sensor every out of range"),
    ('link = "net1"', 'link = "net1"\nnoise = "cauchy"', "unknown sensor noise"),
    ('link = "net1"', 'link = "net1"\npolicy = "periodic"\nbogus = 1',
     "unknown key beside the periodic policy"),
    ('link = "net1"', 'link = "net1"\nbogus = 1', "unknown key beside the default policy"),
    (None, '\n[[sweep]]\nkey = "estimator[0].history"\nvalues = []\n', "an empty sweep"),
    (None, '\n[[sweep]]\nkey = "estimator[0].history"\nvalues = 3\n', "sweep values not an array"),
]

# The same on the network fixture (tests/network/data/wifi_background.toml).
NETWORK_FILE = "tests/network/data/wifi_background.toml"
NETWORK_EDITS = [
    ("rate = 50.0", "rate = -1.0", "background.rate negative"),
    ("rate = 50.0", "rate = 1e12", "background.rate above 1e7"),
    ("rate = 50.0", 'rate = "SATURATED"', "background.rate an unknown word"),
    ("rate = 50.0", "rate = true", "background.rate a boolean"),
    ("position = [5.0, 0.0, 0.0]", "position = [5.0, 0.0]", "link position of 2 numbers"),
    ("position = [5.0, 0.0, 0.0]", "position = [5.0, 0.0, 0.0, 1.0]",
     "link position of 4 numbers"),
    ("position = [3.0, 3.0, 0.0]", "position = [3.0, 3.0]", "background position of 2 numbers"),
    ("positions = [[10.0, 0.0, 0.0],", "positions = [[10.0, 0.0],",
     "background positions row of 2"),
    ("tx_power = 16.0", "tx_power = 16.0\nsink_position = [1.0, 2.0]", "sink_position of 2"),
    ("tx_power = 16.0", 'tx_power = 16.0\ndata_mode = "garbage"', "data_mode not a data mode"),
    ("position = [5.0, 0.0, 0.0]", "position = [5.0, 0.0, 0.0]\ndesign_pmf = [1.5]",
     "design_pmf above 1"),
    ("position = [5.0, 0.0, 0.0]", "position = [5.0, 0.0, 0.0]\ndesign_pmf = [-0.1, 0.5]",
     "design_pmf negative"),
]


def load_toml(path):
    with open(path, "rb") as f:
        return tomllib.load(f)


def main():
    ncosim, source = sys.argv[1], pathlib.Path(sys.argv[2])
    out = subprocess.run([ncosim, "schema"], capture_output=True, text=True)
    if out.returncode != 0:
        print(f"schema_test: `ncosim schema` exited {out.returncode}: {out.stderr}",
              file=sys.stderr)
        return 1
    schema = json.loads(out.stdout)
    jsonschema.Draft7Validator.check_schema(schema)
    validator = jsonschema.Draft7Validator(schema)
    failures = 0

    good = sorted(source.glob("scenarios/**/*.toml")) + sorted(source.glob("results/**/*.toml"))
    good += sorted(source.glob("tests/cli/data/*.toml"))
    if len(good) < 10:
        print(f"schema_test: only {len(good)} scenario files found below {source}",
              file=sys.stderr)
        return 1
    for path in good:
        errors = list(validator.iter_errors(load_toml(path)))
        for e in errors[:5]:
            where = "/".join(str(p) for p in e.absolute_path) or "(root)"
            print(f"FAIL {path.relative_to(source)}: {where}: {e.message}")
        failures += bool(errors)
    print(f"{len(good)} shipped scenario files checked, {failures} invalid")

    base_path = source / "tests/cli/data/base.toml"
    base = base_path.read_text()
    network_path = source / NETWORK_FILE
    network = network_path.read_text()
    for path, text in ((base_path, base), (network_path, network)):
        if list(validator.iter_errors(tomllib.loads(text))):
            print(f"FAIL {path} is invalid: the bad edits below prove nothing")
            return 1
    edits = [(base_path, base, *e) for e in BAD_EDITS]
    edits += [(network_path, network, *e) for e in NETWORK_EDITS]
    rejected = 0
    with tempfile.TemporaryDirectory() as tmp:
        for path, text, old, new, what in edits:
            if old is not None and old not in text:
                print(f"FAIL bad edit '{what}': {old!r} is not in {path}")
                failures += 1
                continue
            bad = text + new if old is None else text.replace(old, new, 1)
            doc = tomllib.loads(bad)
            if validator.is_valid(doc):
                print(f"FAIL bad edit '{what}' ({old!r} -> {new!r}) validates")
                failures += 1
                continue
            # `ncosim check` refuses it too (exit 2).
            file = pathlib.Path(tmp) / path.name
            file.write_text(bad)
            out = subprocess.run([ncosim, "check", str(file)], capture_output=True, text=True)
            if out.returncode != 2:
                print(f"FAIL bad edit '{what}': the schema refuses it, `ncosim check` exits "
                      f"{out.returncode}: {out.stderr.strip()}")
                failures += 1
                continue
            rejected += 1
    print(f"{rejected} of {len(edits)} bad edits rejected by the schema and by check")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
