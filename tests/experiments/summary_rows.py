"""Helpers for reading a reproduction's summary in tests."""

from switchest.experiments.verdict import Verdict, printed_condition, printed_number


def find_row(summary, prefix):
    """The one row whose quantity starts with ``prefix``."""
    found = [r for r in summary.rows if r.quantity.startswith(prefix)]
    assert len(found) == 1, f"{len(found)} rows start with {prefix!r}"
    return found[0]


def close_at_printed(measured, printed, decimals):
    """Equal at the printed precision (half a unit of the last printed digit)."""
    return abs(measured - printed) <= 0.5 * 10.0**-decimals + 1e-12


def assert_rows_compare_only_what_is_printed(summary, *, own_checks: str = "our check"):
    """A referee's reading of a table: printed words are compared with words, printed values
    carry printed digits (no computed float in the paper column), a difference is explained
    exactly when it has a note, and Monte Carlo values say how many runs are behind them
    (rows whose quantity starts with ``own_checks`` are our own consistency checks)."""
    for row in summary.rows:
        printed = printed_number(row.paper)
        if row.paper is not None and printed is None and printed_condition(row.paper) is None:
            assert isinstance(row.measured, str), row  # a printed word against a word of ours
        if printed is not None:
            assert printed.as_tuple().exponent >= -6, row  # printed digits, not a float
        assert (row.verdict is Verdict.EXPLAINED) == (
            row.verdict in (Verdict.EXPLAINED, Verdict.DIFFERS) and bool(row.note.strip()))
        if ("MC" in row.quantity and not row.quantity.startswith(own_checks)
                and not isinstance(row.measured, str)):
            assert row.trials, row
