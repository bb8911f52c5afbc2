"""Estimators written in Python, in the same campaign as the C++ ones."""
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
    assert runs.loc["w", "status"].str.contains("expected a vector of 2 numbers, got 3").all()
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
        assert runs.loc["c", "status"].str.contains(r"samples used, 0\.\.1, got 2").all()
        assert runs.loc["r", "status"].str.contains("a command is running").all()
    assert "too_late" not in ncosim.registered()


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
