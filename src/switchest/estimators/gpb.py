"""Generalized pseudo-Bayesian filters of the first and second order, GPB1 and GPB2
(Bar-Shalom, Li & Kirubarajan 2001, §11.6.4-§11.6.5).

Both approximate the posterior of a jump-Markov linear system, a mixture of :math:`L^k` Gaussians
after :math:`k` samples (one per mode sequence), by a mixture of fewer, switches happening at the
sample instants. The ``timing`` (:doc:`/conventions`;
:class:`~switchest.estimators.mode_bank.ModeBankFilter`) says which interval the mode :math:`s_k`
of sample :math:`k` governs besides :math:`y_k`: the one after it (``"sample"``:
:math:`x_{k+1} = F(s_k) x_k + G(s_k) u_k + w_k`) or the one into it (``"interval"``, Bar-Shalom's:
:math:`x_k = F(s_k) x_{k-1} + G(s_k) u_{k-1} + w`); so which mode's transition a prediction takes.
By default it is the system's.

- GPB1 keeps one Gaussian: :math:`L` Kalman filters, one per mode at sample :math:`k`; mode
  probabilities :math:`\\mu_j(k) \\propto \\Lambda_j(k) c_j`,
  :math:`c_j = \\sum_i \\pi_{ij} \\mu_i(k-1)`. ``"sample"``: each mode-matched posterior
  :math:`i` of sample :math:`k - 1` is predicted through mode :math:`i`'s transition and the
  :math:`L` predictions are collapsed into one Gaussian (the moments of
  :math:`\\sum_i \\mu_i(k-1) \\, \\mathcal{N}(x_i(k|k-1), P_i(k|k-1))`) from which every mode
  :math:`j` updates. ``"interval"`` (§11.6.4): the posteriors are collapsed first and
  mode :math:`j` predicts the one Gaussian through its own transition. It is the IMM's bank with the
  interaction replaced by that collapse (:func:`~switchest.engine.imm.imm_run` with
  ``interaction="collapse"``).
- GPB2 keeps one Gaussian per mode: :math:`L^2` Kalman filters, one per pair (mode :math:`i`
  at :math:`k - 1`, mode :math:`j` at :math:`k`), predicted from mode :math:`i`'s Gaussian
  through mode :math:`i`'s transition (``"sample"``: one prediction per :math:`i`, shared by its
  pairs) or mode :math:`j`'s (``"interval"``, §11.6.5), updated with :math:`C_j`, :math:`R_j`,
  :math:`\\mu_{ij}(k) \\propto \\Lambda_{ij}(k) \\pi_{ij} \\mu_i(k-1)`; each mode's pairs are merged
  into one Gaussian (:mod:`switchest.engine.gpb`).

The output of both is the moments of the mixture over the modes, as the IMM's; ``smooth`` (of
:class:`~switchest.estimators.mode_bank.ModeBankFilter`) runs Kim's (1994) smoother on either.
The IMM (:class:`~switchest.estimators.IMMFilter`) costs what GPB1 costs and is, in general,
about as accurate as GPB2 (Bar-Shalom, Li & Kirubarajan §11.6.6).

Conventions as :class:`~switchest.estimators.IMMFilter`: ``transition[i, j]`` =
:math:`\\Pr(\\text{mode } j \\text{ at } k+1 \\mid \\text{mode } i \\text{ at } k)`, rows summing to
one; mode probabilities kept as log-weights; Joseph-form updates; NaN in ``y`` a missing component;
sample 0 an update of every mode from the prior; one exact transition per mode and distinct sampling
step. Outliers: a filter (of a mode, or of a pair for GPB2) whose normalized innovation squared
exceeds ``gate``, or overflows, is not updated and gets weight zero; a sample no filter can use
counts as missing and is flagged in ``Estimate.outlier``.
"""

from __future__ import annotations

from ..engine.imm import GPB2
from .base import _with_mode_model_parameters
from .mode_bank import ModeBankFilter

__all__ = ["GPB1Filter", "GPB2Filter"]


