"""switchest check: runs on every catalog model and agrees with what the papers state."""

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from switchest import SwitchedLinearSystem
from switchest.analysis import critical_interval, lee_assumptions
from switchest.certify import (
    Check,
    _impulsive,
    _jsr,
    _lee,
    _wang_critical_interval,
    certify,
    method_verdicts,
)
from switchest.cli import main
from switchest.estimators import METHOD_NAMES
from switchest.modelfile import ModelSpec
from switchest.models.catalog import catalog
from switchest.models.lee import LEE_SCENARIO
from switchest.switching import IID, Dwell, MarkovContinuous, Schedule

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "models"


def verdicts(name: str) -> dict[str, bool | None]:
    return {c.name.split(" (")[0]: c.verdict for c in certify(catalog()[name])}


@pytest.fixture(scope="module")
def all_checks():
    return {name: certify(spec) for name, spec in catalog().items()}


def test_every_check_runs_on_every_model(all_checks):
    for name, checks in all_checks.items():
        assert len(checks) >= 9, name
        assert not any("could not be evaluated" in c.detail for c in checks), name


def test_zhang_example1_conditions():
    v = verdicts("zhang-two-mode")
    # Zhang §5.1: CQLF for {A_1, A_2} and for {Lambda_1, Lambda_2}; every mismatch tolerated
    assert v["CQLF of the mode matrices"] is True
    assert v["CQLF of the filter error matrices Lambda_i"] is True


def test_zhang_smart_grid_tolerates_only_the_2_3_mismatches():
    checks = {c.name: c for c in certify(catalog()["zhang-smart-grid"])}
    # the paper's unstable A_q
    assert checks["CQLF of the mode matrices (discrete)"].verdict is False
    # the paper's 2 <-> 3, 1-based
    assert "[(1, 2), (2, 1)]" in checks["tolerable mode mismatches"].detail


def test_wang_models_have_unobservable_modes_but_combined_observability():
    for name in ("wang-example1", "wang-ieee5bus"):
        v = verdicts(name)
        assert v["each mode observable"] is False and v["combined observability W_S"] is True


def test_shankar_vehicle_meets_lemma_1_and_the_boost_converter_does_not():
    assert verdicts("shankar-vehicle")["uniform observability under a dwell time"] is True
    boost = {c.name: c for c in certify(catalog()["shankar-boost"])}
    # with H = [0 1], the inductor current is invisible while the switch is closed (mode 0)
    assert "mode(s) [0] unobservable" in boost["each mode observable"].detail


def test_every_margin_is_positive_exactly_when_its_condition_holds(all_checks):
    """One sign convention: positive = holds, <= 0 = fails (an unobservable mode's margin is
    0, not the positive PBH margin of its observable part)."""
    seen = 0
    for name, checks in all_checks.items():
        for c in checks:
            if c.margin is not None and c.verdict is not None:
                assert (c.margin > 0) == c.verdict, (name, c.name, c.margin, c.verdict)
                seen += 1
    assert seen >= 20
    boost = {c.name: c for c in all_checks["shankar-boost"]}
    assert boost["each mode observable"].verdict is False
    assert boost["each mode observable"].margin == 0


def test_checks_name_registered_methods_and_method_verdicts_combine_them(all_checks):
    named = {m for checks in all_checks.values() for c in checks for m in c.methods}
    assert named and named <= set(METHOD_NAMES)

    def check(verdict, *methods):
        return Check("c", "p", verdict, "d", methods=methods)

    said = method_verdicts([check(True, "rsls", "kalman"), check(None, "kalman"),
                            check(True, "impulsive"), check(False, "impulsive", "rsls"),
                            check(True, "min-distance"), check(True)])
    # the registry's order; a failure wins, then an undecided condition; imm is unnamed
    assert said == {"kalman": None, "min-distance": True, "rsls": False, "impulsive": False}
    wang = method_verdicts(all_checks["wang-example1"])
    assert wang["rsls"] is True and wang["min-distance"] is False
    # Shankar's vehicle meets Lemma 1, the boost converter does not (test above)
    assert method_verdicts(all_checks["shankar-vehicle"])["switch-time"] is True
    assert method_verdicts(all_checks["shankar-boost"])["switch-time"] is False


