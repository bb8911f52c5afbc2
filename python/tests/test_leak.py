"""Reference counting: 1,000 campaigns with a Python estimator leave no objects behind and the
resident memory flat."""
import gc
import resource
import sys
import weakref

import ncosim
from conftest import MOTOR

live = weakref.WeakSet()


class Tracked(ncosim.Estimator):
    def __init__(self, model, params):
        super().__init__(model, params)
        live.add(self)
        self.x = model.x0.copy()

    def on_period(self, k, u, drive):
        self.x = self.model.A @ self.x + drive

    def state(self):
        return self.x


def rss_kib():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def test_no_leak_over_1000_campaigns():
    ncosim.register("tracked", Tracked)
    sc = dict(MOTOR, run={"runs": 2, "periods": 30, "seed": 1},
              estimator=MOTOR["estimator"] + [{"name": "t", "kind": "tracked"}])
    refs = sys.getrefcount(Tracked)

    def campaigns(n):
        for _ in range(n):
            c = ncosim.run(sc, progress=False)  # timing on: its instances too
            assert len(c.runs) == 4
            del c
        gc.collect()

    campaigns(100)  # warm-up: allocator pools, pandas, imports
    before = rss_kib()
    campaigns(1000)
    grown = rss_kib() - before
    print(f"RSS over 1000 campaigns: {before} KiB -> {before + grown} KiB ({grown / 1000:.2f} KiB per campaign)")
    assert len(live) == 0  # every instance (2 runs + the design's check, per campaign) released
    assert sys.getrefcount(Tracked) == refs
    # A leak of one small object per run would be ~2 x 1000 x 100 B; a DataFrame or a design per
    # campaign, far more. 4 MiB is well below one leaked design per campaign (the model arrays alone
    # are ~2 KiB) and well above allocator noise.
    assert grown < 4096, f"RSS grew by {grown} KiB over 1000 campaigns"
