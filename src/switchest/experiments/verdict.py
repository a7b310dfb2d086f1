"""Whether a reproduced value matches the paper, judged at the paper's printed precision.

A paper prints a number with some digits: ``0.9904`` claims four decimals, ``187`` none. Ours
*reproduces* it when it rounds to those digits (it lies within half a unit of the last printed
digit). A Monte Carlo value, known only to its standard error, is *within sampling error* when
its 95 % interval (widened by that half unit) covers the printed value. Anything else *differs*.
A difference is *explained* only by a :class:`Reason` from a small declared vocabulary, with its
evidence (:class:`Explanation`); run details (timings, trial counts, the settings used) never
change a verdict. A value obtained by choosing a parameter so that it matches the paper is
*matched by a fitted reading* (:class:`Fit`): never counted as reproduced.
Words (``"feasible"``, ``"stable"``) reproduce when they are the same word. A printed claim
written as a condition (``"< 4"``, ``"≤ 1 (bounded)"``: an operator, a number, an optional
comment) is reproduced when ours satisfies it, within sampling error when it does within 1.96
standard errors. A row without a printed value is *derived*: shown, never counted.
"""

from __future__ import annotations

import math
import operator
import re
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from enum import StrEnum

__all__ = ["Explanation", "FALLS", "Fit", "Reason", "Verdict", "compared_as_words",
           "fall_with_error", "judge",
           "printed_condition",
           "printed_half_unit", "printed_number", "Z_95"]

Z_95 = 1.959963984540054
"""The two-sided 95 % quantile of the standard normal: the half-width of an interval in
standard errors."""


class Verdict(StrEnum):
    """How a row (or a printed item) compares with the paper."""

    REPRODUCED = "reproduced"
    WITHIN_ERROR = "within sampling error"
    FITTED = "matched by a fitted reading"
    EXPLAINED = "differs, explained"
    DIFFERS = "differs, unexplained"
    NOT_COMPUTED = "not computed"
    DERIVED = "derived"


class Reason(StrEnum):
    """Why a value differs from the printed one: the only grounds on which a difference counts
    as explained. Each is given with its evidence (:class:`Explanation`)."""

    MISPRINT = "misprint in the paper"
    ROUNDING = "the paper's rounding or truncation"
    AMBIGUOUS = "ambiguous printed formula, read both ways"
    UNSTATED = "unstated setting of the paper"
    PAPER_ERROR = "proven error in the paper"
    SAMPLING = "sampling error beyond the printed precision"


@dataclass(frozen=True)
class Explanation:
    """A :class:`Reason` for a difference and the evidence for it (what shows the reason holds:
    the other reading's value, the proof, the paper's own sampling error ...)."""

    reason: Reason
    evidence: str

    def __post_init__(self):
        if not isinstance(self.reason, Reason):
            raise TypeError(f"reason must be a Reason, got {self.reason!r}")
        if not isinstance(self.evidence, str) or not self.evidence.strip():
            raise ValueError("evidence must be a non-empty text: a reason without evidence "
                             "explains nothing")

    def __str__(self) -> str:
        return f"{self.reason.value}: {self.evidence}"


@dataclass(frozen=True)
class Fit:
    """A value computed with a parameter chosen so that it matches the printed one.

    Attributes
    ----------
    parameter : str
        What was chosen, and its value (``"η·sup‖u‖ = 1.04"``).
    unique : bool
        Whether that choice is the only one that matches (the fit then identifies the paper's
        unstated setting; otherwise it only shows that one exists).
    evidence : str
        How uniqueness was decided (the other values that also match, or the scan that found
        none).
    """

    parameter: str
    unique: bool
    evidence: str = ""

    def __post_init__(self):
        if not isinstance(self.parameter, str) or not self.parameter.strip():
            raise ValueError("parameter must name the fitted parameter and its value")
        if not isinstance(self.unique, bool):
            raise TypeError(f"unique must be a bool, got {self.unique!r}")

    def __str__(self) -> str:
        unique = "unique" if self.unique else "not unique"
        return f"fitted {self.parameter} ({unique}" + (f": {self.evidence})" if self.evidence
                                                       else ")")


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


