#!/usr/bin/env python3
"""Costs of ncosim's Python package (bench/README.md, "Python").

    python3 bench/python_bench.py [--reps 7] [--threads 2]   (Debian python3 with numpy, pandas)

Prints a Markdown table of medians (time.perf_counter, wall time) and ratios. Each pair that is
compared is measured in this one process, the two sides alternated repetition by repetition:

1. the Python layer on a C++-only campaign: the flagship (scenarios/dolz2014_table2.toml,
   --runs 20, its 20 000 periods) by ncosim.run() against the executable started with subprocess,
   the same threads, no timing replay in either;
2. a Python estimator: numpy_kf (examples/python/numpy_kf.py) on the flagship's model and links,
   per period inside a campaign (wall time of a numpy_kf-only campaign minus an open_loop-only
   one, per period; and summary.csv's ns_per_period) against the same class driven directly
   (a fake model namespace, the same arrival law, on_packet/on_period/state/covariance N times);
3. reading the tables of a 10 000-run campaign: Campaign(out) and .summary, .runs, .links;
4. threads: the numpy_kf-only campaign and the flagship's estimators plus numpy_kf, at
   threads = 1 and threads = 2.
"""
import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
import types
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
FLAGSHIP = ROOT / "scenarios" / "dolz2014_table2.toml"
EXECUTABLE = ROOT / "build" / "sim" / "ncosim"
sys.path.insert(0, str(ROOT / "build" / "python"))
sys.path.insert(0, str(ROOT / "examples" / "python"))

import ncosim  # noqa: E402
import numpy_kf  # noqa: E402  (registers the kind "numpy_kf")


def median(xs):
    return statistics.median(xs)


class Dirs:
    """A fresh output folder per call, under one temporary folder."""

    def __init__(self, root):
        self.root, self.i = root, 0

    def __call__(self, tag):
        self.i += 1
        return os.path.join(self.root, f"{tag}{self.i}")


