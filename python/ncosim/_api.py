"""ncosim's Python API: the command line's commands as functions, results as pandas DataFrames.

Every function builds the command line the ncosim executable would get and runs it in this
process, so a scenario, an override and an output folder mean exactly what they mean there
(README.md, "Using it"); docs/python.md is the guide.
"""
import json
import os
import shutil
import tempfile
import threading
import warnings
import weakref
from pathlib import Path

from . import _ncosim, _toml

try:
    from . import _paths
    _EXECUTABLE = _paths.executable
except ImportError:  # pragma: no cover - a package copied by hand
    _EXECUTABLE = ""

__all__ = ["ScenarioError", "Campaign", "Comparison", "Fit", "run", "check", "compare", "fit",
           "kinds"]

# Exit statuses of the command line (README.md, "Exit codes").
_EXIT_BAD_INPUT = 2
_EXIT_FLAGGED = 3


class ScenarioError(ValueError):
    """Bad input: the scenario, an override or an argument. The message is the command line's:
    ``FILE:LINE: key 'PATH': ...`` for a file or TOML string, ``<dict>: key 'PATH': ...`` for a
    dict, one line per error (every independent error of a file: the first 20, then a line
    ``and N more errors``). Nothing was written."""

    @property
    def errors(self):
        """The message's lines, one error each."""
        return str(self).splitlines()


def _scenario_source(scenario):
    """(name the command line gets, {name: text} for sources held in memory)."""
    name, texts = _source(scenario)
    for n, text in texts.items():
        try:
            text.encode("utf-8")
        except UnicodeEncodeError as e:
            raise ScenarioError(f"{n}: the scenario is not valid Unicode at character {e.start} "
                                f"({e.reason}: {text[e.start:e.end]!r})") from None
    return name, texts


def _source(scenario):
    if isinstance(scenario, dict):
        return "<dict>", {"<dict>": _toml.dumps(scenario)}
    if isinstance(scenario, os.PathLike):
        return os.fspath(scenario), {}
    if isinstance(scenario, str):
        # A path exists, or is one line ending in .toml or without an assignment; anything else
        # is a TOML text.
        one_line = "\n" not in scenario
        if os.path.exists(scenario) or (one_line and (scenario.strip().endswith(".toml")
                                                      or "=" not in scenario)):
            return scenario, {}
        return "<string>", {"<string>": scenario}
    raise TypeError(f"scenario: expected a path, a TOML string or a dict, got {type(scenario).__name__}")


def _names_python_estimator(scenario, texts, set_):
    """Whether the scenario (with its overrides and sweeps) may name an estimator kind registered
    from Python: any string equal to such a name (a false alarm only costs threads)."""
    from . import _estimator
    names = set(_estimator.registered())
    if not names:
        return False
    if any(v in names for v in (set_ or {}).values() if isinstance(v, str)):
        return True
    text = next(iter(texts.values()), None)
    if text is None:
        try:
            with open(scenario, encoding="utf-8", errors="replace") as f:
                text = f.read()
        except OSError:
            return False
    import re
    return any(re.search(r'["\']' + re.escape(n) + r'["\']', text) for n in names)


def _integer(flag, v):
    """An integer argument as the command line gets it: a float, string or bool is refused, not
    rounded (the command line checks the range: a seed outside 0 .. 2**63 - 1 is refused)."""
    import numbers
    if isinstance(v, bool) or not isinstance(v, numbers.Integral):
        raise ScenarioError(f"{flag[2:]}: expected an integer, got {v!r}")
    return int(v)


def _sets(set_):
    args = []
    for k, v in (set_ or {}).items():
        args += ["--set", f"{k}={_toml.value(v, k)}"]
    return args


def _text(b):
    return b.decode("utf-8", errors="replace")


def _message(err):
    lines = [ln[len("ncosim: "):] if ln.startswith("ncosim: ") else ln
             for ln in _text(err).strip().splitlines()]
    return "\n".join(lines)


