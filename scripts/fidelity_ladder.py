#!/usr/bin/env python3
"""The fidelity ladder across the load: is a fitted statistical link a fair stand-in for a packet-level network?

An IEEE 802.15.4 star (ns-3's lr-wpan) of K sensor nodes on a ring of radius 20 m around the
estimators' node, every node sending one sample every 20 ms, for growing K. Per K the script
writes the star's scenario (without design_pmf: the ladder fits it) and runs

  ncosim ladder WORK/K<k>.toml --out WORK/K<k> --family bernoulli --family delay
                               --family gilbert_elliott --threads T --replace

which records every link (`record-link`: each run the network campaign's run, every node
contending), fits each link's trace (`fit`), writes one scenario per rung (the network with the
`delay` fit as every link's design_pmf; every link replaced by its fitted `bernoulli` (the loss
rate, every delivered packet with its most common delay), `delay` (independent packets with the
trace's delay law) or `gilbert_elliott` (losses in bursts, delays independent of the state)
link), runs them with the same seed and compares each surrogate with the network, paired run by
run (`compare`, --tolerance 0.05). Beside the ladder the script adds

  trace   every link replaced by its own recorded trace (run r replays run r): the check that the
          record is the campaign's channel (a `kalman_extended` run's MSE equals the network's);
  the traces' statistics: loss, delay law, mean loss run, the cross-sensor correlation of the
          losses (what independent surrogates cannot hold), P(every sensor lost in one period).

Writes OUT/table.csv, table.md, timing.csv, fits.csv and the campaigns' summary_<rung>_K<k>.csv;
the ladders' folders (scenarios, traces, fits, campaigns, comparisons) stay in WORK. Long: not part
of the test suite.

  scripts/fidelity_ladder.py [--out results/fidelity_ladder] [--work out/fidelity_ladder]
                             [--ks 2,4,5,6,8] [--runs 20] [--periods 1000] [--threads 2]
Binary: $NCOSIM or build/sim/ncosim. Needs a build with ns-3 (NCOSIM_NS3).
"""

import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(os.environ.get("NCOSIM", ROOT / "build" / "sim" / "ncosim"))
if not BIN.is_absolute():
    BIN = ROOT / BIN

RADIUS = 20.0  # m: every node in range of every other (no hidden node), losses by contention
PERIOD = 0.02  # s
BYTES = 24
WARMUP = 100
SEED = 2025
TOLERANCE = 0.05
ESTIMATORS = """
[[estimator]]
name = "Kalman"
kind = "kalman_extended"
max_delay = 3

[[estimator]]
name = "static N=3"
kind = "static_buffer"
buffer = 3
"""
FAMILIES = ("bernoulli", "delay", "gilbert_elliott")  # the ladder's rungs, lowest first
RUNGS = ("network", "trace") + FAMILIES


def ncosim(*args):
    cmd = [str(BIN), *map(str, args)]
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"fidelity_ladder: {' '.join(cmd)} failed ({r.returncode}):\n{r.stderr}")
    return r.stdout


def head(k, periods, runs):
    return "\n".join([
        f'title = "fidelity ladder: IEEE 802.15.4 star, K = {k}"',
        "",
        "[run]",
        f"periods = {periods}",
        f"warmup = {WARMUP}",
        f"runs = {runs}",
        f"seed = {SEED}",
        f"period = {PERIOD}",
        "",
        "[plant]",
        "A = [[1.0, 0.1], [0.0, 0.8]]",
        "Bw = [[1.0, 0.0], [0.0, 1.0]]",
        "W = [[0.2, 0.1], [0.1, 1.0]]",
        "",
    ])


def sensors(k):
    out = []
    for i in range(k):
        c = "[[1.0, 0.0]]" if i % 2 == 0 else "[[0.0, 1.0]]"
        what = "position" if i % 2 == 0 else "speed"
        out.append(f'[[sensor]]\nname = "{what} {i + 1}"\nC = {c}\nR = [[1.0]]\nlink = "n{i + 1}"\n')
    return "\n".join(out)


def network_links(k):
    out = ['[[network]]\nname = "wsn"\nkind = "lr_wpan"\ntx_power = 0.0\n']
    for i in range(k):
        a = 2.0 * math.pi * i / k
        x, y = RADIUS * math.cos(a), RADIUS * math.sin(a)
        out.append(
            f'[[link]]\nname = "n{i + 1}"\nkind = "network"\nnetwork = "wsn"\nbytes = {BYTES}\n'
            f"position = [{x:.6f}, {y:.6f}, 0.0]\n"
        )
    return "\n".join(out)


def trace_scenario(network_toml, k, periods):
    """The ladder's network.toml with every link replaced by its own recorded trace (paths
    relative to the ladder's folder, where the scenario is written)."""
    text = network_toml.split("\n[[network]]")[0]
    links = "\n".join(
        f'[[link]]\nname = "n{i + 1}"\nkind = "trace"\nfile = "traces/n{i + 1}.csv"\n'
        f"segment = {periods}\n" for i in range(k))
    return text + "\n" + links + "\n" + sensors(k) + ESTIMATORS