def flagship_dict(estimators=None, runs=None, periods=None):
    with open(FLAGSHIP, "rb") as f:
        d = tomllib.load(f)
    if estimators is not None:
        d["estimator"] = estimators
    if runs is not None:
        d["run"]["runs"] = runs
    if periods is not None:
        d["run"]["periods"] = periods
        d["run"]["warmup"] = min(d["run"]["warmup"], periods // 4)
    return d


NUMPY_KF = {"name": "numpy_kf", "kind": "numpy_kf", "max_delay": 1}
OPEN_LOOP = {"name": "open loop", "kind": "open_loop", "max_delay": 1, "expected_status": "diverged"}


# 1. the Python layer on a C++-only campaign

def bench_overhead(a, dirs):
    rows = []
    for threads in sorted({1, a.threads}):
        py, cli, same = [], [], True
        for _ in range(2 * a.reps):  # a short campaign: twice the repetitions
            out_py = dirs("py")
            t0 = time.perf_counter()
            ncosim.run(str(FLAGSHIP), runs=20, threads=threads, progress=False, timing=False, out=out_py)
            py.append(time.perf_counter() - t0)
            out_cli = dirs("cli")
            cmd = [str(EXECUTABLE), "run", str(FLAGSHIP), "--runs", "20", "--threads", str(threads),
                   "--no-timing", "--quiet", "--out", out_cli]
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
            cli.append(time.perf_counter() - t0)
            same &= (Path(out_py, "runs.csv").read_bytes() == Path(out_cli, "runs.csv").read_bytes())
        p, c = median(py), median(cli)
        if threads == 1:
            start = []  # what the subprocess pays and the in-process call does not
            for _ in range(2 * a.reps):
                t0 = time.perf_counter()
                subprocess.run([str(EXECUTABLE), "--version"], check=True, stdout=subprocess.DEVNULL)
                start.append(time.perf_counter() - t0)
            rows.append(("`ncosim --version` by subprocess (process start-up and exit), "
                         f"{2 * a.reps} repetitions", "–", f"{median(start) * 1e3:.1f} ms", "–"))
        rows.append((f"flagship, 20 runs x 20 000 periods, 7 C++ estimators, threads {threads}: "
                     f"`ncosim.run()` / `ncosim run` (subprocess); runs.csv "
                     f"{'byte-identical' if same else 'DIFFERENT'}; {2 * a.reps} repetitions",
                     f"{p:.3f} s", f"{c:.3f} s", f"{p / c:.3f} ({100 * (p / c - 1):+.1f} %)"))
    return rows


# 2. a Python estimator, inside ncosim and driven directly

def fake_model():
    d = flagship_dict()
    pl = d["plant"]
    A, Bw, W = (np.array(pl[k], dtype=float) for k in ("A", "Bw", "W"))
    sensors = [types.SimpleNamespace(name=s["name"], C=np.array(s["C"], dtype=float),
                                     R=np.array(s["R"], dtype=float)) for s in d["sensor"]]
    return types.SimpleNamespace(n=A.shape[0], A=A, Q=Bw @ W @ Bw.T,
                                 x0=np.zeros(A.shape[0]), sensors=sensors)


def fake_arrivals(n_periods, rng):
    """Packets per period as the flagship's links deliver them: each sample of each sensor arrives
    after 0 or 1 period with the Table 2 probabilities, lost otherwise; one sample per packet."""
    d = flagship_dict()
    links = {l["name"]: l["pmf"] for l in d["link"]}
    arrivals = [[] for _ in range(n_periods + 2)]
    for i, s in enumerate(d["sensor"]):
        p0, p1 = links[s["link"]]
        draw = rng.random(n_periods)
        values = rng.standard_normal(n_periods)
        for k in range(n_periods):
            delay = 0 if draw[k] < p0 else 1 if draw[k] < p0 + p1 else None
            if delay is not None:
                arrivals[k + delay].append(
                    types.SimpleNamespace(sensor=i, stamps=[k], values=np.array([values[k]])))
    return arrivals[:n_periods]


def standalone_per_period(n_periods, rng):
    model = fake_model()
    arrivals = fake_arrivals(n_periods, rng)
    drives = rng.standard_normal((n_periods, model.n))
    u = np.zeros(1)
    e = numpy_kf.DelayKF(model, {"max_delay": 1})
    t0 = time.perf_counter()
    for k in range(n_periods):
        for p in arrivals[k]:
            e.on_packet(p, k)
        e.on_period(k, u, drives[k])
        e.state()
        e.covariance()
    return (time.perf_counter() - t0) / n_periods


def campaign_wall(d, threads, out, timing=False):
    t0 = time.perf_counter()
    c = ncosim.run(d, threads=threads, progress=False, timing=timing, out=out)
    return time.perf_counter() - t0, c


def bench_python_estimator(a, dirs):
    rng = np.random.default_rng(1)
    runs, periods = a.kf_runs, a.kf_periods
    kf_d = flagship_dict([NUMPY_KF], runs, periods)
    ol_d = flagship_dict([OPEN_LOOP], runs, periods)
    alone, inside, base, ns = [], [], [], []
    for _ in range(a.reps):
        alone.append(standalone_per_period(a.n, rng))
        inside.append(campaign_wall(kf_d, 1, dirs("kf"))[0])
        base.append(campaign_wall(ol_d, 1, dirs("ol"))[0])
        _, c = campaign_wall(kf_d, 1, dirs("kft"), timing=True)
        ns.append(float(c.summary["ns_per_period"].iloc[0]))
    s = median(alone)
    w = (median(inside) - median(base)) / (runs * periods)
    t = median(ns) * 1e-9
    return [
        (f"numpy_kf per period (A3, Table 2 links, max_delay 1): inside a campaign, wall of a "
         f"numpy_kf-only campaign minus an open_loop-only one ({runs} x {periods} periods, threads 1) "
         f"/ the class driven directly (N = {a.n})",
         f"{w * 1e6:.2f} µs", f"{s * 1e6:.2f} µs", f"{w / s:.3f}"),
        ("numpy_kf per period: inside, `ns_per_period` of summary.csv / driven directly",
         f"{t * 1e6:.2f} µs", f"{s * 1e6:.2f} µs", f"{t / s:.3f}"),
    ]


# 3. the tables of a 10 000-run campaign

def tiny_scenario(runs):
    return {
        "title": "tiny",
        "run": {"periods": 10, "runs": runs, "seed": 1, "period": 1.0},
        "plant": {"kind": "lti", "A": [[0.9]], "Bu": [[1.0]], "Bw": [[1.0]], "W": [[0.1]]},
        "input": {"kind": "white", "std": 1.0},
        "sensor": [{"name": "y", "C": [[1.0]], "R": [[0.05]], "link": "l"}],
        "link": [{"name": "l", "kind": "bernoulli", "loss": 0.3}],
        "estimator": [{"name": "kalman", "kind": "kalman_extended"},
                      {"name": "open loop", "kind": "open_loop"}],
    }


def bench_tables(a, dirs):
    out = dirs("tables")
    t0 = time.perf_counter()
    ncosim.run(tiny_scenario(a.table_runs), progress=False, timing=False, out=out, threads=a.threads)
    t_run = time.perf_counter() - t0
    times, shape = [], None
    for _ in range(a.reps):
        t0 = time.perf_counter()
        c = ncosim.Campaign(out)
        c.summary
        c.runs
        c.links
        times.append(time.perf_counter() - t0)
        shape = (len(c.summary), len(c.runs), len(c.links))
    return [(f"`Campaign(out)` + `.summary`, `.runs`, `.links` of a {a.table_runs}-run campaign "
             f"({shape[1]} rows in runs.csv; the campaign itself, 10 periods per run: {t_run:.2f} s)",
             f"{median(times) * 1e3:.1f} ms", "–", "–")]


# 4. threads

def bench_threads(a, dirs):
    runs, periods = a.thread_runs, a.kf_periods
    flagship = flagship_dict()["estimator"]
    cases = [("numpy_kf only", flagship_dict([NUMPY_KF], runs, periods)),
             ("flagship's 7 estimators + numpy_kf", flagship_dict(flagship + [NUMPY_KF], runs, periods))]
    rows = []
    for name, d in cases:
        t1, t2 = [], []
        for _ in range(a.reps):
            t1.append(campaign_wall(d, 1, dirs("t1"))[0])
            t2.append(campaign_wall(d, 2, dirs("t2"))[0])
        rows.append((f"{name}, {runs} x {periods} periods: threads 2 / threads 1",
                     f"{median(t2):.3f} s", f"{median(t1):.3f} s", f"{median(t2) / median(t1):.3f}"))
    return rows


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--reps", type=int, default=7, help="repetitions per measurement (median; >= 5)")
    p.add_argument("--threads", type=int, default=2,
                   help="threads of measurement 1 (both sides; threads 1 is measured too)")
    p.add_argument("--n", type=int, default=20000, help="periods of the directly driven numpy_kf")
    p.add_argument("--kf-runs", type=int, default=4, help="runs of the numpy_kf campaigns of 2")
    p.add_argument("--kf-periods", type=int, default=5000, help="periods of the campaigns of 2 and 4")
    p.add_argument("--thread-runs", type=int, default=8, help="runs of the campaigns of 4")
    p.add_argument("--table-runs", type=int, default=10000, help="runs of the campaign of 3")
    p.add_argument("--only", default="1234", help="which measurements, e.g. 13")
    a = p.parse_args()
    if not EXECUTABLE.exists():
        sys.exit(f"{EXECUTABLE} is missing: build the tree first")
    load0, start = os.getloadavg()[0], time.perf_counter()
    tmp = tempfile.mkdtemp(prefix="ncosim-pybench-")
    rows = []
    try:
        dirs = Dirs(tmp)
        for key, f in (("1", bench_overhead), ("2", bench_python_estimator), ("3", bench_tables),
                       ("4", bench_threads)):
            if key in a.only:
                rows += f(a, dirs)
    finally:
        shutil.rmtree(tmp, True)
    print(f"medians of {a.reps} repetitions (wall time); load average {load0:.2f} at the start, "
          f"{os.getloadavg()[0]:.2f} at the end; {time.perf_counter() - start:.0f} s in all\n")
    print("| measurement | A | B | A / B |")
    print("|---|---|---|---|")
    for r in rows:
        print("| " + " | ".join(r) + " |")


if __name__ == "__main__":
    main()
