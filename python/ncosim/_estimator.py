"""Estimators written in Python (docs/python.md, "Estimators in Python")."""
from . import _ncosim

__all__ = ["Estimator", "register", "registered"]


class Estimator:
    """Base of an estimator written in Python: the hooks of a C++ estimator (estimators/estimator.h).

    Each run makes a new instance, ``cls(model, params)``: ``model`` is what an estimator may know
    of the scenario (``n``, ``period``, ``A``, ``Bu``, ``Bw``, ``W``, ``Q`` = Bw W Bw', ``x0``,
    ``C`` and ``R`` of every sensor stacked, and ``sensors``: each with ``name``, ``C``, ``R``,
    ``every``, ``buffer``, ``rows`` (its slice of the stacked ``C``), ``loss`` and ``delay_pmf``
    of its link, None for a recorded one); ``params`` is the [[estimator]] table's other keys as a
    dict. The constructor is also called once when the scenario is read: raising there (e.g.
    ValueError for a bad parameter) is bad input, reported with the table's location.

    The run then calls, in the simulation's order:

    - ``on_packet(packet, k)``: a packet delivered at period k (before the update of period k);
      ``packet.sensor``, ``packet.stamps`` (the period of each sample), ``packet.values`` (sample
      i in ``[i*ny, (i+1)*ny)``). Return the number of samples used (None: all).
    - ``on_period(k, u, drive)``: the update of period k: predict with the known input (k > 0),
      then correct with what arrived. ``drive`` is the known part of x[k] - A x[k-1] - Bw w[k-1].
    - ``state()``: xhat[k|k] (n numbers), read after every on_period.
    - ``covariance()`` (optional): the filter's own n x n error covariance, or None.
    - ``mode()`` (optional): the estimated mode, or None.

    ``flops`` (optional, a class attribute or set in the constructor): FLOPs per period, shown in
    summary.csv's ``flops_per_period``. An exception in a hook ends that run's estimate: the run's
    status is ``python_error: ...`` with the message, and the campaign goes on.
    """

    flops = None

    def __init__(self, model, params):
        self.model = model
        self.params = params

    def on_packet(self, packet, k):
        return None

    def on_period(self, k, u, drive):
        raise NotImplementedError

    def state(self):
        raise NotImplementedError

    def covariance(self):
        return None

    def mode(self):
        return None


def register(name, cls=None, *, help=""):
    """Registers an Estimator subclass as estimator kind ``name`` (then ``kind = "name"`` in a
    scenario, file or dict). Registering a name again replaces its class. Usable as a decorator:
    ``@ncosim.register("my_kf")``."""
    def add(c):
        if not (isinstance(c, type) and issubclass(c, Estimator)):
            raise TypeError(f"register: expected a subclass of ncosim.Estimator, got {c!r}")
        from ._api import _COMMAND_LOCK
        # Never while a command runs (it reads the registries; a hook registering would wait for
        # its own campaign): register before run().
        if not _COMMAND_LOCK.acquire(blocking=False):
            raise RuntimeError(f"register({name!r}): a command is running in this process; "
                               "register estimators before calling run()")
        try:
            _ncosim._register_estimator(name, help or (c.__doc__ or "").strip().split("\n")[0], c)
        finally:
            _COMMAND_LOCK.release()
        return c
    return add if cls is None else add(cls)


def registered():
    """The estimator kinds registered from Python, in order."""
    return list(_ncosim._registered_estimators())
