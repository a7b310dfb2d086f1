"""The switched linear system: mode matrices stacked over the L modes.

Continuous time (``domain="continuous"``):

.. math::

    \\begin{aligned}
    \\dot{x} &= A(s)\\, x + B(s)\\, u + w, &
    \\mathbb{E}[w(t)\\, w(r)^\\top] &= Q(s)\\, \\delta(t - r), \\\\
    y(t_k) &= C(s)\\, x(t_k) + v_k, & v_k &\\sim \\mathcal{N}(0, R(s))
    \\end{aligned}

Discrete time (``domain="discrete"``, step ``dt``):

.. math::

    \\begin{aligned}
    x_{k+1} &= A(s)\\, x_k + B(s)\\, u_k + w_k, & w_k &\\sim \\mathcal{N}(0, Q(s)), \\\\
    y_k &= C(s)\\, x_k + v_k, & v_k &\\sim \\mathcal{N}(0, R(s)),
    \\end{aligned}

with :math:`s` the active mode (0-based). This is the model of Shankar et al. eqs
(1)-(2), Zhang & Natarajan eq. (1), Wang et al. eq. (1) (there with a
continuous output), Lee et al. eq. (1) and Etienne et al. eq. (1).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ._checks import check_finite, check_symmetric_psd, check_timing, float_array, positive_scalar

__all__ = ["SwitchedLinearSystem"]

Domain = Literal["continuous", "discrete"]


@dataclass(frozen=True, eq=False)
class SwitchedLinearSystem:
    """A switched linear system with L modes; arrays are read-only.

    Attributes
    ----------
    A : ndarray, shape (L, n, n)
        State matrices.
    B : ndarray, shape (L, n, l)
        Input matrices (:math:`l = 0` when the system has no input).
    C : ndarray, shape (L, m, n)
        Output matrices.
    Q : ndarray, shape (L, n, n)
        Process-noise covariance: intensity (continuous) or per-step covariance
        (discrete). Symmetric positive semidefinite.
    R : ndarray, shape (L, m, m)
        Measurement-noise covariance, symmetric positive definite; all zeros when
        the system was built with ``R=None`` (noise-free measurements).
    domain : {"continuous", "discrete"}
    dt : float or None
        Sampling step of a discrete system; ``None`` for continuous ones.
    timing : {"sample", "interval"}
        Which interval the mode of a sample governs besides its measurement
        (:doc:`/conventions`): the one after it (``"sample"``, the default: Costa, Fragoso &
        Marques 2005, eq. (3.1)) or the one into it (``"interval"``: Bar-Shalom, Li &
        Kirubarajan 2001, §11.6). :func:`switchest.simulate.simulate` draws data in it and the
        multiple-model filters, :func:`switchest.learn.fit` and the model file follow it.

    Notes
    -----
    Build instances with :meth:`continuous`, :meth:`discrete` or
    :meth:`from_statespace`; they validate every argument. Equality is identity:
    two systems with equal matrices are different objects (this keeps them
    hashable for the discretization cache). Model files are read and written by
    :func:`switchest.modelfile.load_system` and :func:`~switchest.modelfile.save_system`
    (a layer above this module).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    domain: Domain
    dt: float | None = None
    timing: str = "sample"

    def __post_init__(self) -> None:
        check_timing(self.timing)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def continuous(cls, A, B=None, C=None, Q=None, R=None, *,
                   timing: str = "sample") -> SwitchedLinearSystem:
        """A continuous-time switched system.

        Parameters
        ----------
        A : array_like, shape (L, n, n) or (n, n)
            Mode state matrices; a single 2-D matrix is shared by all modes.
        B : array_like, shape (L, n, l) or (n, l), optional
            Input matrices; ``None`` means no input (:math:`l = 0`).
        C : array_like, shape (L, m, n) or (m, n), optional
            Output matrices, at least one output (:math:`m \\ge 1`); ``None`` means
            the full state is measured (:math:`C = I`).
        Q : array_like, shape (L, n, n) or (n, n), optional
            Process-noise intensity; ``None`` means no process noise.
        R : array_like, shape (L, m, m) or (m, m), optional
            Measurement-noise covariance (symmetric positive definite); ``None``
            means noise-free measurements.
        timing : {"sample", "interval"}
            Which interval the mode of a sample governs (keyword-only; the attribute).

        A 2-D argument is shared by all modes; the number of modes L is the
        leading size of the 3-D arguments, which must agree. Every matrix must be
        real and finite: boolean, complex or date arrays raise ``TypeError``.
        """
        return cls._build(A, B, C, Q, R, domain="continuous", dt=None, timing=timing)

    @classmethod
    def discrete(cls, A, B=None, C=None, Q=None, R=None, dt: float = 1.0, *,
                 timing: str = "sample") -> SwitchedLinearSystem:
        """A discrete-time switched system with step ``dt``; arguments as :meth:`continuous`.

        Here ``Q`` is the per-step process-noise covariance.
        """
        return cls._build(A, B, C, Q, R, domain="discrete", dt=positive_scalar(dt, "dt"),
                          timing=timing)

    @classmethod
    def from_statespace(cls, systems: Sequence, *, Q=None, R=None,
                        timing: str = "sample") -> SwitchedLinearSystem:
        """Build from one state-space object per mode (e.g. python-control ``ss``).

        Each object needs ``A, B, C, D`` attributes and a ``dt`` attribute (0 or
        ``None`` for continuous time, a positive step for discrete time, ``True``
        for an unspecified step, taken as 1). ``D`` must be zero: switchest models
        have no direct feedthrough. python-control itself is not required. ``Q``, ``R`` and
        ``timing`` as in :meth:`continuous`.
        """
        if isinstance(systems, (str, bytes)) or not isinstance(systems, Sequence):
            raise TypeError(
                f"systems must be a sequence of state-space objects, got {type(systems).__name__}"
            )
        if len(systems) == 0:
            raise ValueError("systems must hold at least one mode, got an empty sequence")
        mats = {k: [] for k in "ABCD"}
        dts = []
        for i, sys in enumerate(systems):
            for k in "ABCD":
                if not hasattr(sys, k):
                    raise TypeError(
                        f"systems[{i}] must have attributes A, B, C, D, missing {k} "
                        f"({type(sys).__name__})"
                    )
                value = float_array(getattr(sys, k), f"systems[{i}].{k}", ndim=(0, 1, 2))
                mats[k].append(np.atleast_2d(value))
            dts.append(_time_base(getattr(sys, "dt", 0), f"systems[{i}].dt"))
        for i, D in enumerate(mats["D"]):
            if np.any(D != 0):
                raise ValueError(f"systems[{i}].D must be zero (no feedthrough), got {D.tolist()}")
        if len(set(dts)) != 1:
            raise ValueError(f"all systems must share one time base dt, got {dts}")
        shapes = {k: {m.shape for m in v} for k, v in mats.items() if k != "D"}
        for k, s in shapes.items():
            if len(s) != 1:
                raise ValueError(f"systems[*].{k} must have one shape across modes, "
                                 f"got {sorted(s)}")
        A, B, C = (np.stack(mats[k]) for k in "ABC")
        if dts[0] == 0.0:
            return cls.continuous(A, B, C, Q, R, timing=timing)
        return cls.discrete(A, B, C, Q, R, dt=dts[0], timing=timing)

    @classmethod
    def _build(cls, A, B, C, Q, R, *, domain: Domain, dt: float | None,
               timing: str) -> SwitchedLinearSystem:
        if A is None:
            raise TypeError("A is required: the mode state matrices, shape (L, n, n) or (n, n)")
        given = {"A": A, "B": B, "C": C, "Q": Q, "R": R}
        arrays = {}
        for name, value in given.items():
            if value is not None:
                arrays[name] = float_array(value, name, ndim=(2, 3))
                check_finite(arrays[name], name)
        n_modes = _count_modes(arrays)
        A = _stack(arrays["A"], n_modes)
        if A.shape[-1] != A.shape[-2]:
            raise ValueError(f"A must be square (n x n), got shape {arrays['A'].shape}")
        n = A.shape[-1]
        if n == 0:
            raise ValueError("A must have at least one state, got n = 0")
        B = _stack(arrays["B"], n_modes) if B is not None else np.zeros((n_modes, n, 0))
        C = (_stack(arrays["C"], n_modes) if C is not None
             else np.broadcast_to(np.eye(n), (n_modes, n, n)))
        m = C.shape[-2]
        _expect(B, "B", (n, B.shape[-1]), f"(n, l) with n = {n}")
        _expect(C, "C", (m, n), f"(m, n) with n = {n}")
        if m == 0:  # nothing to estimate from: every estimator and analysis needs an output
            raise ValueError(
                f"C must have at least one row (m >= 1 outputs), got shape {C.shape[1:]}"
            )
        if Q is None:
            Q = np.zeros((n_modes, n, n))
        else:
            Q = _stack(arrays["Q"], n_modes)
            _expect(Q, "Q", (n, n), f"(n, n) with n = {n}")
            Q = check_symmetric_psd(Q, "Q")
        if R is None:
            R = np.zeros((n_modes, m, m))
        else:
            R = _stack(arrays["R"], n_modes)
            identity = "" if "C" in arrays else " (C defaults to the identity)"
            outputs = f"m = {m} outputs{identity}"
            _expect(R, "R", (m, m), f"(m, m) with {outputs}")
            R = check_symmetric_psd(R, "R", definite=True)
        fields = {}
        for name, arr in zip("ABCQR", (A, B, C, Q, R)):
            arr = np.array(arr, dtype=float)  # own, contiguous copy
            arr.setflags(write=False)
            fields[name] = arr
        return cls(**fields, domain=domain, dt=dt, timing=timing)

    def replace(self, *, timing: str | None = None, **matrices) -> SwitchedLinearSystem:
        """The same system (domain, ``dt``, ``timing``) with some of ``A``, ``B``, ``C``,
        ``Q``, ``R`` (and the ``timing``) replaced, checked as the constructors check them
        (noise-free outputs stay noise-free unless ``R`` is given)."""
        unknown = set(matrices) - {"A", "B", "C", "Q", "R"}
        if unknown:
            raise TypeError(f"replace takes A, B, C, Q, R, timing, got {sorted(unknown)}")
        fields = {name: matrices.get(name, getattr(self, name)) for name in "ABCQR"}
        if "R" not in matrices and not self.has_measurement_noise:
            fields["R"] = None
        return self._build(**fields, domain=self.domain, dt=self.dt,
                           timing=self.timing if timing is None else timing)

    # ------------------------------------------------------------------ sizes
    @property
    def n_modes(self) -> int:
        """Number of modes L."""
        return self.A.shape[0]

    @property
    def n_states(self) -> int:
        """State dimension n."""
        return self.A.shape[1]

    @property
    def n_inputs(self) -> int:
        """Input dimension l (0 without input)."""
        return self.B.shape[2]

    @property
    def n_outputs(self) -> int:
        """Output dimension m."""
        return self.C.shape[1]

    @property
    def is_continuous(self) -> bool:
        """True for a continuous-time system."""
        return self.domain == "continuous"

    @property
    def has_measurement_noise(self) -> bool:
        """False when the system was built with ``R=None`` (noise-free outputs)."""
        return bool(np.any(self.R != 0))

    def __repr__(self) -> str:
        step = "" if self.dt is None else f", dt={self.dt:g}"
        return (
            f"SwitchedLinearSystem({self.domain}, modes={self.n_modes}, states={self.n_states}, "
            f"inputs={self.n_inputs}, outputs={self.n_outputs}{step}, timing={self.timing!r})"
        )


