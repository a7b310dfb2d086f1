"""largest_feasible: bracketing and bisection against a known threshold; the solution it keeps."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from switchest.analysis import largest_feasible


def _threshold(a_star: float):
    """A monotone problem feasible exactly on ``a <= a_star``; the solution records its point."""
    calls: list[float] = []

    def solve(a: float) -> dict:
        calls.append(a)
        return {"a": a, "ok": a <= a_star}

    return solve, calls


@given(st.floats(-5.0, 5.0), st.floats(0.0, 30.0), st.sampled_from([1e-3, 1e-6]))
def test_brackets_and_bisects_to_the_threshold(start, above, tol):
    solve, _ = _threshold(start + above)
    a, sol = largest_feasible(solve, lambda s: s["ok"], start, tol=tol, step=0.25, doublings=10)
    assert start + above - tol <= a <= start + above
    assert sol["a"] == a and sol["ok"]  # the solution returned is the one at the answer


def test_infeasible_start_gives_none_after_one_solve():
    solve, calls = _threshold(-1.0)
    assert largest_feasible(solve, lambda s: s["ok"], 0.0, tol=1e-3, step=1.0, doublings=5) is None
    assert calls == [0.0]


def test_unbracketed_threshold_returns_the_last_doubling():
    solve, calls = _threshold(np.inf)
    a, _ = largest_feasible(solve, lambda s: s["ok"], 0.0, tol=1e-3, step=1.0, doublings=4)
    assert a == 1.0 + 2.0 + 4.0 + 8.0
    assert calls == [0.0, 1.0, 3.0, 7.0, 15.0]  # no bisection without an infeasible end


def test_solves_in_the_documented_order():
    solve, calls = _threshold(0.6)
    a, _ = largest_feasible(solve, lambda s: s["ok"], 0.0, tol=0.1, step=0.25, doublings=10)
    assert calls == [0.0, 0.25, 0.75, 0.5, 0.625, 0.5625]
    assert a == 0.5625


@pytest.mark.parametrize(("kwargs", "exc", "match"), [
    ({"tol": 0.0, "step": 1.0, "doublings": 3}, ValueError, "tol must be a finite positive"),
    ({"tol": 1e-3, "step": -1.0, "doublings": 3}, ValueError, "step must be a finite positive"),
    ({"tol": 1e-3, "step": 1.0, "doublings": 0}, ValueError, "doublings must be a positive int"),
    ({"tol": 1e-3, "step": 1.0, "doublings": 2.0}, ValueError, "doublings must be a positive int"),
    ({"tol": "1", "step": 1.0, "doublings": 2}, TypeError, "tol must be a real scalar"),
])
def test_bad_input(kwargs, exc, match):
    solve, _ = _threshold(1.0)
    with pytest.raises(exc, match=match):
        largest_feasible(solve, lambda s: s["ok"], 0.0, **kwargs)
