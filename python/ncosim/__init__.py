"""ncosim: a discrete-event co-simulator for state estimation over networks, from Python.

    import ncosim
    c = ncosim.run("scenarios/dolz2014_table2.toml", runs=20)
    c.summary            # summary.csv as a pandas DataFrame

docs/python.md is the guide; README.md and results/README.md define every key and column.
"""
from ._api import (Campaign, Comparison, Fit, ScenarioError, check, compare, fit, kinds, run)
from ._estimator import Estimator, register, registered
from ._ncosim import Packet

__all__ = ["run", "check", "compare", "fit", "kinds", "Campaign", "Comparison", "Fit",
           "ScenarioError", "Estimator", "register", "registered", "Packet"]
