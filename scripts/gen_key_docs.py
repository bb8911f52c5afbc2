#!/usr/bin/python3
"""Regenerate the per-kind key tables of scenarios/README.md from the kinds' declarations.

Every block

    <!-- keys:link.bernoulli -->
    ...
    <!-- /keys -->

is replaced by the output of `ncosim list --keys link.bernoulli --format md` (config/keys.h
declarations: type, unit, default, allowed range or values, help). The prose around the blocks is
kept. With --check nothing is written: the exit status is 1 when a block differs from the
declarations, naming each kind and the command that regenerates them (the ctest `key_docs`).

    /usr/bin/python3 scripts/gen_key_docs.py --ncosim build/sim/ncosim [scenarios/README.md]
"""
import argparse
import re
import subprocess
import sys

BLOCK = re.compile(r"(<!-- keys:([A-Za-z0-9_.]+) -->\n)(.*?)(<!-- /keys -->)", re.S)


def table(ncosim, kind):
    out = subprocess.run([ncosim, "list", "--keys", kind, "--format", "md"],
                         capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"gen_key_docs: `ncosim list --keys {kind}` failed: {out.stderr.strip()}")
    return out.stdout


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("readme", nargs="?", default="scenarios/README.md")
    ap.add_argument("--ncosim", default="build/sim/ncosim", help="the ncosim executable")
    ap.add_argument("--check", action="store_true", help="only compare; exit 1 on a difference")
    args = ap.parse_args()
    with open(args.readme, encoding="utf-8") as f:
        text = f.read()
    stale = []

    def replace(m):
        fresh = table(args.ncosim, m.group(2))
        if m.group(3) != fresh:
            stale.append(m.group(2))
        return m.group(1) + fresh + m.group(4)

    new = BLOCK.sub(replace, text)
    count = len(BLOCK.findall(text))
    if args.check:
        if stale:
            print(f"{args.readme}: the key tables of {', '.join(stale)} differ from the kinds' "
                  f"declarations; regenerate them with\n"
                  f"    /usr/bin/python3 scripts/gen_key_docs.py --ncosim build/sim/ncosim "
                  f"{args.readme}", file=sys.stderr)
            return 1
        print(f"{args.readme}: {count} key tables match the declarations")
        return 0
    if new != text:
        with open(args.readme, "w", encoding="utf-8") as f:
            f.write(new)
    print(f"{args.readme}: {count} key tables, {len(stale)} rewritten ({', '.join(stale)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