def read_trace(path):
    with open(path, newline="") as f:
        return [row["delay"] for row in csv.DictReader(f)]


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def trace_stats(traces, periods, warmup):
    """Scored periods only: loss, delay law, mean loss run, and the cross-sensor correlation of
    the losses (mean over sensor pairs of the correlation of the loss indicators in one period)."""
    k = len(traces)
    n = len(traces[0])
    scored = [j for j in range(n) if j % periods >= warmup]
    lost = [[t[j] == "" for j in scored] for t in traces]
    m = len(scored)
    loss = sum(sum(x) for x in lost) / (k * m)
    delays = {}
    for t in traces:
        for j in scored:
            if t[j] != "":
                d = int(t[j])
                delays[d] = delays.get(d, 0) + 1
    total = k * m
    pmf = [delays.get(d, 0) / total for d in range(max(delays) + 1)] if delays else [0.0]
    runs_sum = runs_n = 0
    for li in lost:
        open_run = 0
        for j, x in enumerate(li):
            if j > 0 and scored[j] % periods == warmup and open_run:  # a run's end closes one
                runs_sum += open_run
                runs_n += 1
                open_run = 0
            if x:
                open_run += 1
            elif open_run:
                runs_sum += open_run
                runs_n += 1
                open_run = 0
        if open_run:
            runs_sum += open_run
            runs_n += 1
    means = [sum(li) / m for li in lost]
    corr_sum = pairs = 0
    all_lost = sum(all(li[j] for li in lost) for j in range(m))
    for a in range(k):
        for b in range(a + 1, k):
            va = means[a] * (1 - means[a])
            vb = means[b] * (1 - means[b])
            if va <= 0 or vb <= 0:
                continue
            both = sum(1 for j in range(m) if lost[a][j] and lost[b][j]) / m
            corr_sum += (both - means[a] * means[b]) / math.sqrt(va * vb)
            pairs += 1
    return {
        "loss": loss,
        "pmf": pmf,
        "mean_delay": sum(d * p for d, p in enumerate(pmf)) / max(1e-300, 1 - loss),
        "loss_run_mean": runs_sum / runs_n if runs_n else 0.0,
        "loss_corr": corr_sum / pairs if pairs else float("nan"),
        "all_lost": all_lost / m,
        "all_lost_independent": math.prod(means),
    }


def one_k(k, args, work, out):
    folder = work / f"K{k}"
    scenario = work / f"K{k}.toml"
    scenario.write_text(head(k, args.periods, args.runs) + network_links(k) + "\n" + sensors(k)
                        + ESTIMATORS)
    print(f"K = {k}: ncosim ladder", file=sys.stderr)
    start = time.monotonic()
    fams = [a for f in FAMILIES for a in ("--family", f)]
    ncosim("ladder", scenario, "--out", folder, *fams, "--threads", args.threads,
           "--tolerance", TOLERANCE, "--replace", "--quiet")
    ladder_wall = time.monotonic() - start
    print(f"K = {k}: the replayed traces", file=sys.stderr)
    (folder / "trace.toml").write_text(trace_scenario((folder / "network.toml").read_text(), k,
                                                      args.periods))
    ncosim("run", folder / "trace.toml", "--out", folder / "trace_run", "--quiet", "--no-timing",
           "--replace", "--threads", args.threads)
    traces = [read_trace(folder / "traces" / f"n{i + 1}.csv") for i in range(k)]
    res = {"k": k, "stats": trace_stats(traces, args.periods, WARMUP), "ladder_wall": ladder_wall,
           "ladder": read_csv(folder / "ladder.csv")}
    runs = {r: folder / "runs" / r for r in RUNGS if r != "trace"}
    runs["trace"] = folder / "trace_run"
    for r, d in runs.items():
        res[f"summary_{r}"] = read_csv(d / "summary.csv")
        res[f"runs_{r}"] = read_csv(d / "runs.csv")
        res[f"wall_{r}"] = json.loads((d / "manifest.json").read_text())["wall_seconds"]
        shutil.copy(d / "summary.csv", out / f"summary_{r}_K{k}.csv")
    res["fits"] = {}
    for f in FAMILIES:  # the fitted link of n1 (the nodes are alike; every link's in fits/)
        text = (folder / f"{f}.toml").read_text()
        table = text[text.index('name = "n1"'):].split("\n\n")[0]
        res["fits"][f] = table
    return res


def fmt(x, digits=4):
    if x is None or x == "":
        return ""
    return f"{float(x):.{digits}g}"