class _Progress:
    """tqdm's bar (notebook or terminal) when tqdm is installed; nothing otherwise."""

    def __init__(self, on):
        self.bar = None
        self.on = on
        if on:
            try:
                try:  # a notebook widget where ipywidgets is installed, a text bar otherwise
                    import ipywidgets  # noqa: F401
                    from tqdm.auto import tqdm
                except ImportError:
                    from tqdm import tqdm
                self.tqdm = tqdm
            except ImportError:
                self.on = False

    def __call__(self, done, total, final):
        if self.bar is None:
            self.bar = self.tqdm(total=total, unit="run", desc="ncosim", leave=True)
        if self.bar.total != total:
            self.bar.total = total
        if done != self.bar.n:
            self.bar.update(done - self.bar.n)
        if final:
            self.bar.close()

    def close(self):
        if self.bar is not None and not self.bar.disable:
            self.bar.close()


# One command at a time per process: the command line captures std::cout and holds in-memory
# scenarios by name; a second thread's call waits for the first. A call from inside a command
# (an estimator's method, the progress callback, or the thread that runs the command) would wait
# for itself forever: it raises RuntimeError instead.
_COMMAND_LOCK = threading.Lock()
_COMMAND_THREAD = None  # the thread running a command, while one runs


def _refuse_nested(what):
    if _ncosim._in_hook() or _COMMAND_THREAD == threading.get_ident():
        raise RuntimeError(
            f"ncosim.{what}: called from inside a running ncosim command (an estimator's method or "
            "the progress callback); commands do not nest: call it after the command returns")


def _cli(args, texts=None, progress=None):
    """(exit status, stdout, stderr) of `ncosim ARGS...` run in this process."""
    global _COMMAND_THREAD
    _refuse_nested(args[0] if args else "command")
    with _COMMAND_LOCK:
        _COMMAND_THREAD = threading.get_ident()
        try:
            return _ncosim._cli([str(a) for a in args], texts or {}, progress, _EXECUTABLE)
        finally:
            _COMMAND_THREAD = None


def _raise_for(code, err, what):
    if code == _EXIT_BAD_INPUT:
        raise ScenarioError(_message(err)) from None
    if code != 0:
        raise RuntimeError(f"ncosim {what}: {_message(err) or f'exit status {code}'}")


def _read_csv(path):
    import pandas as pd
    return pd.read_csv(path, keep_default_na=True)


class Campaign:
    """The output folder of a campaign (`ncosim run`), its tables as pandas DataFrames.

    ``summary``, ``runs`` and ``links`` have the columns of summary.csv, runs.csv and links.csv
    (results/README.md); ``design`` and ``manifest`` are design.json and manifest.json as dicts;
    ``error_curve`` and ``trajectory`` are there when the campaign wrote them. Each is read from
    the folder when first asked for. ``out`` is the folder (a temporary one, removed with this
    object, when run() got no ``out``); ``table`` is what the command line prints.
    """

    def __init__(self, out, table="", status=0, temporary=None):
        self.out = Path(out)
        self.table = table
        self.status = status
        self._cache = {}
        self._temporary = temporary
        if temporary is not None:
            self._finalizer = weakref.finalize(self, shutil.rmtree, temporary, True)

    def _csv(self, name):
        if name not in self._cache:
            path = self.out / name
            if not path.exists():
                raise AttributeError(f"{name} is not in {self.out}")
            self._cache[name] = _read_csv(path)
        return self._cache[name]

    def _json(self, name):
        if name not in self._cache:
            with open(self.out / name, encoding="utf-8") as f:
                self._cache[name] = json.load(f)
        return self._cache[name]

    summary = property(lambda self: self._csv("summary.csv"), doc="summary.csv: one row per (case, estimator)")
    runs = property(lambda self: self._csv("runs.csv"), doc="runs.csv: one row per (run, estimator)")
    links = property(lambda self: self._csv("links.csv"), doc="links.csv: one row per (case, link, sender)")
    error_curve = property(lambda self: self._csv("error_curve.csv"), doc="error_curve.csv ([run] error_curve = true)")
    trajectory = property(lambda self: self._csv("trajectory.csv"), doc="trajectory.csv (trace=True)")
    design = property(lambda self: self._json("design.json"), doc="design.json")
    manifest = property(lambda self: self._json("manifest.json"), doc="manifest.json")

    def __repr__(self):
        return f"<ncosim.Campaign {self.out}>\n{self.table}"

    def _repr_html_(self):
        return f"<p><code>{self.out}</code></p>" + self.summary.to_html(max_cols=20, max_rows=60)


