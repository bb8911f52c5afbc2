"""ncosim.run, check, compare, fit and kinds against the command line."""
import os
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import ncosim
from ncosim import _toml
from conftest import executable

COMPARED = ("runs.csv", "summary.csv", "links.csv", "transmissions.csv")


def cli(*args, check=True):
    return subprocess.run([executable(), *map(str, args)], capture_output=True, text=True,
                          check=check)


def same_files(a, b):
    for name in COMPARED:
        pa, pb = Path(a) / name, Path(b) / name
        assert pa.exists() == pb.exists(), name
        if pa.exists():
            assert pa.read_bytes() == pb.read_bytes(), f"{name} differs between {a} and {b}"


def test_file_string_and_dict_give_the_command_lines_bytes(motor, tmp_path):
    path = tmp_path / "motor.toml"
    path.write_text(_toml.dumps(motor))
    cli("run", path, "--out", "cli", "--no-timing", "--quiet", "--threads", 2)
    from_file = ncosim.run(path, out="py_file", timing=False, progress=False, threads=2)
    from_text = ncosim.run(path.read_text(), out="py_text", timing=False, progress=False)
    from_dict = ncosim.run(motor, out="py_dict", timing=False, progress=False)
    for c in (from_file, from_text, from_dict):
        same_files("cli", c.out)
    # The DataFrames are the CSVs.
    pd.testing.assert_frame_equal(from_dict.runs, pd.read_csv("cli/runs.csv"))
    assert list(from_dict.summary.columns) == list(pd.read_csv("cli/summary.csv").columns)
    assert from_dict.design["estimators"][0]["name"] == "KF"
    assert from_dict.manifest["scenario"] == "<dict>"
    assert from_text.manifest["scenario"] == "<string>"


def test_overrides_mean_what_they_mean_on_the_command_line(motor, tmp_path):
    path = tmp_path / "motor.toml"
    path.write_text(_toml.dumps(motor))
    cli("run", path, "--out", "cli", "--no-timing", "--quiet", "--runs", 3, "--periods", 700,
        "--seed", 5, "--set", 'link[0].pmf=[0.9]', "--set", "estimator[0].max_delay=0")
    c = ncosim.run(motor, runs=3, periods=700, seed=5, set={"link[0].pmf": [0.9],
                   "estimator[0].max_delay": 0}, out="py", timing=False, progress=False)
    same_files("cli", c.out)
    assert len(c.runs) == 3


def test_a_temporary_folder_lives_as_long_as_its_campaign(motor):
    c = ncosim.run(motor, progress=False)
    out = c.out
    assert (out / "runs.csv").exists()
    del c
    import gc
    gc.collect()
    assert not out.exists()


def test_bad_input_raises_with_its_location_and_writes_nothing(motor, tmp_path):
    bad = dict(motor, link=[{"name": "net", "kind": "delay", "pmf": [1.5]}, motor["link"][1]])
    with pytest.raises(ncosim.ScenarioError, match=r"^<dict>: key 'link\[0\]\.pmf': "):
        ncosim.run(bad, out="nothing", progress=False)
    assert not Path("nothing").exists()
    path = tmp_path / "bad.toml"
    path.write_text(_toml.dumps(bad))
    line = next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if "1.5" in ln)
    with pytest.raises(ValueError, match=rf"bad\.toml:{line}: key 'link\[0\]\.pmf': "):
        ncosim.run(path, out="nothing", progress=False)
    # The same text as the command line's.
    r = cli("run", path, "--out", "nothing", check=False)
    assert r.returncode == 2
    with pytest.raises(ncosim.ScenarioError) as e:
        ncosim.check(path)
    assert r.stderr.strip() == "ncosim: " + str(e.value)
    with pytest.raises(ncosim.ScenarioError, match=r"--set"):
        ncosim.run(motor, set={"run.warmup": 2.5}, progress=False)
    with pytest.raises(ncosim.ScenarioError, match="unknown key|did you mean"):
        ncosim.check(dict(motor, runn={"runs": 3}))
    with pytest.raises(TypeError):
        ncosim.run(42)
    with pytest.raises(ncosim.ScenarioError, match="cannot open the scenario file"):
        ncosim.check("no_such=file.toml")  # a path, though it holds an "="
    with pytest.raises(ncosim.ScenarioError, match="not valid Unicode"):
        ncosim.check(dict(motor, title="\ud800"))
    assert not Path("nothing").exists()


def test_seeds_outside_0_to_2_63_are_refused_not_clamped(motor):
    """Issue 40 part 7: seed=2**64 ran as 2**63 - 1 (two requests, one campaign)."""
    for seed in (2**64, 2**63, -1):
        with pytest.raises(ncosim.ScenarioError, match=r"--seed: expected an integer in 0 \.\. "
                                                       r"9223372036854775807 \(2\^63 - 1\)"):
            ncosim.run(motor, seed=seed, out="nothing", progress=False)
        with pytest.raises(ncosim.ScenarioError, match=r"--seed: expected an integer in 0"):
            ncosim.check(motor, seed=seed)
    for seed in (1.5, "3", True):
        with pytest.raises(ncosim.ScenarioError, match=r"^seed: expected an integer, got "):
            ncosim.run(motor, seed=seed, out="nothing", progress=False)
    with pytest.raises(ncosim.ScenarioError, match=r"run\.seed: expected an integer TOML can hold"):
        ncosim.run(motor, set={"run.seed": 2**64}, out="nothing", progress=False)
    with pytest.raises(ncosim.ScenarioError, match=r"run\.seed: expected an integer TOML can hold"):
        ncosim.run(dict(motor, run=dict(motor["run"], seed=2**64)), out="nothing", progress=False)
    assert not Path("nothing").exists()
    a = ncosim.run(motor, seed=2**63 - 1, runs=2, timing=False, progress=False)
    b = ncosim.run(motor, seed=np.int64(2**63 - 1), runs=2, timing=False, progress=False)
    assert (a.out / "runs.csv").read_bytes() == (b.out / "runs.csv").read_bytes()


