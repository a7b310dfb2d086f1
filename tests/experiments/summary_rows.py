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
    exactly when it has a reason, a value matched by a fitted reading is never reproduced, and
    Monte Carlo values say how many runs are behind them
    (rows whose quantity starts with ``own_checks`` are our own consistency checks)."""
    for row in summary.rows:
        printed = printed_number(row.paper)
        if row.paper is not None and printed is None and printed_condition(row.paper) is None:
            assert isinstance(row.measured, str), row  # a printed word against a word of ours
        if printed is not None:
            assert printed.as_tuple().exponent >= -6, row  # printed digits, not a float
        assert (row.verdict is Verdict.EXPLAINED) == (
            row.verdict in (Verdict.EXPLAINED, Verdict.DIFFERS) and row.explanation is not None)
        if row.fit is not None:
            assert row.verdict is not Verdict.REPRODUCED, row
        if ("MC" in row.quantity and not row.quantity.startswith(own_checks)
                and not isinstance(row.measured, str)):
            assert row.trials, row


def assert_every_printed_item_judged(paper, summaries):
    """The paper's declared count of printed items is met: the items the summaries judge plus
    the declared not-computed ones make N, and no row judges an item twice as primary at the
    same quantity."""
    from switchest.experiments.items import PAPERS, items_of, tally

    pairs = [(s.experiment, row) for s in summaries for row in s.rows]
    t = tally(paper, items_of(paper, pairs))
    assert t.printed == PAPERS[paper].printed
    assert t.judged + len(t.not_computed) == t.printed, (t.judged, sorted(
        i.key for i in items_of(paper, pairs)))
    for item in items_of(paper, pairs):
        quantities = [r.quantity for r in item.primary]
        assert len(quantities) == len(set(quantities)), item.key
