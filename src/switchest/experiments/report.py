"""A self-contained HTML report of every experiment in a results store.

For each experiment: the paper's values beside ours with their ratio, the
setup, the notes that explain every disagreement, and the figures (embedded as
PNG data, so the page opens from disk without a server).
"""

from __future__ import annotations

import base64
import html
import time
from pathlib import Path

from .registry import Summary, get
from .runner import stored_results
from .store import Store

__all__ = ["summarize_store", "write_report", "AGREE"]

AGREE = 0.10
"""Relative difference up to which a measured value counts as agreeing with the paper's."""

_CSS = """
body { font: 15px/1.5 system-ui, sans-serif; max-width: 1100px; margin: 2em auto; \
padding: 0 1em; color: #222; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; } \
h2 { margin-top: 2.2em; border-bottom: 1px solid #ddd; }
.meta { color: #666; font-size: 0.9em; }
table { border-collapse: collapse; width: 100%; margin: 0.8em 0; font-size: 0.92em; }
th, td { padding: 4px 8px; border-bottom: 1px solid #eee; text-align: right; vertical-align: top; }
th:first-child, td:first-child, td.note { text-align: left; }
th { background: #f6f6f6; }
tr.off td.ratio { background: #fde2e1; font-weight: 600; }
tr.ok td.ratio { background: #e3f4e4; }
td.note { color: #555; max-width: 28em; }
.setup { background: #f8f8f8; padding: 0.6em 0.9em; border-left: 3px solid #bbb; }
ul.notes li { margin-bottom: 0.3em; }
.figs img { max-width: 100%; margin: 0.5em 0; border: 1px solid #eee; }
.toc a { margin-right: 1em; }
.badge { display: inline-block; padding: 0 6px; border-radius: 3px; font-size: 0.8em; \
background: #eee; }
.badge.off { background: #fde2e1; } .badge.ok { background: #e3f4e4; }
"""


def summarize_store(store: Store, out_dir: Path,
                    names: list[str] | None = None) -> list[tuple[Summary, int]]:
    """Summaries of the latest run of each experiment in ``store``, with the count of missing
    tasks."""
    out = []
    for name in names or store.experiments():
        latest = store.latest_run(name)
        if latest is None:
            continue
        params, seed = latest
        experiment = get(name)
        results, missing = stored_results(experiment, params, store, seed)
        if not results:
            continue
        out.append((experiment.summarize(params, results, out_dir / "figures"), missing))
    return out


def _fmt(v) -> str:
    if v is None:
        return "—"
    if isinstance(v, str):
        return html.escape(v)
    return f"{v:.4g}"


def _table(summary: Summary) -> tuple[str, int]:
    lines = ["<table><tr><th>quantity</th><th>paper</th><th>ours</th><th>ours / "
             "paper</th><th>unit</th><th>note</th></tr>"]
    off = 0
    for row in summary.rows:
        ratio = row.ratio
        cls = "" if ratio is None else ("ok" if abs(ratio - 1) <= AGREE else "off")
        off += cls == "off"
        lines.append(
            f'<tr class="{cls}"><td>{html.escape(row.quantity)}</td><td>{_fmt(row.paper)}</td>'
            f"<td>{_fmt(row.measured)}</td><td "
            f"class=\"ratio\">{'—' if ratio is None else f'{ratio:.3f}'}</td>"
            f'<td>{html.escape(row.unit)}</td><td class="note">{html.escape(row.note)}</td></tr>'
        )
    lines.append("</table>")
    return "\n".join(lines), off


def write_report(store: Store, out_dir: str | Path, names: list[str] | None = None) -> Path:
    """Write ``out_dir/report.html`` for the experiments in ``store``; returns its path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    summaries = summarize_store(store, out_dir, names)
    sections, toc = [], []
    for summary, missing in summaries:
        table, off = _table(summary)
        badge = (f'<span class="badge off">{off} value(s) differ from the paper by more than '
                 f'{AGREE:.0%}: '
                 f"see the notes</span>" if off else '<span class="badge ok">no printed value '
                                                     'differs by more '
                 f"than {AGREE:.0%}</span>")
        incomplete = (f'<p class="badge off">incomplete: {missing} task(s) missing from the '
                      'store</p>'
                      if missing else "")
        notes = "".join(f"<li>{html.escape(n)}</li>" for n in summary.notes)
        figs = "".join(
            f'<img alt="{html.escape(f.name)}" src="data:image/png;base64,'
            f'{base64.b64encode(Path(f).read_bytes()).decode()}">' for f in summary.figures)
        toc.append(f'<a href="#{summary.experiment}">{summary.experiment}</a>')
        sections.append(
            f'<h2 id="{summary.experiment}">{html.escape(summary.title)}</h2>'
            f'<p class="meta"><code>{summary.experiment}</code> {badge}</p>{incomplete}'
            f'<p class="setup">{html.escape(summary.setup)}</p>{table}'
            f'<ul class="notes">{notes}</ul><div class="figs">{figs}</div>'
        )
    body = "".join(sections) or "<p>No experiment has been run into this store yet.</p>"
    page = (
        f"<!doctype html><html><head><meta charset='utf-8'><title>switchest reproductions</title>"
        f"<style>{_CSS}</style></head><body><h1>switchest — paper reproductions</h1>"
        f"<p class='meta'>Generated {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} from "
        f"<code>{html.escape(str(store.path))}</code>. Green: within {AGREE:.0%} of the printed "
        "value; red: further, with the reason in the notes.</p><p "
        f"class='toc'>{''.join(toc)}</p>{body}</body></html>"
    )
    path = out_dir / "report.html"
    path.write_text(page, encoding="utf-8")
    return path
