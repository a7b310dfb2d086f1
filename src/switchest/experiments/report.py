"""A self-contained HTML report of every experiment in a results store.

The page opens with its provenance (version, commit, command, quick or full runs, seeds, date,
machine, load, times) and a summary per paper that counts its printed items (:mod:`.items`):
reproduced, matched only by a fitted reading, explained by a reason, unexplained (listed), not
computed. Then, for each experiment: the paper's printed values beside ours with a verdict at
the printed precision (:mod:`.verdict`), Monte Carlo values with their standard errors, the
reason or the fitted parameter behind each verdict, the run details, the function that built
each row, the setup, the notes, and the figures (embedded as PNG data, so the page opens from
disk without a server).
"""

from __future__ import annotations

import base64
import csv
import html
import os
import platform
import subprocess
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from .items import PAPERS, Item, items_of, tally
from .registry import Experiment, Row, Summary, get
from .runner import run_tasks, stored_results
from .store import Store
from .verdict import Verdict, compared_as_words, printed_half_unit, printed_number

__all__ = ["ROW_COLUMNS", "RunFacts", "Section", "paper_items", "provenance", "summarize_store",
           "write_report"]

_COUNTED = (Verdict.REPRODUCED, Verdict.WITHIN_ERROR, Verdict.FITTED, Verdict.EXPLAINED,
            Verdict.DIFFERS, Verdict.NOT_COMPUTED)
_CLASS = {Verdict.REPRODUCED: "ok", Verdict.WITHIN_ERROR: "near", Verdict.FITTED: "fit",
          Verdict.EXPLAINED: "known", Verdict.DIFFERS: "off", Verdict.NOT_COMPUTED: "none",
          Verdict.DERIVED: "derived"}

_CSS = """
body { font: 15px/1.5 system-ui, sans-serif; max-width: 1150px; margin: 2em auto; \
padding: 0 1em; color: #222; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; } \
h2 { margin-top: 2.2em; border-bottom: 1px solid #ddd; }
.meta { color: #666; font-size: 0.9em; }
table { border-collapse: collapse; width: 100%; margin: 0.8em 0; font-size: 0.92em; }
th, td { padding: 4px 8px; border-bottom: 1px solid #eee; text-align: right; vertical-align: top; }
th:first-child, td:first-child, td.note, td.verdict { text-align: left; }
th { background: #f6f6f6; }
td.num { font-variant-numeric: tabular-nums; }
tr.ok td.verdict { background: #e3f4e4; } tr.near td.verdict { background: #eef6d8; }
tr.known td.verdict { background: #fff0cc; } tr.off td.verdict { background: #fde2e1; \
font-weight: 600; }
tr.fit td.verdict { background: #e4ecf7; } tr.none td.verdict { background: #eee; }
tr.derived td.verdict { color: #777; font-style: italic; }
tr.word td.verdict { background: none; border-left: 4px solid #9c9; }
tr.reading td { color: #666; font-size: 0.95em; } tr.reading td:first-child { padding-left: 2em; }
td.note { color: #555; max-width: 30em; } td.why { max-width: 22em; text-align: left; }
td.why summary { cursor: pointer; }
td.src, tr.reading td.src { font-size: 0.8em; color: #888; text-align: left; }
.setup { background: #f8f8f8; padding: 0.6em 0.9em; border-left: 3px solid #bbb; }
ul.notes li { margin-bottom: 0.3em; }
.figs img { max-width: 100%; margin: 0.5em 0; border: 1px solid #eee; }
.badge { display: inline-block; padding: 0 6px; border-radius: 3px; font-size: 0.85em; \
background: #eee; margin-right: 0.3em; }
.badge.ok { background: #e3f4e4; } .badge.near { background: #eef6d8; } \
.badge.known { background: #fff0cc; } .badge.off { background: #fde2e1; } \
.badge.fit { background: #e4ecf7; }
.badge.quick { background: #ffe8b3; font-weight: 600; }
table.provenance td, table.provenance th { text-align: left; }
table.summary td:first-child { white-space: nowrap; }
table.summary td:last-child { text-align: left; }
td.num span.meta { white-space: nowrap; }
"""