def write_outputs(results, args, out):
    header = ["K", "estimator", "loss", "mean_delay", "loss_run_mean", "loss_corr", "all_lost",
              "all_lost_independent"]
    for r in RUNGS:
        header += [f"mse_{r}", f"mse_{r}_ci95"]
    for f in FAMILIES:
        header += [f"change_{f}", f"change_{f}_ci_low", f"change_{f}_ci_high", f"verdict_{f}",
                   f"band_{f}"]
    rows = []
    for res in results:
        st = res["stats"]
        for s in res["summary_network"]:
            e = s["estimator"]
            row = {"K": res["k"], "estimator": e, "loss": st["loss"], "mean_delay": st["mean_delay"],
                   "loss_run_mean": st["loss_run_mean"], "loss_corr": st["loss_corr"],
                   "all_lost": st["all_lost"], "all_lost_independent": st["all_lost_independent"]}
            for r in RUNGS:
                sv = next(x for x in res[f"summary_{r}"] if x["estimator"] == e)
                row[f"mse_{r}"] = sv["mse"]
                row[f"mse_{r}_ci95"] = sv["mse_ci95"]
            for f in FAMILIES:
                c = next(x for x in res["ladder"] if x["rung"] == f and x["estimator"] == e)
                row[f"change_{f}"] = c["change"]
                row[f"change_{f}_ci_low"] = c["change_ci95_low"]
                row[f"change_{f}_ci_high"] = c["change_ci95_high"]
                row[f"verdict_{f}"] = c["verdict"]
                row[f"band_{f}"] = c["band"]
            rows.append(row)
    with open(out / "table.csv", "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
        wr.writeheader()
        for row in rows:
            wr.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})

    def change(row, fam):
        if row[f"change_{fam}"] == "":
            return ""
        pct = [100 * float(row[f"change_{fam}{s}"]) for s in ("", "_ci_low", "_ci_high")]
        return f"{pct[0]:+.1f} % [{pct[1]:+.1f}, {pct[2]:+.1f}] {row[f'band_{fam}']}"

    with open(out / "table.md", "w") as f:
        f.write("| K | estimator | loss | corr. | P(all lost) / indep. | mse network | mse trace | "
                "mse GE | mse delay | mse Bernoulli | GE vs network | delay vs network | "
                "Bernoulli vs network |\n")
        f.write("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n")
        for row in rows:
            mses = " | ".join(f"{fmt(row[f'mse_{r}'])} ± {fmt(row[f'mse_{r}_ci95'], 2)}"
                              for r in ("network", "trace", "gilbert_elliott", "delay", "bernoulli"))
            f.write(f"| {row['K']} | {row['estimator']} | {fmt(row['loss'])} | "
                    f"{fmt(row['loss_corr'], 3)} | {fmt(row['all_lost'], 3)} / "
                    f"{fmt(row['all_lost_independent'], 3)} | {mses} | "
                    f"{change(row, 'gilbert_elliott')} | {change(row, 'delay')} | "
                    f"{change(row, 'bernoulli')} |\n")
    with open(out / "timing.csv", "w", newline="") as f:
        wr = csv.writer(f, lineterminator="\n")
        wr.writerow(["K", "runs", "periods", "threads", "ladder_s"] +
                    [f"wall_per_run_{r}_s" for r in RUNGS] + [f"speedup_{f}" for f in FAMILIES])
        for res in results:
            per = {r: res[f"wall_{r}"] / args.runs for r in RUNGS}
            wr.writerow([res["k"], args.runs, args.periods, args.threads,
                         f"{res['ladder_wall']:.3f}"] + [f"{per[r]:.4g}" for r in RUNGS] +
                        [f"{per['network'] / per[f]:.3g}" for f in FAMILIES])
    with open(out / "fits.csv", "w", newline="") as f:
        wr = csv.writer(f, lineterminator="\n")
        wr.writerow(["K", "family", "link_table_n1"])
        for res in results:
            for fam in FAMILIES:
                wr.writerow([res["k"], fam, res["fits"][fam].strip().replace("\n", "; ")])


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="results/fidelity_ladder")
    p.add_argument("--work", default="out/fidelity_ladder")
    p.add_argument("--ks", default="2,4,5,6,8")
    p.add_argument("--runs", type=int, default=20)
    p.add_argument("--periods", type=int, default=1000)
    p.add_argument("--threads", type=int, default=2)
    args = p.parse_args()
    out = ROOT / args.out
    work = ROOT / args.work
    out.mkdir(parents=True, exist_ok=True)
    work.mkdir(parents=True, exist_ok=True)
    results = [one_k(int(k), args, work, out) for k in args.ks.split(",")]
    write_outputs(results, args, out)
    same = []
    for r in results:
        a = [x["mse"] for x in r["runs_network"] if x["estimator"] == "Kalman"]
        b = [x["mse"] for x in r["runs_trace"] if x["estimator"] == "Kalman"]
        same.append(f"K={r['k']}: {'identical' if a == b else 'DIFFERENT'}")
    print("Kalman per-run mse, network against the replayed traces: " + ", ".join(same),
          file=sys.stderr)


if __name__ == "__main__":
    main()
