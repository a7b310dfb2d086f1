"""Learning without the modes when the switches fall between the samples
(switchest.learn.between_unknown): the E-step on the chain of (mode before, mode after,
instant) against a brute-force oracle, then the boost converter of Shankar et al. §V.A
(examples/models/shankar-boost.toml) fitted without its mode column.

Oracle: over one interval (two samples) the chain's IMM and two-filter smoother merge nothing,
so the E-step is exact there: every member's posterior weight, its joint moments of
:math:`(x_0, x_1)` and the log-likelihood equal those of the stacked Gaussian of
:math:`(x_0, x_1, y_0, y_1)` under each member, conditioned directly, with the member's
transition from :func:`switchest.discretize.interval`. Statistical checks use fixed seeds and
bands of 2 reported standard errors (each misses with probability 4.6 % under the asymptotic
normality of the MLE; the seed makes the outcome deterministic).
"""

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from boost_warnings import boost_fit_warnings_ignored
from scipy.stats import multivariate_normal

from switchest import SwitchedLinearSystem
from switchest.cli import main
from switchest.discretize import interval
from switchest.learn import fit
from switchest.learn.data import record
from switchest.learn.expectation import expectation, log_likelihood
from switchest.modelfile import load_model
from switchest.simulate import simulate

BOOST = Path(__file__).resolve().parents[1] / "examples" / "models" / "shankar-boost.toml"
U = np.array([100.0])  # v_in of the file's description


def small_system(L: int) -> SwitchedLinearSystem:
    gen = np.random.default_rng(L)
    A = gen.normal(size=(L, 2, 2)) - 2.0 * np.eye(2)
    B = gen.normal(size=(L, 2, 1))
    C = gen.normal(size=(L, 1, 2))
    Q = np.array([np.diag(gen.uniform(0.5, 2.0, 2)) for _ in range(L)])
    R = gen.uniform(0.05, 0.2, (L, 1, 1))
    return SwitchedLinearSystem.continuous(A, B, C, Q=Q, R=R)


def brute_force(system, transition, x0, P0, y, u, h, modes, offset, g):
    """Weight, moments of ``(x_1, x_0)`` and likelihood of one member over ``t = (0, h)``."""
    a, b = modes
    L, n = system.n_modes, system.n_states
    tr = interval(system, h, [a, b], [offset]) if a != b else interval(system, h, [a])
    prior = transition[a, b] / (L * (g if a != b else 1))
    # z = (x0, x1, y0, y1) is Gaussian: x1 = F x0 + G u + w, y_k = C x_k + v_k
    F, C0, C1 = tr.F, system.C[a], system.C[b]
    mean_x = np.concatenate([x0, F @ x0 + tr.G @ u])
    cov_x = np.block([[P0, P0 @ F.T], [F @ P0, F @ P0 @ F.T + tr.Qd]])
    H = np.block([[C0, np.zeros_like(C0)], [np.zeros_like(C1), C1]])
    S = H @ cov_x @ H.T + np.block([[system.R[a], np.zeros((1, 1))],
                                    [np.zeros((1, 1)), system.R[b]]])
    gain = cov_x @ H.T @ np.linalg.inv(S)
    yy = y.ravel()
    mean = mean_x + gain @ (yy - H @ mean_x)
    cov = cov_x - gain @ S @ gain.T
    like = multivariate_normal(H @ mean_x, S).logpdf(yy)
    return np.log(prior) + like, mean[n:], mean[:n], cov[n:, n:], cov[:n, :n], cov[n:, :n]


@pytest.mark.parametrize("L, g", [(2, 3), (3, 2)])
def test_one_interval_is_the_exact_posterior(L, g):
    system = small_system(L)
    gen = np.random.default_rng(7)
    transition = gen.dirichlet(np.ones(L), size=L)
    x0, P0 = np.array([0.5, -1.0]), np.diag([1.0, 0.5])
    h = 0.3
    t = np.array([0.0, h])
    y = gen.normal(size=(3, 2, 1))
    u = gen.normal(size=(3, 2, 1))
    mom = expectation(system, transition, x0, P0, record(system, y, u, t, None), grid=g)
    M = L + L * (L - 1) * g
    assert mom.step_weight.shape == (3, 1, M)
    rows = mom.entry[0]
    total = 0.0
    for i in range(3):
        members = [brute_force(system, transition, x0, P0, y[i], u[i, 0], h,
                               mom.table.modes[r], mom.table.offset[r], g) for r in rows]
        log_w = np.array([m[0] for m in members])
        top = log_w.max()
        evidence = top + np.log(np.exp(log_w - top).sum())
        total += evidence
        np.testing.assert_allclose(mom.step_weight[i, 0], np.exp(log_w - evidence), rtol=1e-8,
                                   atol=1e-12)
        for c, (_, x1, x0_c, P1, P0_c, cross) in enumerate(members):
            np.testing.assert_allclose(mom.x1[i, 0, c], x1, rtol=1e-8, atol=1e-10)
            np.testing.assert_allclose(mom.x0[i, 0, c], x0_c, rtol=1e-8, atol=1e-10)
            np.testing.assert_allclose(mom.P1[i, 0, c], P1, rtol=1e-7, atol=1e-10)
            np.testing.assert_allclose(mom.P0[i, 0, c], P0_c, rtol=1e-7, atol=1e-10)
            np.testing.assert_allclose(mom.cross[i, 0, c], cross, rtol=1e-7, atol=1e-10)
        # P(r_1 = b | Y): the members that end in b
        after = mom.table.modes[rows, 1]
        np.testing.assert_allclose(mom.weight[i, 1], [mom.step_weight[i, 0, after == b].sum()
                                                      for b in range(L)], rtol=1e-12)
    np.testing.assert_allclose(mom.loglik, total, rtol=1e-10)
    np.testing.assert_allclose(mom.pairs.sum(), 3.0, rtol=1e-12)
    data = record(system, y, u, t, None)
    np.testing.assert_allclose(log_likelihood(system, transition, x0, P0, data, grid=g), total,
                               rtol=1e-10)


