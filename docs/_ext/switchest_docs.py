"""The switchest documentation's own Sphinx extension.

When Sphinx loads it, before it lists the pages, it writes the text that follows from the
code and must not go stale (into ``docs/_generated`` and ``docs/api``, ignored by git):

* the API pages, one per public module of :data:`API_MODULES`, listing its ``__all__``;
* the ``--help`` text of every ``switchest`` command (``cli.rst`` includes them);
* the registered reproductions of each paper (each paper page includes its table).

It also drops the docstring a constant inherits from its type (a numpy array's would
otherwise fill the page of every array constant), and gives sphinx-gallery the command-line
arguments of each example (:func:`gallery_argv`) and the figures the example wrote with
:mod:`switchest.plotting` (:func:`plotting_scraper`).
"""

from __future__ import annotations

import inspect
import os
import shutil
import subprocess
import sys
from importlib import import_module
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1]
GENERATED = DOCS / "_generated"
API = DOCS / "api"

GALLERY_ARGV = {
    "wang_ieee5bus.py": ["100", "15"],  # 100 runs x 15 intervals instead of 400 x 30
}
"""Command-line arguments of an example in the gallery; the others run at their default size,
which takes seconds (``tests/test_examples.py`` runs every one smaller still)."""


def gallery_argv(gallery_conf, script_vars) -> list[str]:
    """sphinx-gallery's ``reset_argv``: the arguments the example runs with."""
    return GALLERY_ARGV.get(Path(script_vars["src_file"]).name, [])


_WRITTEN: list[Path] = []
"""The PNG files :mod:`switchest.plotting` wrote since :func:`plotting_scraper` last ran."""


def _record_plotting_figures() -> None:
    """Make :mod:`switchest.plotting` list every figure it writes in :data:`_WRITTEN`.

    Its functions write a PNG and close the figure, so sphinx-gallery's matplotlib scraper
    (which collects the figures still open) never sees them; every one of them goes through
    ``switchest.plotting._save``, which this wraps."""
    import switchest.plotting as plotting

    save = plotting._save

    def recording(fig, path, rect=None):
        written = save(fig, path, rect)
        _WRITTEN.append(Path(written))
        return written

    plotting._save = recording


def plotting_scraper(block, block_vars, gallery_conf) -> str:
    """sphinx-gallery image scraper: the figures a cell wrote with :mod:`switchest.plotting`,
    copied into the gallery's images in the order they were written."""
    from sphinx_gallery.scrapers import figure_rst

    images = []
    for path in _WRITTEN:
        image = next(block_vars["image_path_iterator"])
        shutil.copyfile(path, image)
        images.append(image)
    _WRITTEN.clear()
    return figure_rst(images, gallery_conf["src_dir"])


API_MODULES = {
    "switchest": "the package",
    "switchest.system": "the switched linear system",
    "switchest.signals": "switching signals and sample times",
    "switchest.switching": "switching models",
    "switchest.discretize": "exact sampled-data transitions",
    "switchest.simulate": "batched exact simulation",
    "switchest.models": "the papers' systems",
    "switchest.modelfile": "model files",
    "switchest.measurements": "measurement tables",
    "switchest.tabular": "any method on a measurement table",
    "switchest.estimators": "estimators",
    "switchest.analysis": "certificates and designs",
    "switchest.learn": "learning a switched system from data",
    "switchest.metrics": "metrics",
    "switchest.experiments": "paper reproductions",
}
"""The modules of the API reference, in the order of the layers (``README.md``, Layout)."""

_TOP_LEVEL_HOME = {  # the module whose page documents each name ``switchest`` re-exports
    "SwitchedLinearSystem": "switchest.system",
    "SwitchingSignal": "switchest.signals",
    "Trajectory": "switchest.simulate",
    "simulate": "switchest.simulate",
    "Estimate": "switchest.estimators",
    "Transition": "switchest.discretize",
    "interval": "switchest.discretize",
}
_SECTIONS = (("class", "Classes"), ("function", "Functions"), ("exception", "Exceptions"),
             ("data", "Data"))

CLI_COMMANDS = ("", "demo", "list", "run", "reproduce", "estimate", "simulate", "fit", "check",
                "report")
"""``switchest --help`` and each command's --help, included by cli.rst."""

PAPERS = {"Shankar": "shankar", "Zhang": "zhang", "Lee": "lee", "Wang": "wang",
          "Etienne": "etienne", "beyond the papers": "bakeoff"}
"""``Experiment.paper`` -> the name of the table of its reproductions in ``_generated``."""


