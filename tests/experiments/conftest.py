"""Shared by the reproduction tests: one quick run of the module's experiments."""

import pytest

from switchest.experiments import Store, get, run_experiment
from switchest.experiments.scoring import split_variants


@pytest.fixture(scope="module")
def runs(request, tmp_path_factory):
    """``{name: (params, results, summary)}`` for each name in the test module's ``NAMES``,
    run at the quick size into one temporary store; ``results`` has one ``(config, result)``
    pair per configuration (the variants of a task split)."""
    out = tmp_path_factory.mktemp(request.module.__name__.rsplit(".", 1)[-1])
    store = Store(out / "results.sqlite")
    done = {}
    for name in request.module.NAMES:
        exp = get(name)
        params = exp.params(quick=True)
        results = run_experiment(exp, params, store=store)
        summary = exp.summarize(params, results, out / "figures")
        done[name] = (params, split_variants(results), summary)
    return done
