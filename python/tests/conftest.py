"""Shared fixtures of the Python package's tests (run by ctest: python/tests/CMakeLists.txt)."""
import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "examples" / "python"))  # numpy_kf


def executable():
    """The ncosim executable of the build tree that holds the package."""
    import ncosim._paths
    return ncosim._paths.executable


# Schenato's DC motor, one sensor behind a delaying link, the delay-extended Kalman filter: small
# enough for a test (4 runs x 1500 periods, milliseconds).
MOTOR = {
    "title": "motor over a delaying link",
    "run": {"runs": 4, "periods": 1500, "seed": 11},
    "plant": {"kind": "lti", "A": [[1.0, 0.1], [0.0, 0.8]], "Bw": [[1.0, 0.0], [0.0, 1.0]],
              "W": [[0.2, 0.1], [0.1, 1.0]]},
    "sensor": [{"name": "y", "C": [[1.0, 0.0]], "R": [[1.0]], "link": "net"},
               {"name": "v", "C": [[0.0, 1.0]], "R": [[0.5]], "link": "net2"}],
    "link": [{"name": "net", "kind": "delay", "pmf": [0.5, 0.2, 0.1, 0.05]},
             {"name": "net2", "kind": "bernoulli", "loss": 0.3, "delay": 1}],
    "estimator": [{"name": "KF", "kind": "kalman_extended", "max_delay": 3}],
}


@pytest.fixture
def motor():
    import copy
    return copy.deepcopy(MOTOR)


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    yield
