"""Estimators written in Python, in the same campaign as the C++ ones."""
import re

import numpy as np
import pytest

import ncosim
import numpy_kf  # examples/python/numpy_kf.py: registers "numpy_kf"


def with_estimators(motor, *extra):
    return dict(motor, estimator=motor["estimator"] + list(extra))


def test_numpy_kalman_filter_matches_kalman_extended(motor):
    """The check that the interface is right: the same per-run MSE, to rounding."""
    sc = with_estimators(motor, {"name": "numpy", "kind": "numpy_kf", "max_delay": 3})
    sc["run"]["runs"] = 6
    c = ncosim.run(sc, progress=False)
    mse = c.runs.pivot(index="run", columns="estimator", values="mse")
    assert len(mse) == 6
    np.testing.assert_allclose(mse["numpy"], mse["KF"], rtol=1e-9, atol=0)
    ext = c.runs.pivot(index="run", columns="estimator", values="rmse_x2")
    np.testing.assert_allclose(ext["numpy"], ext["KF"], rtol=1e-9, atol=0)
    s = c.summary.set_index("estimator")
    assert s.loc["numpy", "status"] == "ok" and s.loc["numpy", "kind"] == "numpy_kf"
    assert s.loc["numpy", "flops_per_period"] == 2 * 8**3  # the class's own count
    # Its covariance() feeds the consistency columns as the C++ filter's own P does.
    assert s.loc["numpy", "nees"] == pytest.approx(s.loc["KF", "nees"], rel=1e-9)
    # Paired columns: the Kalman filter is the reference, the difference is zero.
    assert s.loc["numpy", "mse_diff"] == pytest.approx(0.0, abs=1e-9)
    assert c.design["estimators"][1]["method"] == "python"


def test_threads_do_not_change_results(motor):
    sc = with_estimators(motor, {"name": "numpy", "kind": "numpy_kf", "max_delay": 3})
    a = ncosim.run(sc, threads=1, progress=False, timing=False)
    b = ncosim.run(sc, threads=2, progress=False, timing=False)
    assert (a.out / "runs.csv").read_bytes() == (b.out / "runs.csv").read_bytes()


class Raising(ncosim.Estimator):
    """raises ZeroDivisionError at period 40 of every run"""

    def on_period(self, k, u, drive):
        if k == 40:
            1 / 0

    def state(self):
        return self.model.x0


class WrongSize(Raising):
    def on_period(self, k, u, drive):
        pass

    def state(self):
        return np.zeros(3)


class BadParams(Raising):
    def __init__(self, model, params):
        super().__init__(model, params)
        if params.get("gain", 1.0) <= 0:
            raise ValueError(f"gain: expected a positive number, got {params['gain']}")


def test_an_estimator_that_raises_gets_a_status_and_the_campaign_goes_on(motor):
    ncosim.register("raising", Raising)
    ncosim.register("wrong_size", WrongSize)
    sc = with_estimators(motor, {"name": "r", "kind": "raising"}, {"name": "w", "kind": "wrong_size"})
    c = ncosim.run(sc, progress=False)
    runs = c.runs.set_index(["estimator", "run"])
    assert (runs.loc["KF", "status"] == "ok").all()
    status = runs.loc["r", "status"]
    assert len(status) == 4
    assert status.str.startswith("python_error: ZeroDivisionError: division by zero (in on_period at k = 40)").all()
    assert runs.loc["w", "status"].str.contains(
        r"expected a vector of 2 real numbers, got an array of float64, shape \(3,\) \(in state").all()
    s = c.summary.set_index("estimator")
    assert s.loc["KF", "status"] == "ok"
    assert s.loc["r", "status"].startswith("python_error: ZeroDivisionError")


class BrokenHook(Raising):
    """its on_packet cannot even be looked up"""

    @property
    def on_packet(self):
        raise AttributeError("no on_packet today")


class CountsTooMany(Raising):
    def on_packet(self, packet, k):
        return packet.count + 1

    def on_period(self, k, u, drive):
        pass


class RegistersInAHook(Raising):
    def on_period(self, k, u, drive):
        ncosim.register("too_late", Raising)