@dataclass(frozen=True)
class RunFacts:
    """Where an experiment's section comes from: its latest run in the store.

    Attributes
    ----------
    mode : str
        ``"full"`` (the paper's setup), ``"quick"`` (the ``--quick`` preset) or ``"custom"``.
    seed : int
    tasks, missing : int
        Tasks of the run in the store, and those the store lacks.
    compute_seconds : float
        Sum over the stored tasks of the time each took.
    finished : float or None
        When the last of them finished (seconds since the epoch).
    """

    mode: str
    seed: int
    tasks: int
    missing: int
    compute_seconds: float
    finished: float | None


@dataclass(frozen=True)
class Section:
    """One experiment's part of the report: its summary, its paper and its run."""

    summary: Summary
    paper: str
    facts: RunFacts

    def pairs(self) -> list[tuple[str, Row]]:
        """``(experiment, row)`` for each of its rows."""
        return [(self.summary.experiment, row) for row in self.summary.rows]

    def counts(self) -> Counter:
        """How many of the items its rows judge got each verdict (a section's own view: an
        item judged in several sections is counted once per paper in the summary)."""
        return Counter(item.verdict for item in items_of(self.paper, self.pairs()))


def _mode(experiment: Experiment, params: dict) -> str:
    if params == experiment.params():
        return "full"
    return "quick" if params == experiment.params(quick=True) else "custom"


def summarize_store(store: Store, out_dir: Path, names: list[str] | None = None, *,
                    progress: Callable[[str, int, int], None] | None = None) -> list[Section]:
    """The sections of the latest run of each experiment in ``store`` (figures are written
    under ``out_dir/figures``); ``progress(name, done, total)`` is called before each."""
    out = []
    chosen = names or store.experiments()
    for done, name in enumerate(chosen):
        if progress is not None:
            progress(name, done, len(chosen))
        latest = store.latest_run(name)
        if latest is None:
            continue
        params, seed = latest
        experiment = get(name)
        results, missing = stored_results(experiment, params, store, seed)
        if not results:
            continue
        tasks = run_tasks(experiment, params, store, seed)
        facts = RunFacts(_mode(experiment, params), seed, len(tasks), missing,
                         sum(t.elapsed for t in tasks), max((t.finished for t in tasks),
                                                            default=None))
        summary = experiment.summarize(params, results, out_dir / "figures")
        out.append(Section(summary, experiment.paper, facts))
    return out


def provenance(*, command: str | None = None, wall_seconds: float | None = None) -> dict:
    """What produced a report: version, commit, command, date and machine (name: value)."""
    from .. import __version__

    facts = {"switchest": __version__, "commit": _commit()}
    if command:
        facts["command"] = command
    facts["date"] = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    facts["machine"] = (f"{_cpu()}, {os.cpu_count()} logical CPUs; {platform.system()} "
                        f"{platform.release()}; Python {platform.python_version()}")
    if hasattr(os, "getloadavg"):
        facts["load average"] = ("{:.2f}, {:.2f}, {:.2f} over the last 1, 5, 15 minutes, when "
                                 "the report was written".format(*os.getloadavg()))
    if wall_seconds is not None:
        facts["wall time"] = f"{wall_seconds:.0f} s (the runs and this report)"
    return facts


