"""Reproductions of Wang, Yin, Lin, Polis & Chen (seed 003), mean-square convergent observers
for randomly switched systems.

* :mod:`.examples`: ``wang-examples``, the scalar Examples 1-4 (Figs 1-6);
* :mod:`.ieee5bus`: ``wang-ieee5bus``, the IEEE 5-bus case of §6 (Figs 8-9);
* :mod:`.paper`: what the paper prints, for both;
* :mod:`.readings`: the paper's misprinted formulas evaluated, where its printed numbers come from;
* :mod:`.monte_carlo`: the simulation of the paper's model and its comparison with the exact
  moments, which both run.

Importing the package registers both experiments.
"""

from .examples import GROWTH_FRACTION, LOG_BINS, scalar_gains
from .ieee5bus import BUS_MODE1_DIRECTIONS, BUS_POLES, STATE_LABELS, bus_gains
from .monte_carlo import Z_MAX
from .paper import BUS_PAPER, DESIGN_GAINS, EXAMPLES_PAPER
from .readings import printed_gain_bound, printed_gamma, printed_optimum, printed_sigma

__all__ = [
    "BUS_MODE1_DIRECTIONS",
    "BUS_PAPER",
    "BUS_POLES",
    "DESIGN_GAINS",
    "EXAMPLES_PAPER",
    "GROWTH_FRACTION",
    "LOG_BINS",
    "STATE_LABELS",
    "Z_MAX",
    "bus_gains",
    "printed_gain_bound",
    "printed_gamma",
    "printed_optimum",
    "printed_sigma",
    "scalar_gains",
]