def _write(path: Path, text: str) -> None:
    """Write ``text`` unless the file holds it already (Sphinx rereads only what changed)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.is_file() or path.read_text() != text:
        path.write_text(text)


def _title(text: str, char: str) -> list[str]:
    return [text, char * len(text), ""]


def _kind(obj) -> str:
    if inspect.isclass(obj):
        return "exception" if issubclass(obj, BaseException) else "class"
    return "function" if callable(obj) else "data"


def _summary(obj) -> str:
    """The first sentence of a docstring, for a list of names."""
    doc = inspect.getdoc(obj) or ""
    return doc.split("\n\n")[0].replace("\n", " ")


def _module_page(name: str, title: str) -> str:
    module = import_module(name)
    lines = [f".. _api-{name}:", "", *_title(f"{name}: {title}", "="),
             f".. automodule:: {name}", "", f".. currentmodule:: {name}", ""]
    names = [n for n in module.__all__ if not n.startswith("_")]
    if name == "switchest":
        lines += [*_title("Re-exported names", "-"),
                  "``import switchest`` gives these names of its modules, documented there:", ""]
        for n in names:
            if n in _TOP_LEVEL_HOME:
                obj = getattr(module, n)
                role = "class" if inspect.isclass(obj) else "func"
                lines.append(f"* :{role}:`switchest.{n} <{_TOP_LEVEL_HOME[n]}.{n}>`: "
                             f"{_summary(obj)}")
        lines += ["", *_title("Subpackages and modules", "-")]
        lines += [f"* :mod:`switchest.{n}`" for n in names if n not in _TOP_LEVEL_HOME]
        return "\n".join(lines) + "\n"
    by_kind: dict[str, list[str]] = {}
    for n in names:
        by_kind.setdefault(_kind(getattr(module, n)), []).append(n)
    for kind, heading in _SECTIONS:
        if by_kind.get(kind):
            lines += [*_title(heading, "-"), ".. autosummary::", "   :toctree: generated/",
                      "   :nosignatures:", ""]
            lines += [f"   {n}" for n in sorted(by_kind[kind], key=str.lower)]
            lines.append("")
    return "\n".join(lines) + "\n"


def write_api_pages() -> None:
    for name, title in API_MODULES.items():
        _write(API / f"{name}.rst", _module_page(name, title))
    toctree = [".. toctree::", "   :maxdepth: 1", "", *(f"   {name}" for name in API_MODULES)]
    _write(GENERATED / "api-toctree.rst", "\n".join(toctree) + "\n")


def write_cli_help() -> None:
    env = {**os.environ, "COLUMNS": "90"}  # argparse wraps at the terminal's width
    for command in CLI_COMMANDS:
        argv = [sys.executable, "-m", "switchest", *([command] if command else []), "--help"]
        text = subprocess.run(argv, capture_output=True, text=True, check=True, env=env).stdout
        _write(GENERATED / f"cli-{command or 'switchest'}.txt", text)


def _escape(text: str) -> str:
    """``text`` as literal reStructuredText inline text."""
    for char in "\\*`|_":
        text = text.replace(char, "\\" + char)
    return text


def write_reproductions() -> None:
    from switchest.experiments import EXPERIMENTS

    for paper, key in PAPERS.items():
        chosen = sorted((e for e in EXPERIMENTS.values() if e.paper == paper),
                        key=lambda e: e.name)
        if not chosen:
            raise RuntimeError(f"no registered reproduction of {paper!r}: update {__file__}")
        rows = [".. list-table::", "   :header-rows: 1", "   :widths: 40 60", "",
                "   * - command", "     - what it reproduces"]
        for e in chosen:
            rows += [f"   * - ``switchest run {e.name}``", f"     - {_escape(e.title)}"]
        _write(GENERATED / f"reproductions-{key}.rst", "\n".join(rows) + "\n")
    unknown = {e.paper for e in EXPERIMENTS.values()} - set(PAPERS)
    if unknown:
        raise RuntimeError(f"reproductions of {sorted(unknown)} have no page: update {__file__}")


def _generate(app) -> None:
    write_api_pages()
    write_cli_help()
    write_reproductions()


def _drop_type_docstring(app, what, name, obj, options, lines) -> None:
    """A constant without a docstring of its own shows none (not its type's, which is what an
    instance's ``__doc__`` gives: a numpy array's would fill the page of every array)."""
    if what not in ("data", "attribute") or not lines or inspect.isclass(obj):
        return
    for inherited in (getattr(obj, "__doc__", None), getattr(type(obj), "__doc__", None)):
        if isinstance(inherited, str) and inherited.strip():
            if lines[0].strip() == inspect.cleandoc(inherited).splitlines()[0].strip():
                lines.clear()
                return


def setup(app):
    _record_plotting_figures()
    _generate(app)  # now: Sphinx lists the source files (and autosummary reads them) next
    app.connect("autodoc-process-docstring", _drop_type_docstring, priority=100)  # before numpydoc
    return {"parallel_read_safe": True, "parallel_write_safe": True}
