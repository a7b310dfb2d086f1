"""Shankar et al. Lemma 2 (eqs (11)-(12)) and Remark 1 (eqs (21)-(22)), checked against
exact matrix exponentials before being trusted."""

import numpy as np
import pytest

from switchest.analysis.switch_time_bounds import estimation_error_bounds, switch_matrix_bounds

N_CASES = 10_000


def _phi_gamma(A, B, t):
    """Oracle: e^{A t} and int_0^t e^{A s} ds B from one augmented exponential, batched."""
    from scipy.linalg import expm

    n, l = A.shape[-1], B.shape[-1]
    M = np.zeros((*A.shape[:-2], n + l, n + l))
    M[..., :n, :n] = A
    M[..., :n, n:] = B
    E = expm(M * t[..., None, None])
    return E[..., :n, :n], E[..., :n, n:]


def _exact_FG(Ai, Aj, Bi, Bj, T, ts):
    """Shankar et al. eqs (4)-(5): F = e^{Aj (T - ts)} e^{Ai ts}, G = ... (exact)."""
    Fi, Gi = _phi_gamma(Ai, Bi, ts)
    Fj, Gj = _phi_gamma(Aj, Bj, T - ts)
    return Fj @ Fi, Fj @ Gi + Gj


def _random_cases(seed):
    """10 000 random switches, in four groups by state size n = 1..4 (inputs l = 2)."""
    rng = np.random.default_rng(seed)
    out = []
    per = N_CASES // 4
    for n in (1, 2, 3, 4):
        scale = np.exp(rng.uniform(np.log(0.05), np.log(3.0), size=(per, 1, 1))) / np.sqrt(n)
        Ai = rng.normal(size=(per, n, n)) * scale
        Aj = rng.normal(size=(per, n, n)) * scale
        Bi = rng.normal(size=(per, n, 2))
        Bj = rng.normal(size=(per, n, 2))
        T = np.exp(rng.uniform(np.log(1e-3), np.log(3.0), size=per))
        t_bar = rng.uniform(0, 1, size=per) * T
        t_hat = rng.uniform(0, 1, size=per) * T
        F, G = _exact_FG(Ai, Aj, Bi, Bj, T, t_bar)
        Fh, Gh = _exact_FG(Ai, Aj, Bi, Bj, T, t_hat)
        out.append(
            {
                "Ai": Ai,
                "Aj": Aj,
                "Bi": Bi,
                "Bj": Bj,
                "T": T,
                "t_bar": t_bar,
                "t_hat": t_hat,
                "dF": np.linalg.norm(Fh - F, 2, axis=(1, 2)),
                "dG": np.linalg.norm(Gh - G, 2, axis=(1, 2)),
            }
        )
    return out


CASES = _random_cases(2024)


def _violations(form, exact_F_in_G):
    counts = {"F": 0, "F_uniform": 0, "G": 0}
    ratio = {"F": 0.0, "G": 0.0}
    for c in CASES:
        b = switch_matrix_bounds(
            c["Ai"],
            c["Aj"],
            c["Bi"],
            c["Bj"],
            T=c["T"],
            t_bar=c["t_bar"],
            t_hat=c["t_hat"],
            form=form,
            F_error=c["dF"] if exact_F_in_G else None,
        )
        slack = 1e-12 * (1 + b.F)  # round-off in the exact differences
        counts["F"] += int(np.sum(c["dF"] > b.F + slack))
        counts["F_uniform"] += int(np.sum(c["dF"] > b.F_uniform + slack))
        counts["G"] += int(np.sum(c["dG"] > b.G + 1e-12 * (1 + b.G)))
        for key, exact, bound in (("F", c["dF"], b.F), ("G", c["dG"], b.G)):
            ok = bound > 1e-9
            ratio[key] = max(ratio[key], float(np.max(exact[ok] / bound[ok])))
    return counts, ratio


@pytest.mark.parametrize("form", ["printed", "proof"])
@pytest.mark.parametrize("exact_F_in_G", [False, True])
def test_lemma2_bounds_hold_on_10000_random_switches(form, exact_F_in_G):
    counts, ratio = _violations(form, exact_F_in_G)
    print(f"form={form} exact_F_in_G={exact_F_in_G}: violations {counts}, max exact/bound {ratio}")
    assert counts == {"F": 0, "F_uniform": 0, "G": 0}
    # both bounds are tight as T -> 0 (F~ ~ (A_i - A_j) t~, G~ ~ (B_i - B_j) t~):
    # the check could fail
    assert ratio["F"] > 0.99 and ratio["G"] > 0.99


def test_bound_built_on_the_printed_Y_would_fail():
    # The proof writes Y = -A(j) t~ - A(i) t~; with A(j) = -A(i) that bound is zero while F~ is not.
    rng = np.random.default_rng(3)
    Ai = rng.normal(size=(2, 2))
    Aj = -Ai
    B = np.zeros((2, 1))
    T, t_bar, t_hat = np.array([0.5]), np.array([0.1]), np.array([0.3])
    F, _ = _exact_FG(Ai[None], Aj[None], B[None], B[None], T, t_bar)
    Fh, _ = _exact_FG(Ai[None], Aj[None], B[None], B[None], T, t_hat)
    dF = np.linalg.norm((Fh - F)[0], 2)
    wrong_Y_norm = np.linalg.norm(-Aj - Ai, 2) * abs(t_hat - t_bar)[0]
    assert wrong_Y_norm == 0.0 and dF > 0.1
    b = switch_matrix_bounds(Ai, Aj, B, B, T=T[0], t_bar=t_bar[0], t_hat=t_hat[0])
    assert dF <= b.F  # the printed (11), with ||A(j) - A(i)||, holds