def test_broken_hooks_end_the_run_not_the_campaign(motor):
    """A hook that cannot be looked up (the instance is refused: its run ends there, nothing
    waits for the GIL), a sample count out of range, a registration from inside a campaign."""
    ncosim.register("broken_hook", BrokenHook)
    ncosim.register("counts_too_many", CountsTooMany)
    ncosim.register("registers_in_a_hook", RegistersInAHook)
    sc = with_estimators(motor, {"name": "b", "kind": "broken_hook"},
                         {"name": "c", "kind": "counts_too_many"},
                         {"name": "r", "kind": "registers_in_a_hook"})
    for threads in (1, 2):
        runs = ncosim.run(sc, threads=threads, progress=False).runs.set_index(["estimator", "run"])
        assert (runs.loc["KF", "status"] == "ok").all()
        assert runs.loc["b", "status"].str.contains("no on_packet today").all()
        assert runs.loc["c", "status"].str.contains(r"samples used, 0\.\.1, got int 2").all()
        assert runs.loc["r", "status"].str.contains("a command is running").all()
    assert "too_late" not in ncosim.registered()


class ReturnsRight(Raising):
    def on_period(self, k, u, drive):
        pass


def returning(hook, value):
    """A class whose `hook` returns `value` (state, covariance or mode)."""
    return type(f"Returns_{hook}", (ReturnsRight,), {hook: lambda self: value})


# (hook, returned value, what the status must say)
BAD_VALUES = [
    ("covariance", np.eye(3), r"expected None or a 2 x 2 matrix of real numbers, got an array of "
                              r"float64, shape \(3, 3\) \(in covariance at k = 0\)"),
    ("covariance", np.eye(1), r"2 x 2 matrix .*shape \(1, 1\) \(in covariance at k = 0\)"),
    ("covariance", np.ones(4), r"2 x 2 matrix .*shape \(4,\) \(in covariance at k = 0\)"),
    ("covariance", np.eye(2) * (1 + 1j), r"got an array of complex128.* \(in covariance at k = 0\)"),
    ("mode", "one", r"expected None or a mode, an integer from 0, got str 'one' \(in mode at k = 0\)"),
    ("mode", 1.5, r"got float 1\.5 \(in mode at k = 0\)"),
    ("mode", -1, r"got int -1 \(in mode at k = 0\)"),
    ("state", np.array(["1", "2"]), r"expected a vector of 2 real numbers, got an array of <U1, "
                                    r"shape \(2,\) \(in state at k = 0\)"),
    ("state", ["1", "2"], r"got list \['1', '2'\] \(in state at k = 0\)"),
    ("state", np.array([1 + 1j, 2]), r"got an array of complex128, shape \(2,\) \(in state"),
    ("state", "12", r"got str '12' \(in state at k = 0\)"),
    ("state", 1.0, r"got float 1\.0 \(in state at k = 0\)"),
]


def test_a_value_of_the_wrong_type_or_shape_is_a_python_error_naming_its_hook(motor):
    """Issue 40 part 7: a covariance() of the wrong shape was cut to its top-left block or gave
    NaN with status ok; a bad mode() or covariance() was reported "in state", with pybind11's
    PYBIND11_DETAILED_ERROR_MESSAGES hint; complex and string arrays were taken as numbers."""
    extra = []
    for i, (hook, value, _) in enumerate(BAD_VALUES):
        ncosim.register(f"bad_value_{i}", returning(hook, value))
        extra.append({"name": f"b{i}", "kind": f"bad_value_{i}"})
    ncosim.register("good_values", returning("mode", np.int64(1)))
    sc = with_estimators(motor, *extra, {"name": "good", "kind": "good_values"})
    sc["run"].update(runs=2, periods=100)
    runs = ncosim.run(sc, progress=False).runs.set_index(["estimator", "run"])
    for i, (hook, value, expected) in enumerate(BAD_VALUES):
        status = runs.loc[f"b{i}", "status"]
        assert status.str.startswith("python_error: expected ").all(), status.iloc[0]
        assert status.str.contains(expected).all(), (hook, value, status.iloc[0])
        assert not status.str.contains("PYBIND11|Unable to cast").any(), status.iloc[0]
    assert (runs.loc["good", "status"] == "ok").all()


class LongMessage(ReturnsRight):
    def on_period(self, k, u, drive):
        raise ValueError("\x1b[31mred\x07" + "é" * 50_000)


