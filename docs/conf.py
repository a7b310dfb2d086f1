"""Sphinx configuration of the switchest documentation.

Build (from the repository root): ``pip install ".[docs]"`` then
``sphinx-build -W -b html docs docs/_build/html``; open ``docs/_build/html/index.html``.

The API pages, the ``--help`` text of the commands and the tables of reproductions are
written from the code at every build (``_ext/switchest_docs.py``); the gallery runs the
scripts of ``examples/`` (sphinx-gallery).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import switchest

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))

# -- project ----------------------------------------------------------------------------------
project = "switchest"
author = "the switchest developers"
copyright = f"2026, {author}"
release = version = switchest.__version__

# -- general ----------------------------------------------------------------------------------
extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.doctest",  # the Examples of the docstrings, run by `-b doctest` (.ci/run)
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "matplotlib.sphinxext.plot_directive",  # the figure of getting-started, drawn at build time
    "numpydoc",
    "sphinx_gallery.gen_gallery",
    "sphinx-mathjax-offline",  # MathJax copied into the build: the pages open offline
    "switchest_docs",  # generated pages (API, CLI help, reproductions); see its docstring
]
templates_path = ["_templates"]
exclude_patterns = ["_build", "_generated", "Thumbs.db", ".DS_Store"]
default_role = "code"  # `x` in a docstring is code, as ``x`` is

# -- autodoc, autosummary, numpydoc -----------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "none"  # the numpydoc sections give the types
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks: set[str] = set()

# -- doctest: the Examples sections run as in their module, whose names they use unqualified
doctest_global_setup = """
import numpy as np
from switchest import *
from switchest.estimators import *
"""

# -- plots drawn at build time ---------------------------------------------------------------
plot_include_source = True
plot_html_show_source_link = False
plot_html_show_formats = False
plot_formats = [("png", 120)]

# -- HTML -------------------------------------------------------------------------------------
html_theme = "furo"
html_title = f"switchest {release}"
html_static_path = ["_static"]
html_css_files = ["switchest.css"]
html_show_sourcelink = False

# -- the gallery ------------------------------------------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": str(DOCS.parent / "examples"),
    "gallery_dirs": "auto_examples",
    # every example runs at build time, each in seconds at its default size (or the one
    # switchest_docs.GALLERY_ARGV gives it)
    "filename_pattern": r"\.py$",
    "reset_argv": "switchest_docs.gallery_argv",
    # the figures of switchest.plotting (written to PNG and closed), then any left open
    "image_scrapers": ("switchest_docs.plotting_scraper", "matplotlib"),
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "show_memory": False,
    "capture_repr": (),
    "min_reported_time": 1,
}
# the examples print rich tables: plain text in the page, no terminal colours
os.environ.setdefault("MPLBACKEND", "Agg")
os.environ["TERM"] = "dumb"
os.environ["NO_COLOR"] = "1"
