#!/usr/bin/env python3
"""The fidelity ladder: is a fitted statistical link a fair stand-in for a packet-level network?

An IEEE 802.15.4 star (ns-3's lr-wpan) of K sensor nodes on a ring of radius 20 m around the
estimators' node, every node sending one sample every 20 ms, for growing K. Per K:

  1. ns3        the campaign on the network: the K nodes contend (CSMA/CA, collisions,
                retransmissions, drops), so a period's losses are correlated across the sensors;
  2. record     every link's trace (`ncosim record-link`), run after run;
  3. fit        the K traces together (the nodes are statistically alike): a Gilbert-Elliott
                link (hidden two-state chain per packet, delays independent of the state; a
                `markov` link when delays vary) and the `delay` family (independent packets);
  4. ge, indep, bern  the same scenario, seed and estimators with every link replaced by an
                independent copy of a fitted link: Gilbert-Elliott (losses in bursts), `delay`
                (independent packets with the trace's delay law and loss), Bernoulli (the trace's
                loss, every packet with the most common delay);
  5. trace      every link replaced by its own recorded trace, run r replaying run r: the check
                that the record is the campaign's channel (a `kalman_extended` run's MSE equals
                the ns3 one's) and that the cross-sensor correlation of the losses is what the
                surrogates lose;

then `ncosim compare ns3 <variant>` (same seed: run r of both draws the same plant and
measurement noise; paired differences with Student-t CIs). Writes OUT/table.csv, table.md,
fits.csv, timing.csv and the campaigns' summary_<variant>_K<k>.csv; the generated scenarios,
traces, fits and campaigns stay in WORK. Long: not part of the test suite.

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
VARIANTS = ("ns3", "trace", "ge", "indep", "bern")


def ncosim(*args, quiet=True):
    cmd = [str(BIN), *map(str, args)]
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if r.returncode not in (0, 1) or (r.returncode == 1 and args[0] != "compare"):
        sys.exit(f"fidelity_ladder: {' '.join(cmd)} failed ({r.returncode}):\n{r.stderr}")
    return r.stdout


def head(k, periods, runs):
    lines = [
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
    ]
    return "\n".join(lines)


def sensors(k):
    out = []
    for i in range(k):
        c = "[[1.0, 0.0]]" if i % 2 == 0 else "[[0.0, 1.0]]"
        what = "position" if i % 2 == 0 else "speed"
        out.append(f'[[sensor]]\nname = "{what} {i + 1}"\nC = {c}\nR = [[1.0]]\nlink = "n{i + 1}"\n')
    return "\n".join(out)


def network_links(k, design_pmf):
    out = ['[[network]]\nname = "wsn"\nkind = "lr_wpan"\ntx_power = 0.0\n']
    for i in range(k):
        a = 2.0 * math.pi * i / k
        x, y = RADIUS * math.cos(a), RADIUS * math.sin(a)
        pmf = "" if design_pmf is None else f"design_pmf = {toml_list(design_pmf)}\n"
        out.append(
            f'[[link]]\nname = "n{i + 1}"\nkind = "network"\nnetwork = "wsn"\nbytes = {BYTES}\n'
            f"position = [{x:.6f}, {y:.6f}, 0.0]\n{pmf}"
        )
    return "\n".join(out)


def toml_list(xs):
    return "[" + ", ".join(f"{x:.17g}" for x in xs) + "]"


def surrogate_links(k, table):
    """`table`: the body of a fitted [[link]] table (fit's link.toml without its name)."""
    return "\n".join(f'[[link]]\nname = "n{i + 1}"\n{table}' for i in range(k))


def trace_links(k, files, segment):
    return "\n".join(
        f'[[link]]\nname = "n{i + 1}"\nkind = "trace"\nfile = "{files[i]}"\nsegment = {segment}\n'
        for i in range(k)
    )


def read_trace(path):
    with open(path, newline="") as f:
        return [row["delay"] for row in csv.DictReader(f)]


def fitted_table(fit_dir):
    """The [[link]] table of link.toml without its header and name (one per sensor later)."""
    text = (fit_dir / "link.toml").read_text().splitlines()
    body = [ln for ln in text if ln.strip() and not ln.startswith("[[link]]")
            and not ln.startswith("name") and not ln.startswith("#")]
    return "\n".join(body) + "\n"


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
                runs_sum += open_run; runs_n += 1; open_run = 0
            if x:
                open_run += 1
            elif open_run:
                runs_sum += open_run; runs_n += 1; open_run = 0
        if open_run:
            runs_sum += open_run; runs_n += 1
    means = [sum(li) / m for li in lost]
    corr_sum = pairs = 0
    all_lost = 0
    for j in range(m):
        all_lost += all(li[j] for li in lost)
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


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def run_campaign(scenario, out, threads):
    start = time.monotonic()
    ncosim("run", scenario, "--out", out, "--quiet", "--no-timing", "--replace", "--threads", threads)
    wall = time.monotonic() - start
    manifest = json.loads((out / "manifest.json").read_text())
    return wall, manifest


def one_k(k, args, work, out):
    w = work / f"K{k}"
    if w.exists():
        shutil.rmtree(w)
    w.mkdir(parents=True)
    h = head(k, args.periods, args.runs)
    print(f"K = {k}: record", file=sys.stderr)
    record_sc = w / "record.toml"
    record_sc.write_text(h + network_links(k, None) + "\n" + sensors(k) +
                         '\n[[estimator]]\nname = "Kalman"\nkind = "kalman_extended"\nmax_delay = 3\n')
    files, traces = [], []
    rec_start = time.monotonic()
    for i in range(k):
        rd = w / f"record_n{i + 1}"
        ncosim("record-link", record_sc, "--link", f"n{i + 1}", "--out", rd, "--quiet")
        files.append(str(rd / f"n{i + 1}.csv"))
        traces.append(read_trace(files[-1]))
    rec_wall = time.monotonic() - rec_start
    st = trace_stats(traces, args.periods, WARMUP)
    print(f"K = {k}: fit (loss {st['loss']:.4f}, correlation {st['loss_corr']:.3f})", file=sys.stderr)
    # The traces of all K links one after the other (the scored periods only): one fit for all.
    joined = w / "joined.csv"
    with open(joined, "w") as f:
        f.write("seq,delay\n")
        n = 0
        for t in traces:
            for j, d in enumerate(t):
                if j % args.periods >= WARMUP:
                    f.write(f"{n},{d}\n")
                    n += 1
    fits = {}
    for fam, key in (("gilbert_elliott", "ge"), ("delay", "indep")):
        fd = w / f"fit_{key}"
        ncosim("fit", joined, "--family", fam, "--out", fd, "--name", "fitted")
        fits[key] = fitted_table(fd)
    # Bernoulli: the trace's loss, every delivered packet with the most common delay.
    mode = max(range(len(st["pmf"])), key=lambda d: st["pmf"][d])
    fits["bern"] = f'kind = "bernoulli"\nloss = {st["loss"]:.17g}\ndelay = {mode}\n'

    fit_rows = read_csv(w / "fit_ge" / "fit.csv")
    sc_text = {
        "ns3": h + network_links(k, st["pmf"]) + "\n" + sensors(k) + ESTIMATORS,
        "trace": h + trace_links(k, files, args.periods) + "\n" + sensors(k) + ESTIMATORS,
        "ge": h + surrogate_links(k, fits["ge"]) + "\n" + sensors(k) + ESTIMATORS,
        "indep": h + surrogate_links(k, fits["indep"]) + "\n" + sensors(k) + ESTIMATORS,
        "bern": h + surrogate_links(k, fits["bern"]) + "\n" + sensors(k) + ESTIMATORS,
    }
    res = {"k": k, "stats": st, "fits": fits, "fit_rows": fit_rows, "record_wall": rec_wall}
    for v in VARIANTS:
        print(f"K = {k}: campaign {v}", file=sys.stderr)
        (w / f"{v}.toml").write_text(sc_text[v])
        wall, _ = run_campaign(w / f"{v}.toml", w / v, args.threads)
        res[f"wall_{v}"] = wall
        res[f"summary_{v}"] = read_csv(w / v / "summary.csv")
        res[f"runs_{v}"] = read_csv(w / v / "runs.csv")
        shutil.copy(w / v / "summary.csv", out / f"summary_{v}_K{k}.csv")
        if v != "ns3":
            ncosim("compare", w / "ns3", w / v, "--out", w / f"compare_{v}", "--allow-scenario-change")
            res[f"compare_{v}"] = read_csv(w / f"compare_{v}" / "compare.csv")
    return res


def fmt(x, digits=4):
    if x is None or x == "":
        return ""
    x = float(x)
    return f"{x:.{digits}g}"


def write_outputs(results, args, out):
    header = ["K", "estimator", "loss", "mean_delay", "loss_run_mean", "loss_corr", "all_lost",
              "all_lost_independent"]
    for v in VARIANTS:
        header += [f"mse_{v}", f"mse_{v}_ci95"]
    for v in VARIANTS[1:]:
        header += [f"diff_{v}", f"diff_{v}_ci_low", f"diff_{v}_ci_high", f"verdict_{v}"]
    rows = []
    for r in results:
        st = r["stats"]
        for i, s in enumerate(r["summary_ns3"]):
            e = s["estimator"]
            row = {"K": r["k"], "estimator": e, "loss": st["loss"], "mean_delay": st["mean_delay"],
                   "loss_run_mean": st["loss_run_mean"], "loss_corr": st["loss_corr"],
                   "all_lost": st["all_lost"], "all_lost_independent": st["all_lost_independent"]}
            for v in VARIANTS:
                sv = next(x for x in r[f"summary_{v}"] if x["estimator"] == e)
                row[f"mse_{v}"] = sv["mse"]
                row[f"mse_{v}_ci95"] = sv["mse_ci95"]
            for v in VARIANTS[1:]:
                c = next(x for x in r[f"compare_{v}"] if x["estimator"] == e and x["metric"] == "mse")
                row[f"diff_{v}"] = c["diff"]
                row[f"diff_{v}_ci_low"] = c["diff_ci_low"]
                row[f"diff_{v}_ci_high"] = c["diff_ci_high"]
                row[f"verdict_{v}"] = c["verdict"]
            rows.append(row)
    with open(out / "table.csv", "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
        wr.writeheader()
        for row in rows:
            wr.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})
    with open(out / "table.md", "w") as f:
        f.write("| K | estimator | loss | corr. | P(all lost) / indep. | mse ns-3 | mse trace | "
                "mse GE | mse indep. | mse Bernoulli | GE − ns-3 (95 % CI) | "
                "indep. − ns-3 (95 % CI) | Bernoulli − ns-3 (95 % CI) |\n")
        f.write("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n")
        for row in rows:
            def ci(v):
                return (f"{fmt(row[f'diff_{v}'])} [{fmt(row[f'diff_{v}_ci_low'])}, "
                        f"{fmt(row[f'diff_{v}_ci_high'])}] {row[f'verdict_{v}']}")
            mses = " | ".join(f"{fmt(row[f'mse_{v}'])} ± {fmt(row[f'mse_{v}_ci95'], 2)}"
                              for v in VARIANTS)
            f.write(f"| {row['K']} | {row['estimator']} | {fmt(row['loss'])} | "
                    f"{fmt(row['loss_corr'], 3)} | {fmt(row['all_lost'], 3)} / "
                    f"{fmt(row['all_lost_independent'], 3)} | {mses} | {ci('ge')} | {ci('indep')} | "
                    f"{ci('bern')} |\n")
    with open(out / "timing.csv", "w", newline="") as f:
        wr = csv.writer(f, lineterminator="\n")
        wr.writerow(["K", "runs", "periods", "threads", "record_s"] +
                    [f"wall_per_run_{v}_s" for v in VARIANTS] +
                    ["speedup_ge", "speedup_indep", "speedup_bern"])
        for r in results:
            per = {v: r[f"wall_{v}"] / args.runs for v in VARIANTS}
            wr.writerow([r["k"], args.runs, args.periods, args.threads, f"{r['record_wall']:.3f}"] +
                        [f"{per[v]:.4g}" for v in VARIANTS] +
                        [f"{per['ns3'] / per[v]:.3g}" for v in ("ge", "indep", "bern")])
    with open(out / "fits.csv", "w", newline="") as f:
        wr = csv.writer(f, lineterminator="\n")
        wr.writerow(["K", "family", "link_table"])
        for r in results:
            for fam in ("ge", "indep", "bern"):
                wr.writerow([r["k"], fam, r["fits"][fam].strip().replace("\n", "; ")])


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
    results = [one_k(int(k), args, work, out) for k in args.ks.split(",")]
    write_outputs(results, args, out)
    same = []
    for r in results:
        a = [x["mse"] for x in r["runs_ns3"] if x["estimator"] == "Kalman"]
        b = [x["mse"] for x in r["runs_trace"] if x["estimator"] == "Kalman"]
        same.append(f"K={r['k']}: {'identical' if a == b else 'DIFFERENT'}")
    print("Kalman per-run mse, ns3 against the replayed traces: " + ", ".join(same), file=sys.stderr)


if __name__ == "__main__":
    main()