def _commit() -> str:
    """The git commit switchest was built from: the stamp the build writes into an installed
    package (``switchest/_commit.txt``, see ``setup.py``), else, for an editable install that
    runs from its checkout, that checkout's commit ('+ uncommitted changes' if it has any)."""
    stamp = resources.files("switchest").joinpath("_commit.txt")
    if stamp.is_file():
        return stamp.read_text(encoding="utf-8").strip()
    here = Path(__file__).resolve().parent
    try:
        head = subprocess.run(["git", "-C", str(here), "rev-parse", "--short=12", "HEAD"],
                              capture_output=True, text=True, timeout=10)
        if head.returncode != 0:
            return "not a git checkout"
        dirty = subprocess.run(["git", "-C", str(here), "status", "--porcelain",
                                "--untracked-files=no", "--", str(here.parent)],
                               capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return "unknown (git not available)"
    return head.stdout.strip() + (" + uncommitted changes" if dirty.stdout.strip() else "")


def _cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _number(value: float, decimals: int | None) -> str:
    """``value`` to ``decimals`` places (None: six significant digits)."""
    if decimals is None or abs(value) >= 1e15:
        return f"{value:.6g}"
    return f"{value:.{decimals}f}"


def _cells(row: Row) -> tuple[str, str]:
    """The paper's cell (its printed digits) and ours: two digits beyond the printed ones, so
    that a miss at the printed precision shows, with ``± se`` for a Monte Carlo value."""
    printed = printed_number(row.paper)
    paper = ("—" if row.paper is None
             else html.escape(str(row.paper)) if printed is None else str(printed))
    if isinstance(row.measured, str):
        count = f" <span class='meta'>(n = {row.trials})</span>" if row.trials else ""
        return paper, html.escape(row.measured) + count
    decimals = None if printed is None else max(0, -printed.as_tuple().exponent) + 2
    if decimals is None and row.se is not None:
        decimals = _se_decimals(row.se)
    ours = _number(float(row.measured), decimals)
    if row.se is not None:
        ours += f" ± {_number(row.se, _se_decimals(row.se))}"
    if row.trials:
        ours += f" <span class='meta'>(n = {row.trials})</span>"
    return paper, ours


def _se_decimals(se: float) -> int:
    """Decimals that show two significant digits of a standard error."""
    if not se > 0 or se >= 1e15:
        return 0
    digits = 0
    while se < 10 and digits < 12:
        se *= 10
        digits += 1
    return digits


def _why(row: Row) -> str:
    """What decides a verdict beyond the numbers, as HTML: the reason, or the fitted parameter
    and whether it is unique, with the evidence one click away."""
    parts = []
    if row.fit is not None:
        unique = "unique" if row.fit.unique else "not unique"
        parts.append((f"fitted {row.fit.parameter} ({unique})", row.fit.evidence))
    if row.explanation is not None:
        parts.append((row.explanation.reason.value, row.explanation.evidence))
    return "".join(f"<details><summary>{html.escape(head)}</summary>{html.escape(body)}</details>"
                   if body else html.escape(head) for head, body in parts)


def _table(summary: Summary) -> str:
    lines = ["<table><tr><th>quantity</th><th>paper (printed)</th><th>ours</th><th>ours / "
             "paper</th><th>unit</th><th>verdict</th><th>reason or fit</th><th>details</th>"
             "<th>computed by</th></tr>"]
    for row in summary.rows:
        ratio, verdict = row.ratio, row.verdict
        paper, ours = _cells(row)
        tolerance = ""
        printed = printed_number(row.paper)
        if printed is not None:
            tolerance = f" title='printed to ± {printed_half_unit(printed):g}'"
        classes = [_CLASS[verdict]]
        shown = verdict.value
        if compared_as_words(row.paper) and verdict is not Verdict.DERIVED:
            classes.append("word")  # a word is the same or not: no precision behind it
            shown += " (same words)" if verdict is Verdict.REPRODUCED else ""
        quantity = html.escape(row.quantity)
        if row.reading:
            classes.append("reading")
            quantity = f"↳ {html.escape(row.reading)}: {quantity}"
        elif row.item is not None and row.paper is not None:
            quantity += f" <span class='meta'>(item: {html.escape(row.item)})</span>"
        lines.append(
            f'<tr class="{" ".join(classes)}"><td>{quantity}</td>'
            f"<td class='num'{tolerance}>{paper}</td><td class='num'>{ours}</td>"
            f"<td class='num'>{'—' if ratio is None else f'{ratio:.4f}'}</td>"
            f"<td>{html.escape(row.unit)}</td><td class='verdict'>{shown}</td>"
            f'<td class="why">{_why(row)}</td>'
            f'<td class="note">{html.escape(row.details)}</td>'
            f'<td class="src"><code>{html.escape(row.source)}</code></td></tr>'
        )
    lines.append("</table>")
    return "\n".join(lines)


def _badges(counts: Counter) -> str:
    """The section's badges: its printed items by verdict (derived rows are not counted)."""
    shown = [(v, counts[v]) for v in _COUNTED if counts[v]]
    if not shown:
        return '<span class="badge">no printed value compared</span>'
    return "".join(f'<span class="badge {_CLASS[v]}">{n} {v.value}</span>' for v, n in shown)


def _papers(sections: list[Section]) -> dict[str, list[Section]]:
    papers: dict[str, list[Section]] = {}
    for section in sections:
        papers.setdefault(section.paper, []).append(section)
    return papers


def paper_items(sections: list[Section]) -> dict[str, list[Item]]:
    """Paper -> its items judged by the rows of ``sections``."""
    return {paper: items_of(paper, [pair for s in group for pair in s.pairs()])
            for paper, group in _papers(sections).items()}


def _summary_table(sections: list[Section]) -> str:
    """Per paper: its printed items by verdict against the number it prints, the reasons of
    the explained ones, the unexplained and the fitted items by name, and its sections."""
    heads = ["printed items (N)", *(v.value for v in _COUNTED), "derived rows (not counted)",
             "sections"]
    lines = ["<table class='summary'><tr><th>paper</th>"
             + "".join(f"<th>{h}</th>" for h in heads) + "</tr>"]
    details = []
    groups = _papers(sections)
    for paper, items in paper_items(sections).items():
        group = groups[paper]
        t = tally(paper, items)
        derived = sum(row.verdict is Verdict.DERIVED for s in group for row in s.summary.rows)
        cells = "".join(f"<td class='num'>{t.counts[v] or ''}</td>" for v in _COUNTED)
        links = ", ".join(
            f'<a href="#{s.summary.experiment}">{html.escape(s.summary.experiment)}</a>'
            + (" <span class='badge quick'>quick</span>" if s.facts.mode == "quick" else "")
            for s in group)
        unjudged = (f" <span class='meta'>({t.unjudged} not in this report)</span>"
                    if t.unjudged > 0 and paper in PAPERS else
                    f" <span class='badge off'>{-t.unjudged} more judged than printed</span>"
                    if t.unjudged < 0 and paper in PAPERS else "")
        lines.append(f"<tr><td>{html.escape(paper)}</td><td class='num'>{t.printed}</td>{cells}"
                     f"<td class='num'>{derived or ''}</td><td>{links}{unjudged}</td></tr>")
        if paper not in PAPERS:
            continue
        entry = [f"<b>{html.escape(paper)}</b>: {html.escape(t.sentence())}."]
        for title, listed in (("unexplained", t.unexplained), ("fitted", t.fitted)):
            if listed:
                entry.append(f"{title}: " + "; ".join(html.escape(i.key) for i in listed) + ".")
        if t.not_computed:
            entry.append("not computed: " + "; ".join(
                f"{html.escape(k)} ({html.escape(v)})" for k, v in t.not_computed.items()) + ".")
        details.append("<li>" + " ".join(entry) + "</li>")
    lines.append("</table>")
    return "\n".join(lines) + f"<ul class='notes'>{''.join(details)}</ul>"


def _provenance_block(facts: dict, sections: list[Section], store: Store) -> str:
    modes = Counter(s.facts.mode for s in sections)
    facts = {**facts, "runs": ", ".join(f"{n} {m}" for m, n in sorted(modes.items())) or "none",
             "seeds": ", ".join(sorted({str(s.facts.seed) for s in sections})) or "—",
             "compute time": f"{sum(s.facts.compute_seconds for s in sections):.0f} s "
                             "summed over the stored tasks",
             "results store": str(store.path)}
    rows = "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(str(v))}</td></tr>"
                   for k, v in facts.items())
    warning = ""
    if modes.get("quick"):
        warning = ("<p><span class='badge quick'>quick</span> Sections marked quick ran the "
                   "<code>--quick</code> preset (few trials, short runs): their Monte Carlo "
                   "values carry large standard errors and are not the paper's setup.</p>")
    return f"<table class='provenance'>{rows}</table>{warning}"