def test_a_long_exception_text_is_capped_and_escaped_in_the_status(motor):
    """A 100 KB message with raw escape bytes was stored whole in every run's status."""
    ncosim.register("long_message", LongMessage)
    sc = with_estimators(motor, {"name": "l", "kind": "long_message"})
    sc["run"].update(runs=2, periods=50)
    c = ncosim.run(sc, progress=False)
    for status in c.runs.set_index("estimator").loc["l", "status"]:
        assert status.startswith(r"python_error: ValueError: \x1b[31mred\x07éé")
        assert "\x1b" not in status and "\x07" not in status
        assert len(status.encode()) < 600
        assert re.search(r"é\.\.\. \(\d+ more bytes\) \(in on_period at k = 0\)$", status), status
    assert "\x1b" not in c.summary.set_index("estimator").loc["l", "status"]


@pytest.mark.parametrize("flops", [-1, float("nan"), float("inf"), "100", 1 + 2j, True])
def test_flops_must_be_a_finite_non_negative_number(motor, flops):
    cls = type("Flops", (ReturnsRight,), {"flops": flops})
    ncosim.register("flops_check", cls)
    with pytest.raises(ncosim.ScenarioError, match=r"flops: expected None or a finite number >= 0 "
                                                   r"\(FLOPs per period\), got "):
        ncosim.check(with_estimators(motor, {"name": "f", "kind": "flops_check"}))
    ncosim.register("flops_check", type("Flops", (ReturnsRight,), {"flops": np.float64(12.5)}))
    assert ncosim.check(with_estimators(motor, {"name": "f", "kind": "flops_check"}))


class RunsInAHook(ReturnsRight):
    def on_period(self, k, u, drive):
        if k == 3:
            ncosim.check(self.params["scenario"])


class ChecksInItsConstructor(ReturnsRight):
    def __init__(self, model, params):
        super().__init__(model, params)
        ncosim.check(params["scenario"])


def test_a_command_from_inside_a_command_raises_instead_of_waiting_forever(motor):
    """Issue 40 part 7: ncosim.run/check from an estimator's hook deadlocked (a non-re-entrant
    lock; SIGINT said "stopping" and stayed hung)."""
    import threading
    ncosim.register("runs_in_a_hook", RunsInAHook)
    ncosim.register("checks_in_its_constructor", ChecksInItsConstructor)
    inner = dict(motor)
    sc = with_estimators(motor, {"name": "h", "kind": "runs_in_a_hook", "scenario": {"x": 1}})
    sc["run"].update(runs=2, periods=50)
    done = {}

    def go():
        for threads in (1, 2):
            done[threads] = ncosim.run(sc, threads=threads, progress=False)

    t = threading.Thread(target=go, daemon=True)
    t.start()
    t.join(120)
    assert not t.is_alive(), "ncosim.check from a hook hangs"
    for c in done.values():
        status = c.runs.set_index("estimator").loc["h", "status"]
        assert status.str.startswith("python_error: RuntimeError: ncosim.check: called from inside "
                                     "a running ncosim command").all(), status.iloc[0]
        assert status.str.endswith("(in on_period at k = 3)").all()
    with pytest.raises(ncosim.ScenarioError, match="RuntimeError: ncosim.check: called from inside"):
        ncosim.check(with_estimators(inner, {"name": "c", "kind": "checks_in_its_constructor",
                                             "scenario": {"x": 1}}))
    calls = []

    def progress(done_runs, total, final):
        try:
            ncosim.check(inner)
        except RuntimeError as e:
            calls.append(str(e))

    from ncosim import _api, _toml
    code, _, err = _api._cli(["run", "<dict>", "--out", "p", "--runs", "2", "--periods", "50"],
                             {"<dict>": _toml.dumps(inner)}, progress)
    assert code == 0, err
    assert calls and all("ncosim.check: called from inside" in c for c in calls), calls
    assert ncosim.check(inner)  # and commands work again afterwards


