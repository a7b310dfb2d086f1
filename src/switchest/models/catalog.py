"""Every paper system as a complete model file: system, sampling, switching, initial state.

:func:`catalog` is what ``examples/models/*.toml`` are written from (a test keeps
them in sync); each entry's description says where it comes from and what was
chosen where the paper is silent.
"""

from __future__ import annotations

import numpy as np

from ..modelfile import ModelSpec
from ..switching import IID, AverageDwell, Dwell, Schedule
from .etienne import ETIENNE_SCENARIO, etienne_academic
from .lee import LEE_SCENARIO
from .shankar import BOOST_SAMPLE_PERIOD, boost_converter, vehicle_2d
from .wang import (
    IEEE_5BUS_SAMPLE_PERIOD,
    WANG_EXAMPLES,
    ieee_5bus,
    ieee_5bus_mode_probabilities,
)
from .zhang import smart_grid, zhang_two_mode

__all__ = ["catalog"]


def catalog() -> dict[str, ModelSpec]:
    """The papers' systems as :class:`~switchest.modelfile.ModelSpec`, keyed by file name."""
    ex1 = WANG_EXAMPLES["example1"]
    grid = smart_grid()
    lee = LEE_SCENARIO
    boost, academic, phasor = boost_converter(), etienne_academic(), lee.system()
    return {
        "shankar-boost": ModelSpec(
            boost, sampling={"period": BOOST_SAMPLE_PERIOD, "duration": 0.1},
            switching=Dwell(boost.n_modes, 0.9e-3, 1.2e-3, initial_mode=0),
            initial=(np.array([0.0, 100.0]), np.diag([25.0, 25.0])), noise={"u_max": 100.0},
            description="Boost converter, Shankar et al. §V.A; input v_in = 100 V. The paper "
                        "switches every 1.2 ms until 0.02 s and then randomly in [0.9, 1.2] ms; a "
                        "file holds one switching model, the random dwell. Process noise unstated "
                        "in the paper (chosen: I)."),
        "shankar-vehicle": ModelSpec(
            vehicle_2d(), sampling={"period": 0.5, "duration": 10.0},
            switching=Schedule([1.65, 2.75, 3.9], [0, 1, 2, 0]),
            initial=(np.zeros(4), 0.01 * np.eye(4)), noise={"u_max": 1.0},
            description="Vehicle maneuver, Shankar et al. §V.B; input u = 1. Process noise "
                        "unstated in the paper (chosen: 1e-3 I)."),
        "zhang-two-mode": ModelSpec(
            zhang_two_mode(), sampling={"duration": 30.0},
            switching=IID([0.5, 0.5]), initial=(np.array([10.0, -10.0]), np.eye(2)),
            description="Zhang & Natarajan §5.1, Example 1 (discrete time). The switching model "
                        "is a choice (the paper fixes mode sequences per figure)."),
        "zhang-smart-grid": ModelSpec(
            grid, sampling={"duration": 6.0},
            switching=IID([1 / 3, 1 / 3, 1 / 3]),
            initial=(np.ones(grid.n_states), np.eye(grid.n_states)),
            description="Zhang & Natarajan §2.2 / Table 1 smart grid, tau = 0.1 s (the value that "
                        "reproduces the printed norms). The switching model is a choice."),
        "wang-example1": ModelSpec(
            ex1.system(), sampling={"period": ex1.T, "duration": 3.0},
            switching=IID(ex1.probabilities()),
            initial=(np.zeros(2), np.eye(2)),
            description="Wang et al. Example 1: two scalar systems, each mode observes one; "
                        "i.i.d. modes at t = kT. R holds the output-noise intensity Xi Xi'."),
        "wang-ieee5bus": ModelSpec(
            ieee_5bus(), sampling={"period": IEEE_5BUS_SAMPLE_PERIOD, "duration": 30.0},
            switching=IID(ieee_5bus_mode_probabilities()),
            initial=(np.zeros(4), np.eye(4)),
            description="Wang et al. §6: IEEE 5-bus, printed linearized A, sensor modes of Table "
                        "3 with packet-loss probabilities; T = 0.6997."),
        "etienne-academic": ModelSpec(
            academic,
            sampling={"tau_min": ETIENNE_SCENARIO.tau_min, "tau_max": ETIENNE_SCENARIO.tau_max,
                      "duration": 40.0},
            switching=AverageDwell(academic.n_modes, ETIENNE_SCENARIO.dwell, 1.0, initial_mode=0),
            initial=(np.zeros(2), np.eye(2)),
            description="Etienne et al. §4 academic example: aperiodic sampling in [0.3, 0.4], "
                        "average dwell time 7 (chatter bound N0 = 1, unstated in the paper); no "
                        "noise."),
        "lee-fsk": ModelSpec(
            phasor, sampling={"period": 0.0025, "duration": lee.horizon},  # lee-detection's grid
            switching=Dwell(phasor.n_modes, lee.min_dwell, lee.max_dwell, initial_mode=0),
            initial=(np.array(lee.x0), np.zeros((2, 2))),
            noise={"v_max": lee.v_max, "u_max": lee.u_max, "x_min": lee.x_min(), "delta": lee.delta,
                   "Delta": lee.Delta, "observer_decay": lee.observer_decay},
            description="Demonstration system for Lee, Ping & Shim (002), which prints no example "
                        "(switchest.models.lee): a phasor x' = omega_i J x + b u, y = x, omega = "
                        "(2 pi, 4 pi) rad/s, b = [0, 1]'. Everything is chosen: bounded noise |v| "
                        "<= 0.1 and input |u| <= 0.02 (Q = R = 0: the noise of Lee et al. is "
                        "bounded, not Gaussian), x(0) = (1, 0) exactly, so |x(t)| >= x_min = 0.8 "
                        "over the 10 s; dwell times uniform in [1.3, 2.5] s (above delta + "
                        "Delta), first mode 0 (the lee-detection experiment draws it at random); "
                        "the detector's windows delta = 0.25 s, Delta = 1 s and observer gains "
                        "with A_i - L_i C = -40 I (noise.observer_decay); output on the "
                        "experiment's 2.5 ms grid."),
    }