def _time_base(dt, name: str) -> float:
    """python-control's ``dt``: 0 or None continuous, True an unspecified step (1), or the step."""
    if dt is None or dt is False:
        return 0.0
    if dt is True:
        return 1.0
    return positive_scalar(dt, name, allow_zero=True)


def _count_modes(arrays: dict[str, np.ndarray]) -> int:
    counts = {name: a.shape[0] for name, a in arrays.items() if a.ndim == 3}
    if len(set(counts.values())) > 1:
        listed = ", ".join(f"{k} has {v}" for k, v in counts.items())
        raise ValueError(f"the stacked arguments disagree on the number of modes: {listed}")
    n_modes = next(iter(counts.values()), 1)
    if n_modes == 0:
        stacked = ", ".join(counts)
        raise ValueError(
            f"a switched system needs at least one mode, got L = 0 ({stacked} stacked over 0 modes)"
        )
    return n_modes


def _stack(arr: np.ndarray, n_modes: int) -> np.ndarray:
    """Broadcast a shared 2-D matrix to every mode; 3-D stacks pass through."""
    return np.broadcast_to(arr, (n_modes, *arr.shape)) if arr.ndim == 2 else arr


def _expect(arr: np.ndarray, name: str, shape: tuple[int, int], text: str) -> None:
    if arr.shape[1:] != shape:
        raise ValueError(f"{name} must be {text} per mode, got shape {arr.shape[1:]}")

