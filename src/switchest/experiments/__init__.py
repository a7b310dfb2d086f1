"""Paper reproductions: a registry of named experiments, a resumable parallel runner,
a SQLite results store and an HTML report.

Importing this package registers every experiment.
"""

# importing the experiment modules registers their experiments
from . import bakeoff, etienne, lee, shankar, wang, zhang  # noqa: F401
from .registry import EXPERIMENTS, Experiment, Row, Summary, get, names, register
from .report import write_report
from .runner import RunInterrupted, run_experiment, run_quick, stored_results
from .store import Store

__all__ = [
    "EXPERIMENTS",
    "Experiment",
    "Row",
    "RunInterrupted",
    "Store",
    "Summary",
    "get",
    "names",
    "register",
    "run_experiment",
    "run_quick",
    "stored_results",
    "write_report",
]
