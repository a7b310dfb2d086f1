"""The old names of the analysis stay importable, warn, and give the same objects; ``holds``,
the one verdict field, agrees with the field it replaced."""

import importlib
import sys
import warnings

import numpy as np
import pytest

import switchest.analysis as analysis
from switchest.analysis import (
    autonomous_stability,
    cqlf,
    dwell_time_observability,
    mismatch_dynamics,
    ms_stable_iid,
    tolerance_region,
    uniform_observability,
    unstable_components,
)
from switchest.models.zhang import zhang_two_mode
from switchest.system import SwitchedLinearSystem

# old module path -> the module it became
MOVED = {
    "bias": "mode_mismatch",
    "bounds": "switch_time_bounds",
    "impulsive": "impulsive_lmis",
    "lee": "min_distance_design",
    "ms_design": "subsystem_observers",
}


@pytest.mark.parametrize("old", sorted(analysis.DEPRECATED_NAMES))
def test_a_theorem_numbered_name_warns_and_is_the_renamed_object(old):
    new = analysis.DEPRECATED_NAMES[old]
    with pytest.warns(DeprecationWarning, match=f"analysis.{old} is deprecated; use .*{new}"):
        value = getattr(analysis, old)
    assert value is getattr(analysis, new)
    assert old not in analysis.__all__ and new in analysis.__all__


def test_from_import_of_an_old_name_warns():
    with pytest.warns(DeprecationWarning, match="theorem4_bound is deprecated"):
        from switchest.analysis import theorem4_bound
    assert theorem4_bound is analysis.mismatch_bias_bound


def test_an_unknown_name_raises_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'theorem99_rate'"):
        analysis.theorem99_rate  # noqa: B018 - the lookup is the test


@pytest.mark.parametrize("old", sorted(MOVED))
def test_an_old_module_path_warns_and_gives_the_new_modules_objects(old, monkeypatch):
    new = importlib.import_module(f"switchest.analysis.{MOVED[old]}")
    monkeypatch.delitem(sys.modules, f"switchest.analysis.{old}", raising=False)
    with pytest.warns(DeprecationWarning, match=f"analysis.{old} is deprecated.*{MOVED[old]}"):
        shim = importlib.import_module(f"switchest.analysis.{old}")
    assert set(new.__all__) <= set(shim.__all__)
    for name in new.__all__:
        assert getattr(shim, name) is getattr(new, name), name
    for old_name, new_name in analysis.DEPRECATED_NAMES.items():
        if old_name in shim.__all__:
            assert getattr(shim, old_name) is getattr(new, new_name)


def test_the_old_module_paths_keep_the_renamed_functions():
    """What callers import from the old paths today (experiments, certify); the warning
    on import is tested above (a module warns once, at its first import)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from switchest.analysis.bias import lemma3_hypotheses, theorem4_bound
        from switchest.analysis.bounds import lemma2_bounds
        from switchest.analysis.impulsive import ClosedLoopLMIs, theorem8_rate, theorem10_rate
        from switchest.analysis.ms_design import critical_interval_nbytes
    assert (lemma3_hypotheses, theorem4_bound, lemma2_bounds, theorem8_rate, theorem10_rate) == (
        analysis.filter_stability_hypotheses, analysis.mismatch_bias_bound,
        analysis.switch_matrix_bounds, analysis.impulsive_observer_decay_rate,
        analysis.impulsive_closed_loop_decay_rate)
    assert ClosedLoopLMIs.__module__ == "switchest.analysis.impulsive_lmis"
    assert critical_interval_nbytes.__module__ == "switchest.analysis.subsystem_observers"


# ------------------------------------------------------------------ one verdict field
def old(result, field: str):
    """The deprecated field ``field`` of ``result``: it warns, naming itself."""
    with pytest.warns(DeprecationWarning, match=rf"\.{field} is deprecated"):
        return getattr(result, field)


def test_holds_agrees_with_the_old_fields_of_stability_certificates():
    stable, unstable = np.diag([0.5, 0.2])[None], np.diag([1.5, 0.2])[None]
    for A in (stable, unstable):
        cert = cqlf(A, "discrete")
        assert old(cert, "feasible") is cert.holds
        ms = ms_stable_iid(A, [1.0])
        assert old(ms, "stable") is ms.holds
    assert cqlf(stable, "discrete").holds and not cqlf(unstable, "discrete").holds


def test_holds_agrees_with_the_old_fields_of_the_mismatch_analysis():
    system = zhang_two_mode()
    d = mismatch_dynamics(system)
    for lam in ([[0.9, 0.2], [0.1, 0.8]], [[0.1, 0.9], [0.9, 0.1]]):
        check = tolerance_region(d, lam, bound=0.5, eta=2.0, sup_input=1.0)
        assert old(check, "inside") is check.holds
    components = unstable_components(system)
    assert components.conclusive is (components.holds is not None)


def test_uniform_observability_holds_is_the_old_observable():
    A, H = np.array([[0.0, 2.0], [-2.0, 0.0]]), np.array([[1.0, 0.0]])
    for T in (0.3, np.pi / 2.0):  # observable; a sampling period that loses observability
        res = uniform_observability(A, H, T)
        assert old(res, "observable") is res.holds
    assert not uniform_observability(A, H, np.pi / 2.0).holds


def test_dwell_time_holds_is_the_proven_lemma_and_the_printed_one_is_named_as_such():
    """Between ``h_bar T`` and ``(h_bar + 1) T`` the printed Lemma 1 claims observability
    that the corrected statement does not give: ``holds`` is the corrected one."""
    A = np.stack([[[0.0, 1.0], [0.0, 0.0]], [[-1.0, 0.0], [0.0, -2.0]]])
    system = SwitchedLinearSystem.continuous(A, C=np.array([[1.0, 1.0]]))
    T = 0.5  # h_bar = 1 here (tests/analysis/test_observability.py)
    between = dwell_time_observability(system, T, tau_d=0.75)
    assert between.printed_lemma_holds and not between.holds
    assert old(between, "holds_corrected") is between.holds
    enough = dwell_time_observability(system, T, tau_d=1.0)
    assert enough.holds and enough.printed_lemma_holds and old(enough, "holds_corrected")


def test_theorem_numbered_fields_are_read_under_their_new_names():
    system = zhang_two_mode()
    stab = autonomous_stability(mismatch_dynamics(system), [[0.9, 0.2], [0.1, 0.8]])
    assert old(stab, "lemma3") is stab.each_mode_contracts
    assert old(stab, "lemma4") is stab.one_mode_per_column