def _section(section: Section) -> str:
    summary, facts = section.summary, section.facts
    quick = " <span class='badge quick'>quick</span>" if facts.mode == "quick" else ""
    incomplete = (f'<p class="badge off">incomplete: {facts.missing} task(s) missing from the '
                  'store</p>' if facts.missing else "")
    notes = "".join(f"<li>{html.escape(n)}</li>" for n in summary.notes)
    figs = "".join(
        f'<img alt="{html.escape(f.name)}" src="data:image/png;base64,'
        f'{base64.b64encode(Path(f).read_bytes()).decode()}">' for f in summary.figures)
    run = (f"{facts.mode} run, seed {facts.seed}, {facts.tasks} task(s), "
           f"{facts.compute_seconds:.1f} s of compute")
    return (f'<h2 id="{summary.experiment}">{html.escape(summary.title)}</h2>'
            f'<p class="meta"><code>{summary.experiment}</code>{quick} '
            f"{_badges(section.counts())} · {run}</p>{incomplete}"
            f'<p class="setup">{html.escape(summary.setup)}</p>{_table(summary)}'
            f'<ul class="notes">{notes}</ul><div class="figs">{figs}</div>')


ROW_COLUMNS = ("experiment", "paper", "item", "reading", "quantity", "printed", "ours", "se",
               "trials", "unit", "verdict", "reason", "evidence", "fitted parameter",
               "fit unique", "fit evidence", "details", "computed by", "run", "seed")
