"""The report's counts: one per printed item of a paper, not one per row.

A paper prints numbers and claims; each is one *item*. Rows judge items: a row belongs to the
item named by its ``item`` (its quantity by default). The rows of an item without a ``reading``
are its *primary* rows (the item as the paper states it, at one or several settings: a
theorem checked at two noise levels); rows with a reading (another formula, a fitted setting)
are *sub-rows*: shown under the item, never counted. An item's verdict is the worst verdict of
its primary rows (a claim holds only where it holds at every setting checked), or, when it has
none, the best of its readings. Items the paper prints that no row judges are *not computed*:
each paper's :data:`PAPERS` entry says how many items it prints and which are not computed,
and the summary counts against that number.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field

from .registry import Row
from .verdict import Reason, Verdict

__all__ = ["Item", "PaperItems", "PAPERS", "Tally", "items_of", "tally"]

_WORST_FIRST = (Verdict.DIFFERS, Verdict.EXPLAINED, Verdict.FITTED, Verdict.WITHIN_ERROR,
                Verdict.REPRODUCED)


@dataclass(frozen=True)
class PaperItems:
    """What a paper prints: how many items, and those no reproduction computes (and why)."""

    printed: int
    not_computed: dict[str, str] = field(default_factory=dict)


PAPERS: dict[str, PaperItems] = {
    "Shankar": PaperItems(18, {
        "Theorem 1: bounds on the prediction error": "its bounds (eqs. (17)-(20)) are not "
        "implemented: they need the paper's unstated constants of Assumption 2",
        "Remark 1: estimation error bounds": "implemented "
        "(switchest.analysis.switch_time_bounds.estimation_error_bounds) but fed by Theorem 1's "
        "bounds, so not judged on a run",
    }),
    "Lee": PaperItems(4),
    "Zhang": PaperItems(33),
    "Wang": PaperItems(67),
    "Etienne": PaperItems(7),
}
"""The printed items of each paper: each number of its text and tables, each word of its
tables (a Yes/No, a set) and each claim of its text, figures and lemmas once (a matrix printed
whole is one item), counted from the paper by hand; the tests check that the reproductions
judge every item but the ones listed as not computed."""


@dataclass(frozen=True)
class Item:
    """One printed item of a paper and the rows that judge it (primary rows first)."""

    paper: str
    key: str
    rows: tuple[tuple[str, Row], ...]  # (experiment, row)

    @property
    def primary(self) -> list[Row]:
        return [row for _, row in self.rows if not row.reading]

    @property
    def readings(self) -> list[Row]:
        return [row for _, row in self.rows if row.reading]

    @property
    def verdict(self) -> Verdict:
        """The worst verdict of the primary rows, else the best of the readings."""
        primary = [r.verdict for r in self.primary]
        if primary:
            return min(primary, key=_WORST_FIRST.index)
        return max((r.verdict for r in self.readings), key=_WORST_FIRST.index)

    @property
    def reasons(self) -> list[Reason]:
        """The reasons of its explained primary rows."""
        return [r.explanation.reason for r in self.primary
                if r.verdict is Verdict.EXPLAINED and r.explanation is not None]


@dataclass(frozen=True)
class Tally:
    """A paper's items by verdict.

    Attributes
    ----------
    printed : int
        N, the number of items the paper prints (:data:`PAPERS`).
    counts : Counter
        Items by verdict, :attr:`Verdict.NOT_COMPUTED` included.
    reasons : Counter
        Explained items by reason.
    unexplained, fitted : list of Item
    not_computed : dict
        Item -> why it is not computed.
    judged : int
        Items some row judges (to compare with ``printed`` minus the not computed).
    """

    printed: int
    counts: Counter
    reasons: Counter
    unexplained: list[Item]
    fitted: list[Item]
    not_computed: dict[str, str]
    judged: int

    @property
    def unjudged(self) -> int:
        """Items neither judged nor declared not computed: those of experiments that did not
        run into this report (negative if rows judge more items than the paper prints)."""
        return self.printed - self.judged - len(self.not_computed)

    @property
    def consistent(self) -> bool:
        """Whether the judged and the not computed items add up to the paper's count."""
        return self.unjudged == 0

    def sentence(self) -> str:
        """``x of N printed items reproduced, ...``."""
        c = self.counts
        reasons = ", ".join(f"{n} {reason.value}" for reason, n in self.reasons.most_common())
        return (f"{c[Verdict.REPRODUCED] + c[Verdict.WITHIN_ERROR]} of {self.printed} printed "
                f"items reproduced ({c[Verdict.WITHIN_ERROR]} within sampling error), "
                f"{c[Verdict.FITTED]} matched only by a fitted reading, "
                f"{c[Verdict.EXPLAINED]} explained" + (f" ({reasons})" if reasons else "")
                + f", {c[Verdict.DIFFERS]} unexplained, {c[Verdict.NOT_COMPUTED]} not computed"
                + (f", {self.unjudged} not in this report (their experiments did not run)"
                   if self.unjudged > 0 else ""))


def items_of(paper: str, rows: Iterable[tuple[str, Row]]) -> list[Item]:
    """The items of ``paper`` judged by ``(experiment, row)`` pairs, in order of first row;
    rows without a printed value (derived) judge no item."""
    grouped: dict[str, list[tuple[str, Row]]] = {}
    for experiment, row in rows:
        if row.paper is not None:
            grouped.setdefault(row.key, []).append((experiment, row))
    return [Item(paper, key, tuple(sorted(pairs, key=lambda p: bool(p[1].reading))))
            for key, pairs in grouped.items()]


def tally(paper: str, items: list[Item]) -> Tally:
    """Count ``items`` of ``paper`` against its printed count (:data:`PAPERS`)."""
    declared = PAPERS.get(paper, PaperItems(len(items)))
    counts = Counter(item.verdict for item in items)
    counts[Verdict.NOT_COMPUTED] = len(declared.not_computed)
    reasons = Counter(reason for item in items if item.verdict is Verdict.EXPLAINED
                      for reason in dict.fromkeys(item.reasons))
    return Tally(declared.printed, counts, reasons,
                 [i for i in items if i.verdict is Verdict.DIFFERS],
                 [i for i in items if i.verdict is Verdict.FITTED],
                 dict(declared.not_computed), len(items))