def test_first_term_of_12_misses_a_time_factor():
    # The proof's first term ||F~ int_0^{t_hat} e^{-A(i) s} ds B(i)|| can exceed the printed
    # ||F~|| e^{||A(i)|| T} ||B(i)||: with A(i) = 0 it is ||F~ B(i)|| t_hat.
    Ai = np.zeros((1, 1))
    Aj = np.array([[-0.2]])
    Bi = np.array([[1.0]])
    T, t_bar, t_hat = 5.0, 1.0, 4.5
    dF = abs(np.exp(-0.2 * (T - t_hat)) - np.exp(-0.2 * (T - t_bar)))
    first_true = dF * t_hat * 1.0
    first_printed = dF * np.exp(0.0 * T) * 1.0
    assert first_true > 4 * first_printed
    b = switch_matrix_bounds(Ai, Aj, Bi, np.zeros((1, 1)), T=T, t_bar=t_bar, t_hat=t_hat,
                             F_error=dF)
    G, Gh = (
        _exact_FG(Ai[None], Aj[None], Bi[None], np.zeros((1, 1, 1)), np.array([T]), np.array([t]))[
            1
        ]
        for t in (t_bar, t_hat)
    )
    assert np.abs(Gh - G).max() <= b.G  # the whole printed (12) still holds here


def test_lemma2_batches_and_broadcasts():
    c = CASES[1]
    b = switch_matrix_bounds(
        c["Ai"], c["Aj"], c["Bi"], c["Bj"], T=c["T"], t_bar=c["t_bar"], t_hat=c["t_hat"]
    )
    one = switch_matrix_bounds(
        c["Ai"][7],
        c["Aj"][7],
        c["Bi"][7],
        c["Bj"][7],
        T=c["T"][7],
        t_bar=c["t_bar"][7],
        t_hat=c["t_hat"][7],
    )
    assert b.F.shape == (N_CASES // 4,) and one.F.shape == ()
    assert one.F == pytest.approx(b.F[7]) and one.G == pytest.approx(b.G[7])
    zero = switch_matrix_bounds(
        c["Ai"][0], c["Aj"][0], c["Bi"][0], c["Bj"][0], T=1.0, t_bar=0.4, t_hat=0.4
    )
    assert zero.F == 0.0 and zero.G == 0.0  # no switching-time error, no matrix error


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"t_bar": 1.5}, "t_bar must lie in"),
        ({"t_hat": -0.1}, "t_hat must lie in"),
        ({"T": 0.0}, "T must be positive"),
        ({"form": "tight"}, "form must be 'printed' or 'proof'"),
        ({"B_j": np.ones((3, 1))}, r"B_j must have shape \(\.\.\., 2, l\)"),
        ({"A_j": np.eye(3)}, "A_i and A_j must be square with one shape"),
    ],
)
def test_lemma2_rejects_bad_input(kwargs, match):
    args = {
        "A_i": np.eye(2),
        "A_j": -np.eye(2),
        "B_i": np.ones((2, 1)),
        "B_j": np.ones((2, 1)),
        "T": 1.0,
        "t_bar": 0.3,
        "t_hat": 0.6,
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        switch_matrix_bounds(**args)


# ------------------------------------------------------------------ Remark 1
def test_remark1_bounds_hold_and_are_tight_at_zero_gain():
    rng = np.random.default_rng(11)
    n, m, N = 3, 2, 500
    K = rng.normal(size=(N, n, m))
    H = rng.normal(size=(m, n))
    X = rng.normal(size=(N, n, n))
    Omega = X @ np.swapaxes(X, 1, 2)
    Y = rng.normal(size=(m, m))
    R = Y @ Y.T + 0.1 * np.eye(m)
    z_mean = rng.normal(size=(N, n))
    IKH = np.eye(n) - K @ H
    e_mean = np.einsum("kab,kb->ka", IKH, z_mean)  # from eq. (13), E[v] = 0
    Sigma = IKH @ Omega @ np.swapaxes(IKH, 1, 2) + K @ R @ np.swapaxes(K, 1, 2)  # eq. (16)
    b = estimation_error_bounds(
        K,
        H,
        mean_prediction_error=np.linalg.norm(z_mean, axis=1),
        prediction_mse_trace=np.trace(Omega, axis1=1, axis2=2),
        R=R,
    )
    assert b.mean.shape == (N,)
    assert np.all(np.linalg.norm(e_mean, axis=1) <= b.mean * (1 + 1e-12))
    assert np.all(np.trace(Sigma, axis1=1, axis2=2) <= b.trace * (1 + 1e-12))
    # K = 0: e = z, Sigma = Omega, both bounds are equalities
    b0 = estimation_error_bounds(
        np.zeros((n, m)), H, mean_prediction_error=2.0, prediction_mse_trace=np.trace(Omega[0]), R=R
    )
    assert b0.mean == pytest.approx(2.0) and b0.trace == pytest.approx(np.trace(Omega[0]))


def test_remark1_rejects_bad_input():
    K, H, R = np.zeros((2, 1)), np.ones((1, 2)), np.eye(1)
    with pytest.raises(ValueError, match=r"H must have shape \(1, 2\)"):
        estimation_error_bounds(
            K, np.ones((2, 2)), mean_prediction_error=1.0, prediction_mse_trace=1.0, R=R
        )
    with pytest.raises(ValueError, match="mean_prediction_error must be non-negative"):
        estimation_error_bounds(K, H, mean_prediction_error=-1.0, prediction_mse_trace=1.0, R=R)
    with pytest.raises(ValueError, match="R must be symmetric positive semidefinite"):
        estimation_error_bounds(
            K, H, mean_prediction_error=1.0, prediction_mse_trace=1.0, R=-np.eye(1)
        )