def test_check(motor):
    assert ncosim.check(motor) == {"cases": 1, "estimators": 1}
    assert ncosim.check(motor, runs=3, periods=500, seed=4) == {"cases": 1, "estimators": 1}
    swept = dict(motor, sweep=[{"key": "link[1].loss", "values": [0.1, 0.2, 0.3]}])
    assert ncosim.check(swept)["cases"] == 3


def test_kinds():
    k = ncosim.kinds()
    assert {"section", "kind", "help", "keys"} <= set(k.columns)
    assert ("estimator", "kalman_extended") in set(zip(k.section, k.kind))
    assert ("link", "gilbert_elliott") in set(zip(k.section, k.kind))
    keys = ncosim.kinds("estimator", keys=True)
    row = keys[(keys.kind == "kalman_extended") & (keys.key == "max_delay")].iloc[0]
    assert row.type == "integer" and row.default == "0" and row.range == "0..62"
    # The same kinds as `ncosim list` (which knows none registered from Python).
    listed = cli("list").stdout
    python_kinds = set(ncosim.registered())
    for kind in k[k.section == "estimator"].kind:
        assert (f"  {kind} " in listed) != (kind in python_kinds), kind


def test_compare_finds_a_regression_and_no_change(motor):
    base = ncosim.run(motor, runs=12, progress=False)
    same = ncosim.run(motor, runs=12, progress=False)
    worse = ncosim.run(motor, runs=12, set={"estimator[0].max_delay": 0}, progress=False,
                       )
    c = ncosim.compare(base, same)
    assert not c.regression and c.verdict == "no regression"
    assert c.table.loc[0, "verdict"] == "unchanged"
    r = ncosim.compare(base, worse.out, allow_scenario_change=True)
    assert r.regression
    assert r.table.loc[0, "verdict"] == "worse"
    assert "worse" in r.markdown
    # 2 runs a side cannot show anything: inconclusive (exit 4), passed when allowed.
    few = ncosim.compare(ncosim.run(motor, runs=2, progress=False),
                         ncosim.run(motor, runs=2, progress=False))
    assert few.inconclusive and not few.regression and few.verdict == "inconclusive"
    assert set(few.table["verdict"]) == {"inconclusive"}
    assert few.table.loc[0, "ci_level"] == pytest.approx(0.9)
    with pytest.raises(ncosim.ScenarioError):
        ncosim.compare(base, worse)  # another scenario text without allow_scenario_change
    with pytest.raises(ValueError):
        ncosim.compare(base, "no/such/folder")


def test_fit_recovers_a_loss_rate():
    rng = np.random.default_rng(3)
    lost = rng.random(20000) < 0.2
    trace = pd.DataFrame({"seq": np.arange(lost.size), "delay": np.where(lost, np.nan, 0)})
    f = ncosim.fit(trace, family="bernoulli", name="synthetic")
    assert "[[link]]" in f.link and 'name = "synthetic"' in f.link
    row = f.families.iloc[0]
    assert row["family"] == "bernoulli"
    assert "loss" in f.link
    p = float(f.link.split("loss = ")[1].split()[0])
    assert abs(p - lost.mean()) < 1e-3


def test_progress_follows_the_runs_and_does_not_change_results(motor, monkeypatch):
    pytest.importorskip("tqdm")
    calls = []
    original = ncosim._api._Progress.__call__

    def record(self, done, total, final):
        calls.append((done, total, final))
        original(self, done, total, final)

    monkeypatch.setattr(ncosim._api._Progress, "__call__", record)
    motor["run"].update(runs=40, periods=40000)  # about a second: the bar is redrawn meanwhile
    a = ncosim.run(motor, progress=True, timing=False, threads=1)
    assert calls[-1] == (40, 40, True)
    assert any(not final and 0 < done < 40 for done, _, final in calls), calls
    assert [d for d, _, _ in calls] == sorted(d for d, _, _ in calls)
    b = ncosim.run(motor, progress=False, timing=False, threads=1)
    same_files(a.out, b.out)


def test_toml_writer_round_trips():
    import tomllib
    doc = {"a": 1, "b": 2.5, "s": 'quote " and \\ and é \x7f', "m": np.eye(2), "t": {"x": True},
           "arr": [{"k": 1}, {"k": 2}], "inl": [{"k": 1}, 3], "weird key": np.float64(1.5),
           "inf": float("inf")}
    back = tomllib.loads(_toml.dumps(doc))
    assert back["m"] == [[1.0, 0.0], [0.0, 1.0]] and back["s"] == doc["s"]
    assert back["arr"] == [{"k": 1}, {"k": 2}] and back["inl"] == [{"k": 1}, 3]
    assert back["weird key"] == 1.5 and back["inf"] == float("inf") and back["t"] == {"x": True}
    with pytest.raises(TypeError, match="None"):
        _toml.dumps({"a": None})
    tricky = {"a\n": 1, "a\x7fb": 2, "": 3, "x.y": {"": [{"q": -0.0}]}, "t": {}, "e": [{}]}
    assert tomllib.loads(_toml.dumps(tricky)) == tricky