"""The columns of ``rows.csv``, one line per row of the report."""


def _write_rows(sections: list[Section], path: Path) -> None:
    """Every row of the report as CSV (:data:`ROW_COLUMNS`)."""
    with path.open("w", newline="", encoding="utf-8") as f:
        out = csv.writer(f)
        out.writerow(ROW_COLUMNS)
        for section in sections:
            for row in section.summary.rows:
                why, fit = row.explanation, row.fit
                out.writerow([
                    section.summary.experiment, section.paper, row.key, row.reading,
                    row.quantity, "" if row.paper is None else row.paper, row.measured,
                    "" if row.se is None else row.se, "" if row.trials is None else row.trials,
                    row.unit, row.verdict.value, "" if why is None else why.reason.value,
                    "" if why is None else why.evidence, "" if fit is None else fit.parameter,
                    "" if fit is None else fit.unique, "" if fit is None else fit.evidence,
                    row.details, row.source, section.facts.mode, section.facts.seed])


_LEGEND = ("<p class='meta'>Each number or claim a paper prints is one <b>item</b>, counted "
           "once however many rows judge it; rows marked ↳ are other readings of an item, shown "
           "and not counted. A printed value is <b>reproduced</b> when ours rounds to the digits "
           "the paper prints; a Monte Carlo value is <b>within sampling error</b> when its 95 % "
           "interval (mean ± 1.96 standard errors, widened by half a unit of the last printed "
           "digit) covers the printed one; a value obtained by choosing a parameter to match is "
           "<b>matched by a fitted reading</b>, never reproduced; otherwise it differs, "
           "<b>explained</b> only by a declared reason with its evidence (misprint, rounding, "
           "ambiguous formula, unstated setting, proven error, sampling error), "
           "<b>unexplained</b> otherwise. Run details never change a verdict. Words compare as "
           "words (marked by a bar, not a colour). Rows the paper prints no value for are "
           "<b>derived</b>: shown, not counted.</p>")


def write_report(store: Store, out_dir: str | Path, names: list[str] | None = None, *,
                 command: str | None = None, wall_seconds: float | None = None,
                 progress: Callable[[str, int, int], None] | None = None) -> Path:
    """Write ``out_dir/report.html`` for the experiments in ``store``; returns its path.

    ``command`` (the command line) and ``wall_seconds`` (how long it ran) go into the
    provenance block when given; ``progress`` as in :func:`summarize_store`. Every row of
    every section is also written to ``out_dir/rows.csv`` (:data:`ROW_COLUMNS`), for a
    spreadsheet or a script.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    sections = summarize_store(store, out_dir, names, progress=progress)
    _write_rows(sections, out_dir / "rows.csv")
    facts = provenance(command=command, wall_seconds=wall_seconds)
    body = ("".join(_section(s) for s in sections)
            or "<p>No experiment has been run into this store yet.</p>")
    page = (
        "<!doctype html><html><head><meta charset='utf-8'><title>switchest reproductions"
        f"</title><style>{_CSS}</style></head><body><h1>switchest — paper reproductions</h1>"
        f"{_provenance_block(facts, sections, store)}<h2 id='summary'>Summary</h2>{_LEGEND}"
        f"{_summary_table(sections)}{body}</body></html>"
    )
    path = out_dir / "report.html"
    path.write_text(page, encoding="utf-8")
    return path