def test_cli_check_states_the_margin_sign_and_ends_with_the_methods(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    assert main(["check", "--model", str(EXAMPLES / "wang-example1.toml")]) == 0
    out = capsys.readouterr().out
    assert "margin: positive when the condition holds, zero or negative when" in out
    words = " ".join(out.split())  # the closing line, unwrapped
    assert words.endswith("where none is defined) methods whose conditions hold: rsls; "
                          "fail: min-distance; undecided or not applicable: kalman, "
                          "switch-time, impulsive; no conditions checked: imm, imm-between, gpb1, "
                          "gpb2, rbpf, imm-ev1")
    assert max(map(len, out.splitlines())) <= 80
    # the paper under each condition rather than a fifth column: 50 lines, not the 70 of five
    assert len(out.splitlines()) <= 55
    assert "│ Wang Assumption 2 " in out


def test_etienne_pairs_are_jointly_observable():
    assert verdicts("etienne-academic")["joint observability of mode pairs"] is True


def test_cli_check_prints_the_table(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "250")
    assert main(["check", "--model", str(EXAMPLES / "zhang-two-mode.toml")]) == 0
    out = capsys.readouterr().out
    assert "tolerable mode mismatches" in out and "holds" in out
    assert main(["check", "--model", str(EXAMPLES / "missing.toml")]) == 2


def test_etienne_theorem_8_certifies_at_least_the_paper_rate():
    checks = {c.name: c for c in certify(catalog()["etienne-academic"])}
    check = checks["impulsive observer under aperiodic sampling"]
    # the paper's beta at its fixed scalars
    assert check.verdict is True and check.margin >= 0.010294


def test_ieee_5bus_critical_interval_is_the_printed_0_7365():
    checks = {c.name: c for c in certify(catalog()["wang-ieee5bus"])}
    check = checks["critical switching interval T_max (i.i.d. modes)"]
    assert "T_max = 0.7365" in check.detail and check.verdict is True


LEE_CHECK = "Lee's assumptions for the given noise bounds"


def lee_check(drop=(), **noise):
    """The Lee check on lee-fsk with noise-table entries dropped or replaced."""
    spec = catalog()["lee-fsk"]
    kept = {k: v for k, v in spec.noise.items() if k not in drop}
    return _lee(replace(spec, noise={**kept, **noise}))


def test_lee_check_gives_the_lee_detection_analysis(all_checks):
    # the lee-detection experiment's quantities: x_min = |x0| - ||b|| u_max horizon,
    # L_i = A_i + 40 I
    s = LEE_SCENARIO
    ref = lee_assumptions(s.system(), u_max=s.u_max, v_max=s.v_max, x_min=s.x_min(), delta=s.delta,
                          Delta=s.Delta, observer_gains=s.observer_gains, min_dwell=s.min_dwell)
    check = {c.name: c for c in all_checks["lee-fsk"]}[LEE_CHECK]
    assert ref.holds is True and check.verdict is True
    assert check.margin == pytest.approx(ref.v_max_allowed - s.v_max, rel=1e-9) and check.margin > 0
    assert f"allowed {ref.v_max_allowed:.4g}" in check.detail
    assert "delta = 0.25 s, Delta = 1 s given" in check.detail


@pytest.mark.parametrize("v_max, failing", [(10.0, "(3), (4)"), (0.11, "(4)")])
def test_lee_check_fails_above_the_allowed_noise_bound(v_max, failing):
    check = lee_check(v_max=v_max)
    assert check.verdict is False and check.margin < 0
    assert f"fail: {failing} at v_max = {v_max:g}" in check.detail


def test_lee_check_with_default_gains_allows_less_noise():
    # pole placement at twice the mode frequencies (lambda_hat = 4 pi) gives E_hat 2.7, not 1.05
    checks = [lee_check(drop=("observer_decay",), v_max=v) for v in (0.1, 0.02)]
    assert [c.verdict for c in checks] == [False, True]
    assert checks[0].margin == pytest.approx(checks[1].margin - 0.08, abs=1e-12)


def test_lee_check_finds_the_smallest_windows_when_none_are_given():
    found = lee_check(drop=("delta", "Delta"))
    assert found.verdict is True and "the smallest satisfying (3)-(4)" in found.detail
    too_noisy = lee_check(drop=("delta", "Delta"), v_max=10.0)
    assert too_noisy.verdict is False and "no window up to 1.3 s satisfies (3)" in too_noisy.detail


def test_lee_check_does_not_apply_without_a_noise_bound(all_checks):
    check = {c.name: c for c in all_checks["shankar-vehicle"]}[LEE_CHECK]
    assert check.verdict is None and "noise.v_max" in check.detail


def test_cli_check_reports_lee_on_the_lee_model(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "250")
    assert main(["check", "--model", str(EXAMPLES / "lee-fsk.toml")]) == 0
    row = next(line for line in capsys.readouterr().out.splitlines() if LEE_CHECK in line)
    assert "holds" in row


@pytest.mark.parametrize("switching, verdict, note", [
    (Schedule([2.0, 4.0], [0, 1, 0]), True, "dwell 2 s > delta + Delta = 1.25 s"),
    (Dwell(2, 1.2, 2.0), False, "dwell 1.2 s <= delta + Delta = 1.25 s"),
    (IID([0.5, 0.5]), False, "dwell 0.0025 s <= delta + Delta"),  # one sampling interval
    (MarkovContinuous([[-1.0, 1.0], [1.0, -1.0]]), False, "no minimum dwell time"),
    (None, True, "Assumption 3: not checked"),
])
def test_lee_check_reads_assumption_3_from_the_switching_model(switching, verdict, note):
    spec = catalog()["lee-fsk"]
    check = _lee(replace(spec, switching=switching))
    assert check.verdict is verdict and note in check.detail


# ------------------------------------------------------------------ large models, rounding
def random_stable_spec(n, *, continuous, rng, switching=None, **sampling):
    """A random 2-mode model: Schur (discrete) or Hurwitz (continuous) modes, 2 outputs."""
    A = rng.standard_normal((2, n, n)) / np.sqrt(n)
    C = rng.standard_normal((2, 2, n))
    if continuous:
        A -= (np.max(np.linalg.eigvals(A).real, axis=1) + 0.5)[:, None, None] * np.eye(n)
        system = SwitchedLinearSystem.continuous(A, C=C, Q=np.zeros((n, n)), R=np.eye(2))
    else:
        A *= 0.9 / np.max(np.abs(np.linalg.eigvals(A)), axis=1)[:, None, None]
        system = SwitchedLinearSystem.discrete(A, C=C, Q=np.eye(n), R=np.eye(2), dt=0.1)
    return ModelSpec(system=system, sampling={"duration": 1.0, **sampling},
                     switching=switching or IID([0.5, 0.5]))


def test_certify_finishes_on_a_200_state_model_and_says_what_it_skipped():
    spec = random_stable_spec(200, continuous=False, rng=np.random.default_rng(0))
    checks = {c.name: c for c in certify(spec)}
    assert not any("could not be evaluated" in c.detail for c in checks.values())
    for name in ("CQLF of the mode matrices (discrete)",
                 "CQLF of the filter error matrices Lambda_i", "tolerable mode mismatches"):
        assert checks[name].verdict is None
        assert re.search(r"skipped: an n = 200 CQLF.* needs ~\d+(\.\d+)? GiB; limit 1 GiB",
                         checks[name].detail)
    jsr = checks["joint spectral radius of the sampled modes"]
    assert "spectral norm" in jsr.detail and jsr.margin is not None
    ms = checks["mean-square stability under i.i.d. modes (open loop)"]
    assert ms.verdict is True and 0 < ms.margin < 1  # matrix-free: no 40000 x 40000 matrix


def test_large_continuous_models_skip_the_critical_interval_and_the_impulsive_lmis():
    rng = np.random.default_rng(1)
    iid = random_stable_spec(200, continuous=True, rng=rng, period=0.1)
    check = _wang_critical_interval(iid)
    assert check.verdict is None
    assert re.search(r"skipped: the critical interval of an n = 200 model .* needs ~\d+ GiB; "
                     r"limit 1 GiB", check.detail)
    dwell = random_stable_spec(200, continuous=True, rng=rng, tau_min=0.05, tau_max=0.1,
                               switching=Dwell(2, 1.0, 2.0))
    check = _impulsive(dwell)
    assert check.verdict is None and "skipped: an n = 200 impulsive-observer LMI" in check.detail


def test_a_period_equal_to_the_critical_interval_is_not_decided_by_rounding():
    spec = catalog()["wang-example1"]
    threshold = critical_interval(spec.system, spec.switching.p).fast_observer
    at = _wang_critical_interval(replace(spec, sampling={**spec.sampling, "period": threshold}))
    assert at.verdict is None and "equals the exact MS threshold" in at.detail
    below = _wang_critical_interval(
        replace(spec, sampling={**spec.sampling, "period": 0.99 * threshold}))
    assert below.verdict is True


def test_jsr_verdict_of_a_marginal_family_is_inconclusive_not_a_coin_toss():
    # rotations: JSR = 1 exactly, computed 1 +- ulps; the outward-rounded bracket holds 1
    th = 0.3
    rot = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    system = SwitchedLinearSystem.discrete(np.stack([rot, rot.T]), C=np.eye(2), Q=np.eye(2),
                                           R=np.eye(2), dt=1.0)
    check = _jsr(ModelSpec(system=system, sampling={"duration": 1.0}))
    assert check.verdict is None and "JSR in [1, 1]" in check.detail  # both bounds print as 1