def run(scenario, *, runs=None, periods=None, seed=None, threads=None, set=None, out=None,
        progress=True, resume=False, replace=False, trace=False, timing=True, fail_on_status=False):
    """Runs a Monte Carlo campaign (`ncosim run`) and returns its Campaign.

    ``scenario`` is a path, a TOML string or a dict (tables as dicts, ``[[sensor]]`` as a list of
    dicts). ``set`` maps key paths to values, as ``--set KEY=VALUE``. ``out=None`` writes into a
    temporary folder kept as long as the Campaign. ``progress``: a tqdm bar when tqdm is
    installed. Bad input raises ScenarioError (a ValueError) and writes nothing; Ctrl-C
    (KeyboardInterrupt) stops the campaign as SIGINT stops the command line: the runs that
    finished are kept in the run store of ``out`` and ``resume=True`` goes on from there.
    """
    name, texts = _scenario_source(scenario)
    if threads is None and _names_python_estimator(scenario, texts, set):
        threads = 1  # the GIL serialises Python: one thread is fastest (docs/python.md, "Threads")
    temporary = None
    if out is None:
        temporary = tempfile.mkdtemp(prefix="ncosim-")
        out = os.path.join(temporary, "campaign")
    args = ["run", name, "--out", os.fspath(out)]
    for flag, v in (("--runs", runs), ("--periods", periods), ("--seed", seed), ("--threads", threads)):
        if v is not None:
            args += [flag, _integer(flag, v)]
    args += _sets(set)
    args += ["--resume"] * bool(resume) + ["--replace"] * bool(replace) + ["--trace"] * bool(trace)
    args += ["--no-timing"] * (not timing) + ["--fail-on-status"] * bool(fail_on_status)
    bar = _Progress(progress)
    if not bar.on:
        args.append("--quiet")
    try:
        code, stdout, err = _cli(args, texts, bar if bar.on else None)
    finally:
        bar.close()
    if code in (128 + 2, 128 + 15):
        msg = _message(err)
        if temporary is not None:
            shutil.rmtree(temporary, True)
        raise KeyboardInterrupt(msg)
    if code not in (0, _EXIT_FLAGGED):
        if temporary is not None:
            shutil.rmtree(temporary, True)
        _raise_for(code, err, "run")
    if code == _EXIT_FLAGGED:
        warnings.warn(_message(err), RuntimeWarning, stacklevel=2)
    return Campaign(out, _text(stdout), code, temporary)


def check(scenario, *, set=None, runs=None, periods=None, seed=None):
    """Parses, validates and designs a scenario (`ncosim check`) without running it. Returns
    {"cases": N, "estimators": M}; bad input raises ScenarioError."""
    name, texts = _scenario_source(scenario)
    args = ["check", name] + _sets(set)
    for flag, v in (("--runs", runs), ("--periods", periods), ("--seed", seed)):
        if v is not None:
            args += [flag, _integer(flag, v)]
    code, out, err = _cli(args, texts)
    _raise_for(code, err, "check")
    text = _text(out)
    import re
    m = re.search(r"ok \((\d+) case\(s\), (\d+) estimator\(s\)\)", text)
    return {"cases": int(m.group(1)), "estimators": int(m.group(2))} if m else {"output": text}


def _folder(x):
    return os.fspath(x.out if isinstance(x, Campaign) else x)


class Comparison:
    """`ncosim compare`: ``table`` (compare.csv as a DataFrame), ``markdown`` (what it prints),
    ``regression`` (True when a row got worse: the command's exit 1), ``inconclusive`` (True when
    no row got worse but one could not be told from a change beyond the tolerance: exit 4, or 0
    with allow_inconclusive)."""

    def __init__(self, table, markdown, regression, warnings_text, inconclusive=False):
        self.table = table
        self.markdown = markdown
        self.regression = regression
        self.inconclusive = inconclusive
        self.warnings = warnings_text

    @property
    def verdict(self):
        """``regression``, ``inconclusive`` or ``no regression`` (docs/compare.md)."""
        if self.regression:
            return "regression"
        return "inconclusive" if self.inconclusive else "no regression"

    def __repr__(self):
        return f"<ncosim.Comparison: {self.verdict}>\n{self.markdown}"

    def _repr_html_(self):
        return f"<p>verdict: <b>{self.verdict}</b></p>" + self.table.to_html()


