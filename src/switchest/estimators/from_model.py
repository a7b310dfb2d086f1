"""The registered methods' estimators built from a model file, one builder per family.

Each builder is ``build(method, spec, t, **options) -> Estimator``: ``method`` the registry's
row (:class:`~switchest.estimators.registry.Method`, whose :meth:`~.registry.Method.build`
calls it with the options it accepted), ``spec`` the model file
(:class:`~switchest.modelfile.ModelSpec`), ``t`` the sample times. It takes from the model
file what the estimator's constructor needs and the user options do not give — the prior
``[initial]``, a transition matrix (:func:`~switchest.default_designs.transition_for`), gains
(:mod:`switchest.default_designs`), the detector's bounds and windows (``[noise]``) — and
passes the other options on to the constructor.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .._checks import float_array, positive_scalar
from ..analysis import decay_observer_gains
from ..default_designs import impulsive_gains, rsls_gains, transition_for
from ..modelfile import ModelSpec
from ..switching import MarkovAtSamples

if TYPE_CHECKING:
    from .base import Estimator
    from .registry import Method

__all__ = ["build_filter", "build_impulsive", "build_min_distance", "build_rsls"]

_LEE_SETTINGS = {  # option -> (what it is, CLI flag)
    "v_max": ("the noise bound |v(t)| <= v_max, Lee et al. eq. (2)", "--v-max"),
    "delta": ("the estimation window, Lee et al. condition (3)", "--delta"),
    "Delta": ("the detection delay, Lee et al. condition (4)", "--Delta"),
}


def build_filter(method: Method, spec: ModelSpec, t, *, stay: float | None = None,
                 particles: int | None = None, seed: int | None = None,
                 **options: Any) -> Estimator:
    """The Kalman-type filters: ``method.estimator(system, [transition,] x0, P0, **options)``.

    A required transition matrix comes from the switching model (:func:`transition_for`) at the
    median sampling interval of ``t``, or from ``stay``; an optional one (Shankar et al.'s
    Algorithm 1 uses none) only when ``stay`` is given or the switching model is a Markov chain
    at the samples. A method with the option ``particles`` gets 1000 particles unless told
    otherwise, and ``rng=seed`` (default 0: the same particles on every run).
    """
    spec, t = _checked(spec, t)
    explicit = stay is not None or isinstance(spec.switching, MarkovAtSamples)
    args = []
    if method.transition == "required" or (method.transition == "optional" and explicit):
        T = float(np.median(np.diff(t))) if t.size > 1 else 1.0
        args.append(transition_for(spec, T, stay=stay))
    elif method.transition == "optional":
        args.append(None)
    if "particles" in method.options:
        if "rng" in options:
            raise TypeError(f"method {method.name!r} takes the seed of its random numbers as "
                            "seed=, got rng=")
        options |= {"particles": 1000 if particles is None else particles,
                    "rng": 0 if seed is None else seed}
    return method.estimator(spec.system, *args, *_prior(spec), **options)


def build_min_distance(method: Method, spec: ModelSpec, t, *, v_max: float | None = None,
                       delta: float | None = None, Delta: float | None = None,
                       **options: Any) -> Estimator:
    """Lee, Ping & Shim's detector with the model's bounds and windows.

    ``v_max``, ``delta`` and ``Delta`` override ``[noise]``. Unless given as options, ``u_max``
    (used only by the detector's assumption check) and the observer gains (``observer_decay``,
    :func:`~switchest.analysis.min_distance_design.decay_observer_gains`; otherwise the
    detector's default) come from ``[noise]``. The detector takes its time grid (uniform) from
    the ``t`` it runs on.
    """
    spec, _ = _checked(spec, t)
    noise = spec.noise
    settings = {"v_max": v_max, "delta": delta, "Delta": Delta}
    for name, value in settings.items():
        if value is not None:
            settings[name] = positive_scalar(value, name)
        elif name in noise:
            settings[name] = noise[name]
        else:
            what, flag = _LEE_SETTINGS[name]
            raise ValueError(f"method {method.name!r} needs {name}, {what}: add {name} to the "
                             f"model file's [noise] table or pass {flag} ({name}= in Python)")
    options.setdefault("u_max", noise.get("u_max", 0.0))
    if "observer_gains" not in options:
        decay = noise.get("observer_decay")
        options["observer_gains"] = (None if decay is None
                                     else decay_observer_gains(spec.system, decay))
    return method.estimator(spec.system, **settings, **options)


def build_rsls(method: Method, spec: ModelSpec, t, *, switch_interval: float | None = None,
               **options: Any) -> Estimator:
    """Wang et al.'s observer with the default gains (:func:`rsls_gains`) for the switching
    interval ``T``: ``switch_interval``, or the model's ``sampling.period``."""
    spec, _ = _checked(spec, t)
    if switch_interval is not None:
        T = positive_scalar(switch_interval, "switch_interval")
    elif spec.sampling.get("period") is not None:
        T = spec.sampling["period"]
    else:
        raise ValueError(f"method {method.name!r} needs the switching interval T (Wang et al. "
                         "Assumption 1): set sampling.period in the model file or pass "
                         "--switch-interval (switch_interval= in Python)")
    return method.estimator(spec.system, rsls_gains(spec, T), T, *_prior(spec), **options)


def build_impulsive(method: Method, spec: ModelSpec, t, **options: Any) -> Estimator:
    """Etienne et al.'s impulsive observer with the gains of Theorem 8's LMIs for the sampling
    intervals of ``t`` (:func:`impulsive_gains`)."""
    spec, t = _checked(spec, t)
    return method.estimator(spec.system, impulsive_gains(spec, t), *_prior(spec), **options)


def _checked(spec: ModelSpec, t) -> tuple[ModelSpec, np.ndarray]:
    if not isinstance(spec, ModelSpec):
        raise TypeError(f"spec must be a ModelSpec (switchest.modelfile.load_model), got "
                        f"{type(spec).__name__}")
    return spec, float_array(t, "t", ndim=1)


def _prior(spec: ModelSpec) -> tuple[np.ndarray, np.ndarray]:
    if spec.initial is None:
        raise ValueError("the model file needs an [initial] table (mean, cov) to start the filter")
    return spec.initial
