"""The estimation methods a user selects by name, one entry each, in one table.

Each entry names the estimator class that implements the method, what its ``run`` must be
told of the switching, whether it uses a mode transition matrix, the user options of
:func:`switchest.tabular.estimate_table` (and ``switchest estimate``) that apply to it, a
one-line description and the paper it implements. :func:`switchest.tabular.estimate_table`,
the command line's ``--method`` and the conformance suite of the estimators
(tests/estimators/test_conformance.py) all read this table; a method registered here is
offered by the first two and held to the protocol of
:class:`~switchest.estimators.base.Estimator` by the third.
"""

from __future__ import annotations

from dataclasses import dataclass

from .base import Estimator
from .gpb import GPB1Filter, GPB2Filter
from .imm import IMMFilter
from .imm_ev1 import IMMEV1Filter
from .impulsive import ImpulsiveObserver
from .min_distance import MinimumDistanceDetector
from .mode_kalman import ModeKalmanFilter
from .rbpf import RBPFilter
from .rsls import RSLSObserver
from .switch_time import SwitchTimeKalmanFilter

__all__ = ["METHOD_NAMES", "Method", "get_method"]


@dataclass(frozen=True)
class Method:
    """One user-facing estimation method.

    Attributes
    ----------
    name : str
        The name a user gives (``switchest estimate --method NAME``).
    estimator : type of Estimator
        The class that implements it.
    switching : {"modes", "signals"} or None
        The keyword by which ``estimator.run`` is told the switching: ``"modes"``, the
        true or believed mode at each sample; ``"signals"``, the true switching signal
        (:class:`~switchest.signals.SwitchingSignal`); None when the method estimates
        the switching from the measurements alone.
    transition : {"required", "optional", "unused"}
        Whether the constructor takes a mode transition matrix
        (``transition[i, j]`` = P(mode j at k+1 | mode i at k)).
    options : tuple of str
        The options of :func:`switchest.tabular.estimate_table` that apply to it.
    description : str
        One line: what it estimates and from what.
    paper : str
        The paper (and section) it implements.
    """

    name: str
    estimator: type[Estimator]
    switching: str | None
    transition: str
    options: tuple[str, ...]
    description: str
    paper: str

    @property
    def needs_modes(self) -> bool:
        """True when ``run`` must be told the known modes (per sample or as a signal)."""
        return self.switching is not None


_METHODS = (
    Method("kalman", ModeKalmanFilter, "modes", "unused", (),
           "Kalman filter along a known (or believed) mode sequence",
           "Zhang & Natarajan (001), Algorithm 1"),
    Method("switch-time", SwitchTimeKalmanFilter, "modes", "unused", ("grid", "refine"),
           "Kalman filter with the modes known at the samples and gridded maximum-likelihood "
           "switching times", "Shankar et al. (000), §III-§IV, eq. (23)"),
    Method("imm", IMMFilter, None, "required", ("stay", "smooth", "timing"),
           "interacting multiple model filter; modes unknown", "Blom & Bar-Shalom (1988)"),
    Method("gpb1", GPB1Filter, None, "required", ("stay", "smooth", "timing"),
           "first-order generalized pseudo-Bayesian filter (one Gaussian kept); modes unknown",
           "Bar-Shalom, Li & Kirubarajan (2001), §11.6.4"),
    Method("gpb2", GPB2Filter, None, "required", ("stay", "smooth", "timing"),
           "second-order generalized pseudo-Bayesian filter (one Gaussian per mode, L^2 "
           "filters); modes unknown", "Bar-Shalom, Li & Kirubarajan (2001), §11.6.5"),
    Method("rbpf", RBPFilter, None, "required", ("stay", "particles", "seed", "timing"),
           "Rao-Blackwellized particle filter (modes sampled, a Kalman filter per particle); "
           "modes unknown", "Doucet, Gordon & Krishnamurthy (2001), §III"),
    Method("imm-ev1", IMMEV1Filter, None, "optional", ("grid", "stay"),
           "IMM extended-Viterbi filter with switching-time estimation; modes unknown",
           "Shankar et al. (000), Algorithm 1"),
    Method("min-distance", MinimumDistanceDetector, None, "unused", ("v_max", "delta", "Delta"),
           "minimum-distance mode estimation and switching detection on a uniform time grid",
           "Lee, Ping & Shim (002), §III-§V"),
    Method("rsls", RSLSObserver, "modes", "unused", ("switch_interval",),
           "subsystem observer of a randomly switched system, fed the integrated output",
           "Wang et al. (003), §3"),
    Method("impulsive", ImpulsiveObserver, "signals", "unused", (),
           "impulsive observer at aperiodic samples along the switching signal",
           "Etienne et al. (004), eqs (2)-(3)"),
)
_BY_NAME = {m.name: m for m in _METHODS}

METHOD_NAMES: tuple[str, ...] = tuple(_BY_NAME)
"""The registered method names, in the order they are offered (``switchest estimate --method``,
:func:`switchest.tabular.estimate_table`)."""


def get_method(name: str) -> Method:
    """The registered method called ``name``.

    Raises
    ------
    ValueError
        When no method of that name is registered (the message lists them).
    """
    if not isinstance(name, str) or name not in _BY_NAME:
        raise ValueError(f"method must be one of {METHOD_NAMES}, got {name!r}")
    return _BY_NAME[name]