def test_exact_e_step_is_refused_between_the_samples():
    spec = load_model(BOOST)
    t = spec.sample_times(None, rng=0)[:10]
    with pytest.raises(ValueError, match="e_step='exact' enumerates mode sequences that switch "
                                         "at the samples"):
        fit(spec.system, np.zeros((t.size, 1)), U, t, x0=spec.initial[0], P0=spec.initial[1],
            switch_times="between", e_step="exact")


def test_boost_fit_without_the_modes_recovers_R():
    """Library fit from R x 2, Q x 1/2 on 6 trials (1206 samples), the modes unknown: R within
    2 of its standard error (6-10 %), where the E-step that holds each mode over the interval
    after its sample fits R far above 5 (the mistimed switches' error)."""
    spec = load_model(BOOST)
    t = spec.sample_times(None, rng=0)
    sys, (x0, P0) = spec.system, spec.initial
    traj = simulate(sys, spec.switching, t, spec.initial, U, trials=6, rng=11)
    start = sys.replace(Q=0.5 * sys.Q, R=2 * sys.R)
    with boost_fit_warnings_ignored():
        res = fit(start, traj.y, U, t, x0=x0, P0=P0, estimate=("transition", "R", "Q"),
                  shared=("R",), switch_times="between", grid=4, rng=0)
        held = fit(start, traj.y, U, t, x0=x0, P0=P0, estimate=("transition", "R"),
                   shared=("R",), rng=0)
    assert res.converged and res.switch_times == "between"
    se = res.se["R"][0, 0, 0]
    assert 0.04 * 5 < se < 0.12 * 5
    assert abs(res.system.R[0, 0, 0] - 5.0) <= 2 * se
    assert held.system.R[0, 0, 0] > 5.0 + 10 * held.se["R"][0, 0, 0]


def test_boost_round_trip_without_the_mode_column(tmp_path, capsys):
    """``switchest simulate`` on the boost file, the mode column dropped, ``switchest fit
    --shared R --grid 4``: between the samples by default (the file switches in continuous
    time), R within 2 of its printed standard error."""
    data = tmp_path / "boost.csv"
    assert main(["simulate", "--model", str(BOOST), "--input", "100", "--trials", "4",
                 "--seed", "5", "--out", str(data)]) == 0
    pd.read_csv(data).drop(columns=["mode"]).to_csv(data, index=False)
    fitted = tmp_path / "fitted.toml"
    assert main(["fit", "--model", str(BOOST), "--data", str(data), "--estimate",
                 "transition,R", "--shared", "R", "--grid", "4", "--out", str(fitted)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert ("unknown modes, switches between the samples (instants marginalized on a grid of "
            "4)") in out
    row = out.split("R all modes [0,0] │")[1].split("│")
    R, se = float(row[0]), float(row[1])
    assert R == pytest.approx(load_model(fitted).system.R[0, 0, 0], rel=1e-5)
    assert 0.04 * 5 < se < 0.15 * 5 and abs(R - 5.0) <= 2 * se
    assert re.search(r"transition 0→1 │ \S+ │ \S+ │", out)


def test_fit_at_the_samples_of_a_file_that_switches_between_them_warns(tmp_path, capsys):
    """Without the modes no check of the data tells a fit at the samples that the file's
    switches fall between them (the E-step's mixture absorbs them): the CLI says so from the
    model file, and not when the timing is the file's."""
    data = tmp_path / "boost.csv"
    assert main(["simulate", "--model", str(BOOST), "--duration", "0.02", "--seed", "2",
                 "--out", str(data)]) == 0
    pd.read_csv(data).drop(columns=["mode"]).to_csv(data, index=False)
    said = {}
    for timing in ("samples", "between"):
        capsys.readouterr()
        with boost_fit_warnings_ignored():
            assert main(["fit", "--model", str(BOOST), "--data", str(data), "--estimate", "R",
                         "--switch-times", timing, "--grid", "2", "--max-iter", "2",
                         "--out", str(tmp_path / f"{timing}.toml")]) == 0
        said[timing] = " ".join(capsys.readouterr().err.split())
    assert "warning: the model file's switches fall between the samples" in said["samples"]
    assert "--switch-times between models them" in said["samples"]
    assert "switches fall between the samples" not in said["between"]
