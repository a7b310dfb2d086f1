"""Helpers for reading a reproduction's summary in tests."""


def find_row(summary, prefix):
    """The one row whose quantity starts with ``prefix``."""
    found = [r for r in summary.rows if r.quantity.startswith(prefix)]
    assert len(found) == 1, f"{len(found)} rows start with {prefix!r}"
    return found[0]


def close_at_printed(measured, printed, decimals):
    """Equal at the printed precision (half a unit of the last printed digit)."""
    return abs(measured - printed) <= 0.5 * 10.0**-decimals + 1e-12