@_with_mode_model_parameters
class GPB1Filter(ModeBankFilter):
    """First-order generalized pseudo-Bayesian filter (Bar-Shalom, Li & Kirubarajan §11.6.4),
    batched over trials and modes.

    Every mode-matched Kalman filter restarts from one Gaussian and updates with its :math:`C`,
    :math:`R`; :math:`\\mu_j(k) \\propto \\Lambda_j(k) \\sum_i \\pi_{ij} \\mu_i(k-1)`. The one
    Gaussian, in the ``"sample"`` timing: the moments of
    :math:`\\sum_i \\mu_i(k-1) \\, \\mathcal{N}(x_i(k|k-1), P_i(k|k-1))`, each mode-matched
    posterior :math:`i` predicted through mode :math:`i`'s transition
    (the model :math:`x_{k+1} = F(s_k) x_k + G(s_k) u_k + w_k`, :math:`y_k = C(s_k) x_k + v_k`); in
    the ``"interval"`` timing (§11.6.4; :math:`x_k = F(s_k) x_{k-1} + G(s_k) u_{k-1} + w`,
    :math:`y_k = C(s_k) x_k + v`): the moments of the mixture
    :math:`\\sum_i \\mu_i \\, \\mathcal{N}(x_i, P_i)` of the previous sample, then predicted through
    mode :math:`j`'s transition. The output is the moments
    of the mixture over the modes.

    Parameters
    ----------
    {mode model parameters}
    gate : float, optional
        Largest normalized innovation squared a mode-matched filter accepts (keyword-only);
        ``None`` rejects only measurements whose innovation overflows. A sample every mode
        rejects is treated as missing and flagged in ``Estimate.outlier``.
    timing : {"sample", "interval"}, optional
        Which interval the mode of sample :math:`k` governs besides :math:`y_k` (keyword-only):
        the one after it (``"sample"``) or the one into it (``"interval"``, Bar-Shalom's); by
        default the system's; the models and the derivation are in
        :class:`~switchest.estimators.mode_bank.ModeBankFilter`.

    Notes
    -----
    With the identity ``transition`` GPB1 is *not* the static multiple-model bank (each mode's
    filter alone from the prior, :math:`\\mu_j(k) \\propto \\mu_j(0) \\prod \\Lambda_j`): its
    probabilities do follow :math:`\\mu_j(k) \\propto \\mu_j(k-1) \\Lambda_j(k)`, but
    :math:`\\Lambda_j` is the likelihood of mode :math:`j`'s filter restarted from the collapsed
    Gaussian of all modes. The IMM and GPB2 with the identity transition are that bank (their
    mixing weights are :math:`\\delta_{ij}`).

    Examples
    --------
    >>> from switchest.models.shankar import BoostTable1
    >>> boost = BoostTable1()  # Shankar et al.'s boost converter, Table I's setting
    >>> gpb1 = GPB1Filter(boost.system(), boost.transition, *boost.prior)
    >>> traj = boost.simulate(0.01, 3, rng=0)  # 3 trials x 10 ms
    >>> est = gpb1.run(traj.y, boost.input, traj.t)
    >>> est.x.shape, est.mode.shape
    ((3, 21, 2), (3, 21))
    """

    _interaction = "collapse"


@_with_mode_model_parameters
class GPB2Filter(ModeBankFilter):
    """Second-order generalized pseudo-Bayesian filter (Bar-Shalom, Li & Kirubarajan §11.6.5),
    batched over trials, modes and pairs of modes.

    :math:`L^2` Kalman filters, one per pair (mode :math:`i` at :math:`k - 1`, mode :math:`j` at
    :math:`k`), each predicted from mode :math:`i`'s Gaussian and updated with mode :math:`j`'s
    :math:`C`, :math:`R`;
    :math:`\\mu_{ij}(k) \\propto \\Lambda_{ij}(k) \\pi_{ij} \\mu_i(k-1)`. The prediction goes
    through mode :math:`i`'s transition in the ``"sample"`` timing
    (:math:`x_{k+1} = F(s_k) x_k + G(s_k) u_k + w_k`, :math:`y_k = C(s_k) x_k + v_k`: computed once
    per :math:`i`), through mode :math:`j`'s in the
    ``"interval"`` timing (§11.6.5; :math:`x_k = F(s_k) x_{k-1} + G(s_k) u_{k-1} + w`,
    :math:`y_k = C(s_k) x_k + v`). Mode :math:`j`'s pairs are merged
    into one Gaussian: :math:`\\mu_j = \\sum_i \\mu_{ij}`, :math:`x_j = \\sum_i \\mu_{i|j} x_{ij}`,
    :math:`P_j = \\sum_i \\mu_{i|j} (P_{ij} + (x_{ij} - x_j)(x_{ij} - x_j)^\\top)` with
    :math:`\\mu_{i|j} = \\mu_{ij} / \\mu_j`. The output is the moments of the mixture over the
    modes. At sample 0 there is only the prior: :math:`L` filters,
    :math:`\\mu_j(0) \\propto \\Lambda_j \\, \\mathrm{mode\\_prob0}_j`.

    Parameters
    ----------
    {mode model parameters}
    gate : float, optional
        Largest normalized innovation squared a pair's filter accepts (keyword-only); ``None``
        rejects only measurements whose innovation overflows. A sample every pair rejects is
        treated as missing and flagged in ``Estimate.outlier``.
    timing : {"sample", "interval"}, optional
        Which interval the mode of sample :math:`k` governs besides :math:`y_k` (keyword-only):
        the one after it (``"sample"``) or the one into it (``"interval"``, Bar-Shalom's); by
        default the system's; see :class:`~switchest.estimators.mode_bank.ModeBankFilter`.

    Notes
    -----
    With the identity ``transition`` the pairs :math:`i \\ne j` have weight zero and GPB2 is the
    static multiple-model bank: each mode's Kalman filter alone from the prior,
    :math:`\\mu_j(k) \\propto \\mu_j(0) \\prod_t \\Lambda_j(t)`.

    Examples
    --------
    >>> import numpy as np
    >>> from switchest import simulate
    >>> from switchest.models import vehicle_2d, vehicle_maneuver
    >>> man = vehicle_maneuver()  # Shankar et al.'s vehicle, section V.B: it turns, then drives on
    >>> traj = simulate(vehicle_2d(), man.signal, man.t, np.zeros(4), u=man.u, trials=2, rng=0)
    >>> transition = np.full((3, 3), 0.05) + 0.85 * np.eye(3)
    >>> gpb2 = GPB2Filter(vehicle_2d(), transition, np.zeros(4), 0.01 * np.eye(4))
    >>> smoothed = gpb2.smooth(traj.y, man.u, man.t)  # GPB2's pass, then the two-filter smoother
    >>> smoothed.mode_prob.shape  # (trials, samples, modes)
    (2, 21, 3)
    >>> bool(np.all(np.isfinite(smoothed.x)))
    True
    """

    _interaction = GPB2