def test_bad_parameters_are_bad_input_with_their_location(motor):
    ncosim.register("bad_params", BadParams)
    assert ncosim.check(with_estimators(motor, {"name": "b", "kind": "bad_params", "gain": 2.0}))
    with pytest.raises(ncosim.ScenarioError,
                       match=r"^<dict>: key 'estimator\[1\]\.kind': the Python estimator \"bad_params\" "
                             r"refused its table: ValueError: gain: expected a positive number, got -1"):
        ncosim.run(with_estimators(motor, {"name": "b", "kind": "bad_params", "gain": -1}),
                   out="nothing", progress=False)
    from pathlib import Path
    assert not Path("nothing").exists()


def test_registration(motor, tmp_path):
    with pytest.raises(ValueError, match="built-in"):
        ncosim.register("kalman_extended", Raising)
    with pytest.raises(TypeError):
        ncosim.register("not_a_class", object)
    assert "numpy_kf" in ncosim.registered()
    # A file names a Python kind like a built-in one; registering again replaces the class.
    path = tmp_path / "s.toml"
    from ncosim import _toml
    path.write_text(_toml.dumps(with_estimators(motor, {"name": "p", "kind": "swap"})))

    class First(Raising):
        def on_period(self, k, u, drive):
            pass

    class Second(First):
        flops = 7.0

    ncosim.register("swap", First)
    assert ncosim.run(path, progress=False).summary.set_index("estimator").loc["p", "flops_per_period"] != 7.0
    ncosim.register("swap", Second)
    assert ncosim.run(path, progress=False).summary.set_index("estimator").loc["p", "flops_per_period"] == 7.0
    kinds = ncosim.kinds("estimator")
    assert "swap" in set(kinds.kind)


def test_the_model_an_estimator_sees(motor):
    seen = {}

    class Spy(Raising):
        def __init__(self, model, params):
            super().__init__(model, params)
            seen.update(model=model, params=params)

        def on_packet(self, packet, k):
            seen.setdefault("packets", []).append((packet.sensor, k - packet.stamps[0], packet.count))
            return None

        def on_period(self, k, u, drive):
            pass

    ncosim.register("spy", Spy)
    sc = with_estimators(motor, {"name": "s", "kind": "spy", "anything": [1, 2], "t": {"x": "y"}})
    sc["run"].update(runs=1, periods=200)
    ncosim.run(sc, progress=False)
    m = seen["model"]
    np.testing.assert_array_equal(m.A, [[1.0, 0.1], [0.0, 0.8]])
    np.testing.assert_allclose(m.Q, [[0.2, 0.1], [0.1, 1.0]])
    assert m.C.shape == (2, 2) and m.R[1, 1] == 0.5 and m.n == 2
    assert [s.name for s in m.sensors] == ["y", "v"]
    np.testing.assert_allclose(m.sensors[0].delay_pmf[:4], [0.5, 0.2, 0.1, 0.05])
    assert m.sensors[1].loss == pytest.approx(0.3)
    assert seen["params"] == {"anything": [1, 2], "t": {"x": "y"}}
    delays = {(s, d) for s, d, _ in seen["packets"]}
    assert {(0, 0), (0, 3), (1, 1)} <= delays and all(d <= 3 for _, d in delays)


def test_a_python_estimator_in_network_runs():
    """A [[network]] scenario simulates each run's ns-3 in a worker process (network/worker.h):
    the Python estimator runs in the campaign's threads of this process, beside the progress
    bar's thread, and sees the packets the network delivered."""
    import tomllib
    from conftest import ROOT
    k = ncosim.kinds("network")
    if "lr_wpan" not in set(k.kind):
        pytest.skip("this build has no ns-3 networks")
    path = ROOT / "scenarios" / "wsn_star.toml"
    with open(path, "rb") as f:
        sc = tomllib.load(f)
    kalman = next(e for e in sc["estimator"] if e["kind"] == "kalman_extended")
    sc["estimator"].append({"name": "numpy", "kind": "numpy_kf", "max_delay": kalman["max_delay"]})
    sc["run"].update(runs=6, periods=300)
    import os
    os.chdir(path.parent)  # its relative paths
    c = ncosim.run(sc, threads=2, progress=True)
    mse = c.runs.pivot(index="run", columns="estimator", values="mse")
    assert len(mse) == 6 and (c.runs.status == "ok").all()
    np.testing.assert_allclose(mse["numpy"], mse[kalman["name"]], rtol=1e-9, atol=0)
