"""The published systems, each a function with the paper's parameters as defaults."""

from .etienne import ETIENNE_SCENARIO, EtienneScenario, etienne_academic
from .lee import LEE_SCENARIO, LeeScenario, fsk_oscillator
from .shankar import (
    BOOST_INPUT_VOLTAGE,
    BOOST_SAMPLE_PERIOD,
    VehicleManeuver,
    boost_converter,
    boost_switching,
    vehicle_2d,
    vehicle_maneuver,
)
from .wang import (
    IEEE_5BUS_A,
    IEEE_5BUS_INITIAL_ERROR,
    IEEE_5BUS_POLES,
    IEEE_5BUS_POLES_AGGRESSIVE,
    IEEE_5BUS_SAMPLE_PERIOD,
    WANG_EXAMPLES,
    ScalarPairExample,
    ieee_5bus,
    ieee_5bus_from_tables,
    ieee_5bus_mode_probabilities,
    wang_scalar_pair,
    wang_scalar_pair_probabilities,
)
from .zhang import SMART_GRID_TAU, smart_grid, zhang_two_mode

__all__ = [
    "BOOST_INPUT_VOLTAGE",
    "BOOST_SAMPLE_PERIOD",
    "ETIENNE_SCENARIO",
    "EtienneScenario",
    "LEE_SCENARIO",
    "LeeScenario",
    "fsk_oscillator",
    "IEEE_5BUS_A",
    "IEEE_5BUS_INITIAL_ERROR",
    "IEEE_5BUS_POLES",
    "IEEE_5BUS_POLES_AGGRESSIVE",
    "IEEE_5BUS_SAMPLE_PERIOD",
    "SMART_GRID_TAU",
    "ScalarPairExample",
    "VehicleManeuver",
    "WANG_EXAMPLES",
    "boost_converter",
    "boost_switching",
    "etienne_academic",
    "ieee_5bus",
    "ieee_5bus_from_tables",
    "ieee_5bus_mode_probabilities",
    "smart_grid",
    "vehicle_2d",
    "vehicle_maneuver",
    "wang_scalar_pair",
    "wang_scalar_pair_probabilities",
    "zhang_two_mode",
]
