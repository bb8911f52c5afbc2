#!/usr/bin/python3
"""tests/schema/fuzz_schema_test.py — the JSON Schema against `ncosim check` on fuzzed scenarios
(issue 40 part 7, "schema gaps").

Usage: fuzz_schema_test.py FUZZ_TEST NCOSIM [MUTANTS]

The structured fuzzer (tests/fuzz/structured_fuzz_test.cc, fixed seed) writes MUTANTS mutants of
the shipped scenarios (default 300) with the verdict of loading each as `ncosim check` does. Every
mutant is then validated against `ncosim schema` (Debian's python3-jsonschema):

- a mutant the schema refuses must be refused by check too (the schema is never stricter than
  the reader: a false alarm in the editor is a defect);
- a mutant the schema accepts and check refuses must be refused for a reason that JSON Schema
  cannot express (INEXPRESSIBLE below: each class named and explained, also in README.md's
  "Editing scenarios with completion and checks"). Any other is a gap in the schema: the test
  fails naming the mutant and check's message.

Prints the counts of each class (the figure the issue asks for).
"""
import collections
import json
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import tomllib

try:
    import jsonschema
except ImportError:
    print("fuzz_schema_test: the Python module jsonschema is missing: install Debian's "
          "python3-jsonschema (scripts/bootstrap.sh installs it)", file=sys.stderr)
    sys.exit(1)

# What the schema cannot say about a scenario: check's message -> the class, tried in this order.
# Each needs the model, another key's value, another table or file, or a value JSON cannot hold;
# README.md ("Editing scenarios with completion and checks") lists the same.
INEXPRESSIBLE = [
    ("a [[sweep]] value, judged in its case (the schema cannot resolve a sweep's key path to the "
     "key it sets)", r"\(in the sweep case |\(in the base scenario"),
    ("a non-finite number (JSON has no NaN or infinity, so a schema never sees one)",
     r"finite numbers?, got|got -?(nan|inf)\b"),
    ("a matrix whose rows differ in length (JSON Schema cannot compare two arrays' lengths)",
     r"expected every row to have \d+ entries"),
    ("a size set by the model or by another key (the state size, the outputs, a chain's states)",
     r"\(the state size\)|expected a \d+x\d+ matrix|square|\(the state\)|one per output|"
     r"per-state|as many|entries \(the"),
    ("a property of a matrix or law (symmetric, positive semidefinite, a sum of probabilities)",
     r"positive semidefinite|non-symmetric|must sum to|sum to at most|rows sum|eigenvalue"),
    ("a reference to another table by name, or names that must be unique",
     r"expected the name of a \[\[|expected a unique|expected an estimator name"),
    ("a bound set by another key (warmup below periods)", r"periods-1"),
    ("a radio's reach (the power at its network's sink: positions, transmit power and the "
     "standard together)", r"within range of network"),
    ("a resource limit (--max-memory, --max-work)", r"--max-memory|--max-work"),
    ("a design that cannot be made for this model", r"the \w+ design|cannot be posed"),
    ("a file that must exist and be well formed (a trace, SUMO inputs)",
     r"cannot open|not found|readable"),
]


def classify(message):
    text = message.split(": key ", 1)[-1]
    for name, pattern in INEXPRESSIBLE:
        if re.search(pattern, text):
            return name
    return None


def main():
    fuzz_test, ncosim = sys.argv[1], sys.argv[2]
    mutants = int(sys.argv[3]) if len(sys.argv) > 3 else 300
    schema = json.loads(subprocess.run([ncosim, "schema"], capture_output=True, text=True,
                                       check=True).stdout)
    validator = jsonschema.Draft7Validator(schema)
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, NCOSIM_FUZZ_MUTANTS=str(mutants), NCOSIM_FUZZ_SECONDS="0",
                   NCOSIM_FUZZ_RUN_EVERY="0", NCOSIM_FUZZ_DUMP=tmp)
        out = subprocess.run([fuzz_test, "--gtest_filter=StructuredFuzz.*"], env=env,
                             capture_output=True, text=True)
        if out.returncode != 0:
            print(f"fuzz_schema_test: the fuzzer failed:\n{out.stdout[-3000:]}{out.stderr[-2000:]}")
            return 1
        verdicts = {}
        for line in (pathlib.Path(tmp) / "verdicts.tsv").read_text().splitlines():
            index, verdict, message = line.split("\t", 2)
            verdicts[int(index)] = (verdict, message)
        counts = collections.Counter()
        classes = collections.Counter()
        failures = 0
        for index, (verdict, message) in sorted(verdicts.items()):
            text = (pathlib.Path(tmp) / f"mutant_{index}.toml").read_text()
            try:
                doc = tomllib.loads(text)
            except tomllib.TOMLDecodeError as e:
                counts["not TOML to Python's tomllib"] += 1
                print(f"note: mutant {index} is not read by tomllib ({e}); check: {verdict}")
                continue
            valid = validator.is_valid(doc)
            refused = verdict == "refused"
            counts[(f"schema {'accepts' if valid else 'refuses'}, "
                    f"check {'refuses' if refused else 'accepts'}")] += 1
            if not valid and not refused:
                failures += 1
                first = next(iter(validator.iter_errors(doc)))
                where = "/".join(str(p) for p in first.absolute_path) or "(root)"
                print(f"FAIL mutant {index}: check accepts it, the schema refuses it: {where}: "
                      f"{first.message}\n{text}")
            if valid and refused:
                why = classify(message)
                if why is None:
                    failures += 1
                    print(f"FAIL mutant {index}: the schema accepts it, check refuses it for a "
                          f"reason the schema could say: {message}\n{text}")
                else:
                    classes[why] += 1
                    print(f"  accepted by the schema, refused by check ({why}): {message}")
    print(f"{len(verdicts)} mutants:")
    for k, v in sorted(counts.items()):
        print(f"  {v:4d}  {k}")
    print("accepted by the schema and refused by check, by reason:")
    for k, v in classes.most_common():
        print(f"  {v:4d}  {k}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