def judge(paper, measured, *, se: float | None = None, explanation: Explanation | None = None,
          fit: Fit | None = None) -> Verdict:
    """The verdict on ``measured`` against the printed ``paper`` value.

    Parameters
    ----------
    paper : float, int, str or None
        The printed value (see :func:`printed_number`), a word, or None (not printed).
    measured : float or str
        Ours: a number or a word.
    se : float, optional
        Standard error of a Monte Carlo ``measured``.
    explanation : Explanation, optional
        Why ours may differ; a difference is explained by it and by nothing else.
    fit : Fit, optional
        Set when ``measured`` was obtained by choosing a parameter to match ``paper``: a match
        is then :attr:`Verdict.FITTED`, never reproduced.
    """
    if explanation is not None and not isinstance(explanation, Explanation):
        raise TypeError(f"explanation must be an Explanation, got {explanation!r}")
    if fit is not None and not isinstance(fit, Fit):
        raise TypeError(f"fit must be a Fit, got {fit!r}")
    if paper is None:
        return Verdict.DERIVED
    differs = Verdict.DIFFERS if explanation is None else Verdict.EXPLAINED
    verdict = _compare(paper, measured, se, differs)
    if fit is not None and verdict in (Verdict.REPRODUCED, Verdict.WITHIN_ERROR):
        return Verdict.FITTED
    return verdict


def _compare(paper, measured, se: float | None, differs: Verdict) -> Verdict:
    """Reproduced, within sampling error, or ``differs`` (explained or not)."""
    printed = printed_number(paper)
    condition = printed_condition(paper)
    if condition is not None:
        return _judge_condition(condition, measured, se, differs)
    if printed is None:
        numbers = _printed_numbers(str(paper))
        if numbers is not None:  # numbers in a text: "0.26∠1.33", a matrix
            return _judge_numbers(numbers, measured, differs)
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


_NUMBER = re.compile(r"[-+−]?(?:[0-9]+\.[0-9]*|\.[0-9]+|[0-9]+)(?:[eE][-+]?[0-9]+)?")
_LETTER = re.compile(r"[A-Za-z_]")


def _printed_numbers(text: str) -> tuple[str, list[Decimal]] | None:
    """``(skeleton, numbers)`` of a text that prints numbers between separators only (``∠``,
    commas, brackets: ``"0.26∠1.33"``, ``"[[0.27, -0.01], [0, 1]]"``), else None (a word, a
    formula with letters)."""
    if _LETTER.search(text):
        return None
    numbers = [Decimal(m.replace("−", "-")) for m in _NUMBER.findall(text)]
    if not numbers:
        return None
    return _NUMBER.sub("#", text.replace(" ", "")), numbers


def _judge_numbers(printed: tuple[str, list[Decimal]], measured, differs: Verdict) -> Verdict:
    """Each printed number of a text against ours at its own printed precision."""
    ours = _printed_numbers(measured) if isinstance(measured, str) else None
    if ours is None or ours[0] != printed[0]:
        return differs
    close = all(abs(float(a) - float(b)) <= printed_half_unit(b) * (1 + 1e-9)
                for a, b in zip(ours[1], printed[1], strict=True))
    return Verdict.REPRODUCED if close else differs


def compared_as_words(paper) -> bool:
    """Whether a printed value is judged as a word (the same words or not), not by its
    digits or as a condition."""
    return (isinstance(paper, str) and printed_number(paper) is None
            and printed_condition(paper) is None and _printed_numbers(paper) is None)


def _word(text: str) -> str:
    return " ".join(text.lower().split())


FALLS = "falls as g grows"
"""The word of a trend claim that holds: each printed item claiming a fall is judged against it."""


def fall_with_error(values, ses, at, *, name: str = "g") -> str:
    """Whether Monte Carlo ``values`` (standard errors ``ses``) fall as ``at`` grows, beyond
    sampling error: :data:`FALLS` when the first-to-last fall exceeds 1.96 standard errors and
    no step rises by more than 1.96 standard errors of the difference; otherwise the words say
    where it rises (or that no fall is resolved).

    The standard error of a difference is taken as ``sqrt(se_a^2 + se_b^2)``: conservative for
    values computed on the same trials (common random numbers correlate them positively).
    """
    values, ses = [float(v) for v in values], [float(s) for s in ses]
    if not len(values) == len(ses) == len(at) >= 2:
        raise ValueError("values, ses and at must have the same length, at least 2")
    rises = []
    for k in range(len(values) - 1):
        step, se = values[k + 1] - values[k], math.hypot(ses[k], ses[k + 1])
        if step > Z_95 * se:
            rises.append(f"rises from {name} = {at[k]:g} to {at[k + 1]:g} by {step:.3g} "
                         f"({step / se:.0f} SE)" if se > 0 else
                         f"rises from {name} = {at[k]:g} to {at[k + 1]:g} by {step:.3g}")
    if rises:
        return "; ".join(rises)
    drop, se = values[0] - values[-1], math.hypot(ses[0], ses[-1])
    if drop > Z_95 * se:
        return FALLS
    return f"no fall beyond sampling error from {name} = {at[0]:g} to {at[-1]:g}"
