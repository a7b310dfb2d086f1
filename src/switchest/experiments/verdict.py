"""Whether a reproduced value matches the paper, judged at the paper's printed precision.

A paper prints a number with some digits: ``0.9904`` claims four decimals, ``187`` none. Ours
*reproduces* it when it rounds to those digits (it lies within half a unit of the last printed
digit). A Monte Carlo value, known only to its standard error, is *within sampling error* when
its 95 % interval (widened by that half unit) covers the printed value. Anything else *differs*;
a difference whose row carries a note (a misprint, another reading of the setup) is *explained*.
Words (``"feasible"``, ``"stable"``) reproduce when they are the same word. A printed claim
written as a condition (``"< 4"``, ``"≤ 1 (bounded)"``: an operator, a number, an optional
comment) is reproduced when ours satisfies it, within sampling error when it does within 1.96
standard errors. A row without a printed value is *derived*: shown, never counted.
"""

from __future__ import annotations

import math
import operator
import re
from decimal import Decimal, InvalidOperation
from enum import StrEnum

__all__ = ["Verdict", "printed_condition", "printed_number", "printed_half_unit", "judge", "Z_95"]

Z_95 = 1.959963984540054
"""The two-sided 95 % quantile of the standard normal: the half-width of an interval in
standard errors."""


class Verdict(StrEnum):
    """How a row compares with the paper."""

    REPRODUCED = "reproduced"
    WITHIN_ERROR = "within sampling error"
    EXPLAINED = "differs, explained"
    DIFFERS = "differs"
    DERIVED = "derived"


def printed_number(paper) -> Decimal | None:
    """The paper's value as the decimal it prints, or None for a word (or no value).

    A float stands for its shortest decimal form (``0.9904``); a string keeps every digit it
    holds, trailing zeros included (``"0.150"`` claims three decimals, ``0.15`` two).
    """
    if paper is None or isinstance(paper, bool):
        return None
    if isinstance(paper, (int, float)):
        if not math.isfinite(paper):
            return None
        return Decimal(repr(float(paper))) if isinstance(paper, float) else Decimal(paper)
    if isinstance(paper, str):
        try:
            value = Decimal(paper.strip().replace("−", "-"))
        except InvalidOperation:
            return None
        return value if value.is_finite() else None
    raise TypeError(f"a printed value must be a number, a string or None, got {type(paper)}")


_OPERATORS = {"<": operator.lt, "<=": operator.le, "≤": operator.le, ">": operator.gt,
              ">=": operator.ge, "≥": operator.ge}
_CONDITION = re.compile(r"\s*(<=|>=|<|>|≤|≥)\s*([-+−]?[0-9.]+(?:[eE][-+]?[0-9]+)?)(?:\s.*)?$")


def printed_condition(paper) -> tuple[str, float] | None:
    """``(operator, bound)`` of a printed condition such as ``"≤ 1 (bounded)"``, else None."""
    if not isinstance(paper, str):
        return None
    match = _CONDITION.match(paper)
    if match is None:
        return None
    return match.group(1), float(match.group(2).replace("−", "-"))


def printed_half_unit(printed: Decimal) -> float:
    """Half a unit of the last printed digit: ``0.00005`` for ``0.9904``, ``0.5`` for ``187``."""
    return 0.5 * 10.0 ** printed.as_tuple().exponent


def judge(paper, measured, *, se: float | None = None, note: str = "") -> Verdict:
    """The verdict on ``measured`` against the printed ``paper`` value.

    Parameters
    ----------
    paper : float, int, str or None
        The printed value (see :func:`printed_number`), a word, or None (not printed).
    measured : float or str
        Ours: a number or a word.
    se : float, optional
        Standard error of a Monte Carlo ``measured``.
    note : str
        The row's note; a difference with a note counts as explained.
    """
    if paper is None:
        return Verdict.DERIVED
    printed = printed_number(paper)
    differs = Verdict.EXPLAINED if note.strip() else Verdict.DIFFERS
    condition = printed_condition(paper)
    if condition is not None:
        return _judge_condition(condition, measured, se, differs)
    if printed is None:  # a word
        same = isinstance(measured, str) and _word(measured) == _word(str(paper))
        return Verdict.REPRODUCED if same else differs
    if isinstance(measured, str) or isinstance(measured, bool) or measured is None:
        return differs
    value = float(measured)
    if not math.isfinite(value):
        return differs
    gap, half = abs(value - float(printed)), printed_half_unit(printed)
    if gap <= half * (1 + 1e-9):
        return Verdict.REPRODUCED
    if se is not None and math.isfinite(se) and gap <= Z_95 * se + half:
        return Verdict.WITHIN_ERROR
    return differs


def _judge_condition(condition: tuple[str, float], measured, se: float | None,
                     differs: Verdict) -> Verdict:
    """A number against a printed ``(operator, bound)``; a Monte Carlo one within error when
    moving it by 1.96 standard errors towards the bound satisfies the condition."""
    if isinstance(measured, (str, bool)) or measured is None or not math.isfinite(measured):
        return differs
    holds, bound = _OPERATORS[condition[0]], condition[1]
    value = float(measured)
    if holds(value, bound):
        return Verdict.REPRODUCED
    if se is not None and math.isfinite(se):
        nearer = value - Z_95 * se if value > bound else value + Z_95 * se
        if holds(nearer, bound) or nearer == bound:
            return Verdict.WITHIN_ERROR
    return differs


def _word(text: str) -> str:
    return " ".join(text.lower().split())
