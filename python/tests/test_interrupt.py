"""Ctrl-C (SIGINT) stops a campaign run from Python cleanly: KeyboardInterrupt, the finished runs
kept in the run store, and resume=True completes it with the runs an uninterrupted campaign has."""
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import ncosim
from conftest import MOTOR, ROOT

SCRIPT = textwrap.dedent("""
    import sys, ncosim
    sc = {scenario!r}
    try:
        ncosim.run(sc, out="long", threads=1, progress=False, timing=False)
        print("COMPLETED")
    except KeyboardInterrupt as e:
        print("INTERRUPTED", e)
    """)


def test_ctrl_c_keeps_what_finished_and_resume_completes(tmp_path):
    sc = dict(MOTOR, run={"runs": 400, "periods": 60000, "seed": 11})
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    p = subprocess.Popen([sys.executable, "-c", SCRIPT.format(scenario=sc)], cwd=tmp_path, env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    store = tmp_path / ".long.partial.sqlite"  # the run store while the campaign runs
    deadline = time.monotonic() + 60
    while not store.exists() and time.monotonic() < deadline:
        time.sleep(0.02)
    time.sleep(1.0)  # some runs finish and are committed (the whole campaign takes ~10 s)
    p.send_signal(signal.SIGINT)
    time.sleep(0.05)
    p.send_signal(signal.SIGINT)  # a second Ctrl-C must not end the interpreter (a kernel)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 0 and "INTERRUPTED" in out, (p.returncode, out, err)
    assert "--resume" in out  # the command line's message, as KeyboardInterrupt's text
    c = ncosim.run(sc, out=tmp_path / "long", resume=True, threads=2, progress=False, timing=False)
    runs = c.runs[c.runs.estimator == "KF"]
    assert sorted(runs.run) == list(range(400))
    assert c.manifest["complete"] is True
    # The first runs are those of an uninterrupted campaign of the same seed.
    ref = ncosim.run(dict(sc, run={"runs": 3, "periods": 60000, "seed": 11}), progress=False,
                     timing=False)
    assert list(runs.mse[:3]) == list(ref.runs.mse[:3])
