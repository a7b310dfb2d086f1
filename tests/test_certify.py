"""switchest check: runs on every catalog model and agrees with what the papers state."""

from pathlib import Path

import pytest

from switchest.certify import certify
from switchest.cli import main
from switchest.models.catalog import catalog

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
    assert checks["CQLF of the mode matrices (discrete)"].verdict is False  # the paper's unstable A_q
    assert "[(1, 2), (2, 1)]" in checks["tolerable mode mismatches"].detail  # paper's 2 <-> 3, 1-based


def test_wang_models_have_unobservable_modes_but_combined_observability():
    for name in ("wang-example1", "wang-ieee5bus"):
        v = verdicts(name)
        assert v["each mode observable"] is False and v["combined observability W_S"] is True


def test_shankar_vehicle_meets_lemma_1_and_the_boost_converter_does_not():
    assert verdicts("shankar-vehicle")["uniform observability under a dwell time"] is True
    boost = {c.name: c for c in certify(catalog()["shankar-boost"])}
    # with H = [0 1], the inductor current is invisible while the switch is closed (mode 0)
    assert "mode(s) [0] unobservable" in boost["each mode observable"].detail


def test_etienne_pairs_are_jointly_observable():
    assert verdicts("etienne-academic")["joint observability of mode pairs"] is True


def test_cli_check_prints_the_table(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "250")
    assert main(["check", "--model", str(EXAMPLES / "zhang-two-mode.toml")]) == 0
    out = capsys.readouterr().out
    assert "tolerable mode mismatches" in out and "holds" in out
    assert main(["check", "--model", str(EXAMPLES / "missing.toml")]) == 2


def test_etienne_theorem_8_certifies_at_least_the_paper_rate():
    check = {c.name: c for c in certify(catalog()["etienne-academic"])}["impulsive observer under aperiodic sampling"]
    assert check.verdict is True and check.margin >= 0.010294  # the paper's beta at its fixed scalars


def test_ieee_5bus_critical_interval_is_the_printed_0_7365():
    check = {c.name: c for c in certify(catalog()["wang-ieee5bus"])}["critical switching interval T_max (i.i.d. modes)"]
    assert "T_max = 0.7365" in check.detail and check.verdict is True
