"""The estimation methods a user selects by name, one row each, in one table.

Each row names the estimator class that implements the method and the function that builds it
from a model file (:mod:`.from_model`), says what its ``run`` must be told of the switching,
whether it uses a mode transition matrix, which user options apply to it, and gives a one-line
description and the paper it implements. :meth:`Method.build` makes the estimator from a
:class:`~switchest.modelfile.ModelSpec` and :meth:`Method.run` runs it with the keywords it
takes. :func:`switchest.tabular.estimate_table`, the command line (``switchest estimate
--method``, its choices and help), the bake-off (:mod:`switchest.experiments.bakeoff`) and the
conformance suite of the estimators (tests/estimators/test_conformance.py) all read this table:
a new method is its class, its kernel and one row here.

Classes and builders are named by reference (``"module:name"``, a module relative to this
package or absolute) and imported at their first use, so that reading the table (the names,
options and descriptions the command line's parser shows) imports no estimator.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from importlib import import_module
from typing import TYPE_CHECKING, Any

import numpy as np

from .._checks import check_bool, did_you_mean

if TYPE_CHECKING:
    from ..modelfile import ModelSpec
    from ..signals import SwitchingSignal
    from .base import Estimate, Estimator

__all__ = ["METHOD_NAMES", "Method", "get_method", "methods", "methods_with"]


def _resolve(reference: str) -> Any:
    """The object ``name`` of ``module`` for ``reference = "module:name"`` (``module`` relative
    to this package when it starts with a dot)."""
    module, _, name = reference.partition(":")
    return getattr(import_module(module, __package__), name)


@dataclass(frozen=True)
class Method:
    """One user-facing estimation method.

    Attributes
    ----------
    name : str
        The name a user gives (``switchest estimate --method NAME``).
    implementation : str
        The class that implements it, ``"module:Class"`` (:attr:`estimator` imports it).
    switching : {"modes", "signals"} or None
        The keyword by which ``estimator.run`` is told the switching: ``"modes"``, the
        true or believed mode at each sample; ``"signals"``, the true switching signal
        (:class:`~switchest.signals.SwitchingSignal`); None when the method estimates
        the switching from the measurements alone.
    transition : {"required", "optional", "unused"}
        Whether the constructor takes a mode transition matrix
        (``transition[i, j]`` =
        :math:`\\Pr(\\text{mode } j \\text{ at } k+1 \\mid \\text{mode } i \\text{ at } k)`).
    options : tuple of str
        The user options that apply to it: the options of
        :func:`switchest.tabular.estimate_table` and ``switchest estimate`` of the same names.
        ``smooth`` is an option of :meth:`run`, the others of :meth:`build`.
    description : str
        One line: what it estimates and from what.
    paper : str
        The paper (and section) it implements.
    builder : str
        The function that builds the estimator from a model file, ``"module:function"``,
        called as ``builder(method, spec, t, **options)`` (:meth:`build`); by default the
        Kalman-type filters' ``cls(system, [transition,] x0, P0, **options)``.
    inputs : bool
        False when the method's model has no input (Wang et al. eq. (1)): :meth:`run` gives
        its ``run`` no ``u``.
    innovation_check : bool
        True when its covariance is that of its innovations given the model (Kalman updates
        along the given modes), so that :func:`switchest.tabular.estimate_table` warns when
        the data do not fit the model file.
    between_samples : bool
        True when the method models switches inside the sampling intervals (a continuous-time
        system's), not only at the samples.
    """

    name: str
    implementation: str
    switching: str | None
    transition: str
    options: tuple[str, ...]
    description: str
    paper: str
    builder: str = ".from_model:build_filter"
    inputs: bool = True
    innovation_check: bool = False
    between_samples: bool = False

    @property
    def estimator(self) -> type[Estimator]:
        """The class that implements the method (imported at the first look-up)."""
        return _resolve(self.implementation)

    @property
    def needs_modes(self) -> bool:
        """True when ``run`` must be told the known modes (per sample or as a signal)."""
        return self.switching is not None

    def check_options(self, names: Iterable[str]) -> None:
        """Refuse the user options among ``names`` that apply to other methods, not to this one.

        Raises
        ------
        ValueError
            Naming the first such option and the methods it applies to.
        """
        for name in names:
            owners = methods_with(name)
            if owners and name not in self.options:
                raise ValueError(f"{name} applies to method {' or '.join(map(repr, owners))} "
                                 f"only, got method {self.name!r}")

    def build(self, spec: ModelSpec, t, **options: Any) -> Estimator:
        """The method's estimator for the model file ``spec`` sampled at ``t``.

        Parameters
        ----------
        spec : ModelSpec
            The model file (:func:`switchest.modelfile.load_model`): the system, its prior
            (``[initial]``) and what the method's design takes from it (the switching model
            for a transition matrix, ``[noise]`` for the minimum-distance detector, the sampling
            period for the RSLS observer).
        t : array_like, shape (K,)
            The sample times the estimator will run on.
        **options
            The user options of the method (:attr:`options`, e.g. ``grid``, ``stay``,
            ``v_max``, ``particles``, ``seed``, ``timing``; unset ones take the builder's
            default or the model file's value) and keyword arguments of the estimator's
            constructor, passed on as given (e.g. ``switch_time="marginal"``,
            ``observer_gains=...``).

        Returns
        -------
        Estimator
            An instance of :attr:`estimator`.

        Raises
        ------
        ValueError
            For a user option of other methods only (:meth:`check_options`), and when the
            model file lacks what the method needs (the message says what to add).
        """
        self.check_options(options)
        build: Callable[..., Estimator] = _resolve(self.builder)
        return build(self, spec, t, **options)

    def run(self, estimator: Estimator, y, u=None, t=None, *, modes=None,
            signals: SwitchingSignal | Sequence[SwitchingSignal] | None = None, segments=None,
            smooth: bool = False) -> Estimate:
        """Run ``estimator`` (from :meth:`build`) over ``y`` with the keywords its ``run`` takes.

        The caller gives what it knows of the switching; the method is told what
        :attr:`switching` says it takes and nothing else: a method that estimates the modes is
        not told them.

        Parameters
        ----------
        estimator : Estimator
            The method's estimator.
        y, u, t : array_like
            Measurements ``(..., K, m)``, inputs ``(..., K, l)`` and sample times ``(K,)``,
            as for ``estimator.run``. For a method without input (:attr:`inputs` False) ``u``
            is None or has no columns.
        modes : array_like of int, shape (K,) or (..., K), optional
            The known mode at each sample: required by the ``"modes"`` methods; the
            ``"signals"`` methods take their switching signal from it
            (:func:`switchest.measurements.mode_signal`, one trial) when ``signals`` is None.
        signals : SwitchingSignal or sequence of them, optional
            The true switching signal(s), for the ``"signals"`` methods.
        segments : optional
            The true switching instants inside the sample intervals
            (``Trajectory.segments()``), for the ``"modes"`` methods that take them (the
            clairvoyant mode-based Kalman filter).
        smooth : bool
            Fixed-interval smoothed estimates (``estimator.smooth``) instead of filtered ones;
            only for the methods with the option ``smooth``.

        Returns
        -------
        Estimate

        Raises
        ------
        ValueError
            When the method needs modes (or a signal) and none is given, when ``smooth`` does
            not apply to it, or when ``u`` has columns for a method without input.
        """
        if check_bool(smooth, "smooth"):
            self.check_options(["smooth"])
            return estimator.smooth(y, u, t)
        if not self.inputs:
            if u is not None and np.size(u):
                raise ValueError(f"u must be None or have no columns: method {self.name!r} takes "
                                 f"no input, got shape {np.shape(u)}")
            u = None
        told = {}
        if self.switching == "modes":
            if modes is None:
                raise ValueError(f"method {self.name!r} needs modes, the known mode at each "
                                 "sample")
            told["modes"] = modes
            if segments is not None:
                told["segments"] = segments
        elif self.switching == "signals":
            if signals is None:
                if modes is None:
                    raise ValueError(f"method {self.name!r} needs signals, the switching "
                                     "signal, or modes, the known mode at each sample")
                from ..measurements import mode_signal

                signals = mode_signal(t, modes)
            told["signals"] = signals
        return estimator.run(y, u, t, **told)


_TABLE = {m.name: m for m in (
    Method("kalman", ".mode_kalman:ModeKalmanFilter", "modes", "unused", ("gate",),
           "Kalman filter along a known (or believed) mode sequence",
           "Zhang & Natarajan (001), Algorithm 1", innovation_check=True),
    Method("switch-time", ".switch_time:SwitchTimeKalmanFilter", "modes", "unused",
           ("grid", "refine", "switch_time", "gate"),
           "Kalman filter with the modes known at the samples and gridded maximum-likelihood "
           "switching times", "Shankar et al. (000), §III-§IV, eq. (23)", innovation_check=True,
           between_samples=True),
    Method("imm", ".imm:IMMFilter", None, "required", ("stay", "smooth", "timing", "gate"),
           "interacting multiple model filter; modes unknown", "Blom & Bar-Shalom (1988)"),
    Method("imm-between", ".imm_between:BetweenSamplesIMMFilter", None, "required",
           ("grid", "stay", "smooth", "gate"),
           "IMM on the chain of (mode before, mode after, switching instant on a grid): a "
           "continuous-time system switching between the samples; modes unknown",
           "beyond Shankar et al. (000), eqs (3)-(5) and (23); Blom & Bar-Shalom (1988)",
           between_samples=True),
    Method("gpb1", ".gpb:GPB1Filter", None, "required", ("stay", "smooth", "timing", "gate"),
           "first-order generalized pseudo-Bayesian filter (one Gaussian kept); modes unknown",
           "Bar-Shalom, Li & Kirubarajan (2001), §11.6.4"),
    Method("gpb2", ".gpb:GPB2Filter", None, "required", ("stay", "smooth", "timing", "gate"),
           "second-order generalized pseudo-Bayesian filter (one Gaussian per mode, L^2 "
           "filters); modes unknown", "Bar-Shalom, Li & Kirubarajan (2001), §11.6.5"),
    Method("rbpf", ".rbpf:RBPFilter", None, "required", ("stay", "particles", "seed", "timing"),
           "Rao-Blackwellized particle filter (modes sampled, a Kalman filter per particle); "
           "modes unknown", "Doucet, Gordon & Krishnamurthy (2001), §III"),
    Method("imm-ev1", ".imm_ev1:IMMEV1Filter", None, "optional",
           ("grid", "switch_time", "estimate", "stay", "gate"),
           "IMM extended-Viterbi filter with switching-time estimation; modes unknown",
           "Shankar et al. (000), Algorithm 1", between_samples=True),
    Method("min-distance", ".min_distance:MinimumDistanceDetector", None, "unused",
           ("v_max", "delta", "Delta"),
           "minimum-distance mode estimation and switching detection on a uniform time grid",
           "Lee, Ping & Shim (002), §III-§V", builder=".from_model:build_min_distance"),
    Method("rsls", ".rsls:RSLSObserver", "modes", "unused", ("switch_interval",),
           "subsystem observer of a randomly switched system, fed the integrated output",
           "Wang et al. (003), §3", builder=".from_model:build_rsls", inputs=False),
    Method("impulsive", ".impulsive:ImpulsiveObserver", "signals", "unused", (),
           "impulsive observer at aperiodic samples along the switching signal",
           "Etienne et al. (004), eqs (2)-(3)", builder=".from_model:build_impulsive"),
)}

METHOD_NAMES: tuple[str, ...] = tuple(_TABLE)
"""The registered method names, in the order they are offered (``switchest estimate --method``,
:func:`switchest.tabular.estimate_table`)."""


def methods() -> tuple[Method, ...]:
    """Every registered method, in the order they are offered."""
    return tuple(_TABLE.values())


def methods_with(option: str) -> tuple[str, ...]:
    """The names of the registered methods that the user option ``option`` applies to (none
    for a name that is no user option)."""
    return tuple(m.name for m in _TABLE.values() if option in m.options)


def get_method(name: str) -> Method:
    """The registered method called ``name``.

    Raises
    ------
    ValueError
        When no method of that name is registered (the message lists them and suggests the
        closest, :func:`switchest._checks.did_you_mean`: ``'imm'`` for ``"IMM"``).
    """
    if not isinstance(name, str) or name not in _TABLE:
        hint = did_you_mean(name, _TABLE, before="; ") if isinstance(name, str) else ""
        raise ValueError(f"method must be one of {tuple(_TABLE)}, got {name!r}{hint}")
    return _TABLE[name]
