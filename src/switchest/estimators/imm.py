"""The interacting multiple model filter (Blom & Bar-Shalom, 1988).

One Kalman filter per mode; at each sample their estimates are mixed with the
mode transition probabilities, after each update the mode probabilities are
re-weighted by the filters' likelihoods. Switches are assumed to happen at the
sample instants; the ``timing`` says which interval the mode of a sample governs
(:doc:`/conventions`) and so whether the mixing falls after the prediction
(``"sample"``) or before it (``"interval"``: Blom & Bar-Shalom's original); by default
it is the system's. Mode probabilities are kept as log-weights.

Both ``run`` (a whole record) and ``step`` (streaming) call the compiled kernel of
:mod:`switchest.engine.imm` (the one ``imm_run`` and ``imm_step`` call, through the filter's
:class:`~switchest.engine.imm.Bank`: its tables checked once), which holds the one
implementation of each equation: interaction (Blom & Bar-Shalom, 1988), mode-matched
Kalman prediction and update (Joseph form; the information form where that loses its
digits, a covariance beyond :math:`1/\\varepsilon` repaired with a ``RuntimeWarning``), and the
combined output (Bar-Shalom, Li & Kirubarajan §11.6.6).

Outliers: a mode whose filter rejects the measurement (its normalized innovation
squared overflows or exceeds ``gate``) is not updated and gets likelihood zero at
that sample; when every mode rejects it, the sample is treated as missing — no
update, the mode probabilities stay the predicted ones — and it is flagged in
``Estimate.outlier``.

Convention (all of switchest): ``transition[i, j]`` =
:math:`\\Pr(\\text{mode } j \\text{ at } k+1 \\mid \\text{mode } i \\text{ at } k)`; rows sum to
one.
"""

from __future__ import annotations

from .base import _with_mode_model_parameters
from .mode_bank import IMMState, ModeBankFilter

__all__ = ["IMMState", "IMMFilter"]


@_with_mode_model_parameters
class IMMFilter(ModeBankFilter):
    """Interacting multiple model filter, batched over trials and modes.

    Parameters
    ----------
    {mode model parameters}
    gate : float, optional
        Largest normalized innovation squared :math:`e^\\top S^{-1} e` a mode-matched filter
        accepts (keyword-only); e.g. ``scipy.stats.chi2.ppf(0.9999, m)``. ``None``
        rejects only measurements whose innovation overflows. A sample every mode
        rejects is treated as missing and flagged in ``Estimate.outlier``.
    timing : {"sample", "interval"}, optional
        Which interval the mode :math:`s_k` of sample :math:`k` governs besides :math:`y_k`
        (keyword-only; :doc:`/conventions`); ``None`` (the default): the system's ``timing``:

        - ``"sample"`` (the model :func:`switchest.simulate` draws with switches
          at the samples; Costa, Fragoso & Marques 2005, eq. (3.1)):
          :math:`x_{k+1} = F(s_k) x_k + G(s_k) u_k + w_k`, :math:`w_k \\sim \\mathcal{N}(0,
          Q_d(s_k))`, :math:`y_k = C(s_k) x_k + v_k`, :math:`v_k \\sim \\mathcal{N}(0, R(s_k))`.
          Each mode-matched posterior :math:`i` of sample :math:`k - 1` is predicted through mode
          :math:`i`'s transition, then the predictions are mixed into mode :math:`j`'s prior with
          the weights :math:`\\mu_{i|j} = \\pi_{ij} \\mu_i / c_j`, :math:`c_j = \\sum_i \\pi_{ij}
          \\mu_i`.
        - ``"interval"`` (Blom & Bar-Shalom 1988; Bar-Shalom, Li & Kirubarajan 2001,
          §11.6.6; FilterPy's ``IMMEstimator``):
          :math:`x_k = F(s_k) x_{k-1} + G(s_k) u_{k-1} + w`, :math:`y_k = C(s_k) x_k + v`. The
          posteriors are mixed with the same weights, then mode :math:`j`'s mixture is predicted
          through mode :math:`j`'s transition.

        Both update mode :math:`j` with :math:`C_j`, :math:`R_j`. With one mode they are the same
        (Kalman) filter.

    Notes
    -----
    Derivation of the ``"sample"`` ordering: :math:`x_k` is independent of :math:`s_k` given
    :math:`(s_{k-1}, x_{k-1})`, so

    .. math::

        p(x_k \\mid s_k = j, Y_{k-1}) = \\sum_i \\Pr(s_{k-1} = i \\mid s_k = j, Y_{k-1}) \\,
        p(x_k \\mid s_{k-1} = i, Y_{k-1}),

    with :math:`\\Pr(s_{k-1} = i \\mid s_k = j, Y_{k-1}) = \\mu_{i|j}` and
    :math:`p(x_k \\mid s_{k-1} = i, Y_{k-1})` mode :math:`i`'s Kalman prediction from
    its posterior (Gaussian given mode-matched posteriors). Moment-matching that mixture is
    Blom & Bar-Shalom's approximation, applied after the prediction instead of before it.

    ``smooth(y, u, t)`` gives the fixed-interval smoothed estimates and mode probabilities
    (:meth:`~switchest.estimators.mode_bank.ModeBankFilter.smooth`): by default the two-filter
    smoother on the IMM's mode-matched posteriors (Helmick, Blair & Hoffman 1995), with
    ``method="kim"`` Kim's (1994) backward recursion, as Murphy (1998, "Switching Kalman
    filters", §3-4) applies it to collapsing filters.

    Examples
    --------
    >>> import numpy as np
    >>> from switchest.models.shankar import BoostTable1
    >>> boost = BoostTable1()  # Shankar et al.'s boost converter, Table I's setting
    >>> traj = boost.simulate(0.01, 3, rng=0)  # 3 trials x 10 ms
    >>> imm = IMMFilter(boost.system(), boost.transition, *boost.prior)
    >>> est = imm.run(traj.y, boost.input, traj.t)
    >>> est.x.shape, est.mode_prob.shape  # (trials, samples, states), (..., modes)
    ((3, 21, 2), (3, 21, 2))
    >>> bool(np.allclose(est.mode_prob.sum(axis=-1), 1.0))
    True
    >>> imm.smooth(traj.y, boost.input, traj.t).x.shape  # the two-filter smoother, given the record
    (3, 21, 2)
    """

    _interaction = "mix"
