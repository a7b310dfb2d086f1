"""Switching models: validation naming the argument, the same draws as the generators,
round trips through the model-file table, and the laws they promise."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from switchest.signals import (
    average_dwell_time,
    dwell_time,
    iid_at_samples,
    markov_at_samples,
    markov_continuous,
    satisfies_average_dwell_time,
    schedule,
)
from switchest.switching import (
    IID,
    KINDS,
    AverageDwell,
    Dwell,
    MarkovAtSamples,
    MarkovContinuous,
    Schedule,
    SwitchingModel,
)

T = np.arange(0.0, 6.0, 0.1)  # sample times; the continuous-time draws end one step past them
T_END = 6.0 - 0.1 + 0.1
P = np.array([[0.9, 0.1, 0.0], [0.25, 0.7, 0.05], [0.3, 0.3, 0.4]])  # asymmetric
RATES = np.array([[-1.0, 0.75, 0.25], [2.0, -2.5, 0.5], [0.1, 0.2, -0.3]])

# each model beside the generator call it stands for (the former {"kind": ...} dict's draw)
CASES = {
    "dwell": (Dwell(3, 0.3, 0.8, initial_mode=2),
              lambda rng: dwell_time(3, T_END, 0.3, 0.8, rng=rng, initial_mode=2)),
    "average-dwell": (AverageDwell(3, 0.4, 2.0, rate=9.0, initial_mode=1),
                      lambda rng: average_dwell_time(3, T_END, 0.4, 2.0, rng=rng, rate=9.0,
                                                     initial_mode=1)),
    "average-dwell default rate": (AverageDwell(2, 0.5, 1.0),
                                   lambda rng: average_dwell_time(2, T_END, 0.5, 1.0, rng=rng)),
    "markov": (MarkovAtSamples(P), lambda rng: markov_at_samples(P, T, rng=rng)),
    "markov mode": (MarkovAtSamples(P, initial=2),
                    lambda rng: markov_at_samples(P, T, rng=rng, initial=2)),
    "markov p0": (MarkovAtSamples(P, initial=[0.1, 0.0, 0.9]),
                  lambda rng: markov_at_samples(P, T, rng=rng, initial=[0.1, 0.0, 0.9])),
    "markov-continuous": (MarkovContinuous(RATES, initial_mode=1),
                          lambda rng: markov_continuous(RATES, T_END, rng=rng, initial_mode=1)),
    "iid": (IID([0.2, 0.5, 0.3]), lambda rng: iid_at_samples([0.2, 0.5, 0.3], T, rng=rng)),
    "schedule": (Schedule([1.0, 2.5, 4.0], [0, 2, 2, 1]),
                 lambda rng: schedule([1.0, 2.5, 4.0], [0, 2, 2, 1])),
}


@pytest.mark.parametrize("name", CASES)
def test_sample_draws_what_the_generator_draws(name):
    model, generator = CASES[name]
    for seed in (0, 1, 7):
        got = model.sample(np.random.default_rng(seed), T)
        want = generator(np.random.default_rng(seed))
        np.testing.assert_allclose(got.times, want.times, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(got.modes, want.modes)


@pytest.mark.parametrize("name", CASES)
def test_table_round_trip(name):
    model = CASES[name][0]
    table = model.to_dict()
    assert table["kind"] == model.kind and KINDS[model.kind] is type(model)
    back = SwitchingModel.from_dict(table, n_modes=3 if name != "average-dwell default rate" else 2)
    assert type(back) is type(model) and back.to_dict().keys() == table.keys()
    for key, value in table.items():
        if key != "kind":
            np.testing.assert_allclose(back.to_dict()[key], value, rtol=0, atol=0)
    a, b = (m.sample(np.random.default_rng(3), T) for m in (model, back))
    np.testing.assert_allclose(a.times, b.times, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(a.modes, b.modes)


def test_to_dict_is_the_model_file_table():
    assert Dwell(2, 1.0, 2.0).to_dict() == {"kind": "dwell", "min_dwell": 1.0, "max_dwell": 2.0,
                                            "initial_mode": 0}
    assert AverageDwell(2, 7.0, 1.0).to_dict() == {"kind": "average-dwell", "tau_a": 7.0,
                                                   "N0": 1.0, "initial_mode": 0}
    assert MarkovAtSamples([[0.5, 0.5], [0.2, 0.8]]).to_dict() == {
        "kind": "markov", "transition": [[0.5, 0.5], [0.2, 0.8]]}
    assert Schedule([1.0], [0, 1]).to_dict() == {"kind": "schedule", "times": [1.0],
                                                 "modes": [0, 1]}


@pytest.mark.parametrize("build, error, match", [
    (lambda: Dwell(1, 1.0, 2.0), ValueError, r"n_modes must be at least 2"),
    (lambda: Dwell(2.0, 1.0, 2.0), TypeError, r"n_modes must be an int"),
    (lambda: Dwell(2, -1.0, 2.0), ValueError, r"min_dwell must be a finite positive number"),
    (lambda: Dwell(2, 2.0, 1.0), ValueError, r"max_dwell must be >= min_dwell = 2"),
    (lambda: Dwell(2, 1.0, "2"), TypeError, r"max_dwell must be a real scalar"),
    (lambda: Dwell(2, 1.0, 2.0, initial_mode=2), ValueError, r"initial_mode must be a mode"),
    (lambda: Dwell(2, 1.0, 2.0, initial_mode=True), TypeError, r"initial_mode must be an int"),
    (lambda: AverageDwell(2, 0.0, 1.0), ValueError, r"tau_a must be a finite positive number"),
    (lambda: AverageDwell(2, 1.0, 0.5), ValueError, r"N0 must be >= 1"),
    (lambda: AverageDwell(2, 1.0, 1.0, rate=np.inf), ValueError, r"rate must be a finite positive"),
    (lambda: MarkovAtSamples([[0.5, 0.6], [0.5, 0.5]]), ValueError,
     r"transition rows must sum to 1"),
    (lambda: MarkovAtSamples([[1.0, 0.0]]), ValueError, r"transition must be square"),
    (lambda: MarkovAtSamples(P, initial=3), ValueError, r"initial must be a mode index in 0\.\.2"),
    (lambda: MarkovAtSamples(P, initial=[0.5, 0.5]), ValueError, r"initial must have length 3"),
    (lambda: MarkovContinuous([[-1.0, 1.0], [1.0, -2.0]]), ValueError,
     r"rates rows must sum to zero"),
    (lambda: MarkovContinuous([[1.0, -1.0], [1.0, -1.0]]), ValueError,
     r"rates must have non-negative off-diagonal"),
    (lambda: MarkovContinuous([[-1.0, 1.0], [1.0, -1.0]], initial_mode=-1), ValueError,
     r"initial_mode must be a mode index"),
    (lambda: IID([0.5, 0.6]), ValueError, r"p must sum to 1"),
    (lambda: IID([-0.5, 1.5]), ValueError, r"p must be non-negative"),
    (lambda: Schedule([2.0, 1.0], [0, 1, 0]), ValueError, r"times must be strictly increasing"),
    (lambda: Schedule([1.0], [0, 1, 0]), ValueError, r"modes must have one more entry than times"),
    (lambda: Schedule([np.nan], [0, 1]), ValueError, r"times must be finite"),
])
def test_parameters_are_validated_by_name(build, error, match):
    with pytest.raises(error, match=match):
        build()


@pytest.mark.parametrize("table, match", [
    ({"kind": "dwel", "min_dwell": 1.0}, r"table\['kind'\] must be one of \['average-dwell'"),
    ({"min_dwell": 1.0}, r"table\['kind'\] must be one of"),
    ({"kind": "dwell", "min_dwell": 1.0}, r"table\['max_dwell'\] is required for kind 'dwell'"),
    ({"kind": "iid", "p": [1.0], "tau_a": 1.0},
     r"table\['tau_a'\] is not a parameter of kind 'iid'"),
    ({"kind": "iid", "p": [0.5, 0.5]}, r"a 'iid' model of 2 modes cannot drive n_modes = 3"),
])
def test_from_dict_names_what_is_wrong(table, match):
    with pytest.raises(ValueError, match=match):
        SwitchingModel.from_dict(table, n_modes=3)


def test_from_dict_on_a_class_takes_only_its_kind():
    assert isinstance(IID.from_dict({"kind": "iid", "p": [1.0]}, n_modes=1), IID)
    with pytest.raises(ValueError, match=r"table\['kind'\] must be one of \['iid'\], got 'dwell'"):
        IID.from_dict({"kind": "dwell", "min_dwell": 1.0, "max_dwell": 1.0}, n_modes=2)
    with pytest.raises(TypeError, match="table must be a dict, got list"):
        SwitchingModel.from_dict([("kind", "iid")], n_modes=2)


def test_parameters_are_read_only():
    model = MarkovAtSamples(P, initial=[0.1, 0.0, 0.9])
    with pytest.raises(ValueError, match="read-only"):
        model.transition[0, 0] = 0.0
    with pytest.raises(AttributeError):
        model.initial = 1


def test_sample_times_are_checked():
    for model, _ in CASES.values():
        with pytest.raises(ValueError, match="t must be a non-empty, strictly increasing"):
            model.sample(0, [0.0, 0.0])


def test_attributes_say_when_switches_happen():
    at_samples = {name for name, (model, _) in CASES.items() if model.at_samples}
    assert at_samples == {"markov", "markov mode", "markov p0", "iid"}
    assert Dwell(2, 0.3, 0.8).dwell_time == 0.3
    assert Schedule([1.0, 2.5, 4.0], [0, 2, 2, 1]).dwell_time == pytest.approx(3.0)  # merged
    assert Schedule([1.0], [0, 1]).dwell_time is None
    assert all(CASES[k][0].dwell_time is None
               for k in ("average-dwell", "markov", "markov-continuous", "iid"))
    assert [CASES[k][0].n_modes for k in ("dwell", "markov", "markov-continuous", "iid")] == [3] * 4
    assert CASES["schedule"][0].n_modes is None


def test_a_schedule_ignores_the_rng():
    model = CASES["schedule"][0]
    a, b = model.sample(0, T), model.sample(99, T[:3])
    np.testing.assert_allclose(a.times, [1.0, 4.0])
    np.testing.assert_array_equal(a.modes, b.modes)


@settings(max_examples=40, deadline=None)
@given(lo=st.floats(0.05, 2.0), spread=st.floats(0.0, 3.0), n_modes=st.integers(2, 5),
       seed=st.integers(0, 2**32 - 1))
def test_dwell_signals_respect_their_bounds(lo, spread, n_modes, seed):
    model = Dwell(n_modes, lo, lo + spread, initial_mode=n_modes - 1)
    sig = model.sample(np.random.default_rng(seed), T)
    gaps = np.diff(np.concatenate([[0.0], sig.times]))
    assert np.all(gaps >= lo * (1 - 1e-12)) and np.all(gaps <= (lo + spread) * (1 + 1e-12))
    assert sig.modes[0] == n_modes - 1 and sig.modes.max() < n_modes
    assert sig.times.size == 0 or sig.times[-1] < T_END


@settings(max_examples=40, deadline=None)
@given(tau_a=st.floats(0.05, 2.0), N0=st.floats(1.0, 4.0), seed=st.integers(0, 2**32 - 1))
def test_average_dwell_signals_respect_their_bound(tau_a, N0, seed):
    sig = AverageDwell(3, tau_a, N0).sample(np.random.default_rng(seed), T)
    assert satisfies_average_dwell_time(sig, tau_a, N0)


@settings(max_examples=30, deadline=None)
@given(p=st.lists(st.floats(0.0, 1.0), min_size=2, max_size=4).filter(lambda v: sum(v) > 0.1),
       seed=st.integers(0, 2**32 - 1))
def test_at_sample_models_switch_only_at_samples(p, seed):
    p = np.asarray(p) / np.sum(p)
    L = p.size
    transition = np.tile(p, (L, 1))
    for model, first in ((IID(p), 0), (MarkovAtSamples(transition), 1)):  # markov: uniform start
        sig = model.sample(np.random.default_rng(seed), T)
        assert np.all(np.isin(sig.times, T))
        assert np.all(p[sig.modes[first:]] > 0)