def compare(base, new, *, metric=None, tolerance=None, alpha=None, correction=None,
            allow_inconclusive=False, allow_scenario_change=False):
    """Compares two campaigns (Campaign objects or output folders) row by row, paired where the
    seeds match (`ncosim compare BASE NEW`). Returns a Comparison."""
    with tempfile.TemporaryDirectory(prefix="ncosim-compare-") as tmp:
        args = ["compare", _folder(base), _folder(new), "--out", os.path.join(tmp, "cmp")]
        for flag, v in (("--metric", metric), ("--tolerance", tolerance), ("--alpha", alpha),
                        ("--correction", correction)):
            if v is not None:
                args += [flag, v]
        args += ["--allow-inconclusive"] * bool(allow_inconclusive)
        args += ["--allow-scenario-change"] * bool(allow_scenario_change)
        code, out, err = _cli(args)
        if code not in (0, 1, 4):
            _raise_for(code, err, "compare")
        table = _read_csv(os.path.join(tmp, "cmp", "compare.csv"))
        with open(os.path.join(tmp, "cmp", "compare.md"), encoding="utf-8") as f:
            markdown = f.read()
    inconclusive = code == 4 or (code == 0 and "inconclusive" in set(table["verdict"]))
    return Comparison(table, markdown, code == 1, _message(err), inconclusive)


class Fit:
    """`ncosim fit`: ``families`` (fit.csv as a DataFrame), ``link`` (the selected family's
    [[link]] table, TOML text, as link.toml holds it) and ``output`` (what the command prints)."""

    def __init__(self, families, link, output):
        self.families = families
        self.link = link
        self.output = output

    def __repr__(self):
        return f"<ncosim.Fit>\n{self.output}"


def fit(trace, *, family=None, criterion=None, starts=None, name=None, out=None):
    """Fits channel models to a packet trace (`ncosim fit TRACE`): a CSV path (seq,delay), or a
    pandas DataFrame with those columns. ``family``: a name or a list of names."""
    with tempfile.TemporaryDirectory(prefix="ncosim-fit-") as tmp:
        if hasattr(trace, "to_csv"):
            path = os.path.join(tmp, f"{name or 'trace'}.csv")
            frame = trace[["seq", "delay"]].copy()
            frame["delay"] = frame["delay"].astype("Int64")  # integers, empty when lost
            frame.to_csv(path, index=False)
            trace = path
        folder = os.fspath(out) if out is not None else os.path.join(tmp, "fit")
        args = ["fit", os.fspath(trace), "--out", folder]
        for f in ([family] if isinstance(family, str) else family or []):
            args += ["--family", f]
        for flag, v in (("--criterion", criterion), ("--starts", starts), ("--name", name)):
            if v is not None:
                args += [flag, v]
        code, stdout, err = _cli(args)
        _raise_for(code, err, "fit")
        families = _read_csv(os.path.join(folder, "fit.csv"))
        with open(os.path.join(folder, "link.toml"), encoding="utf-8") as f:
            link = f.read()
    return Fit(families, link, _text(stdout))


def kinds(section=None, *, keys=False):
    """Every registered kind (plants, links, inputs, estimators, send policies, networks, and the
    scenario's own sections) as a DataFrame: section, kind, help, keys (how many). With
    ``keys=True``, one row per declared key: section, kind, key, type, unit, default, range,
    required, help. ``section`` keeps one section ("estimator", "link", ...)."""
    import pandas as pd
    rows = _ncosim._kinds()
    if section is not None:
        rows = [r for r in rows if r["section"] == section]
    if not keys:
        return pd.DataFrame([{"section": r["section"], "kind": r["kind"], "help": r["help"],
                              "keys": len(r["keys"])} for r in rows])
    return pd.DataFrame([{"section": r["section"], "kind": r["kind"], **k}
                         for r in rows for k in r["keys"]])
