"""The bake-off runs every method on every case and the clairvoyant filter is the floor."""

from switchest.experiments import Store, get, run_experiment


def test_bakeoff_quick(tmp_path):
    exp = get("bakeoff")
    params = exp.params(quick=True, trials=4)
    results = run_experiment(exp, params, store=Store(tmp_path / "b.sqlite"))
    summary = exp.summarize(params, results, tmp_path)
    assert len(summary.rows) == 4 * 6 and summary.figures[0].exists()
    by_case = {}
    for row in summary.rows:
        case, method = row.quantity.split(": ", 1)
        by_case.setdefault(case, {})[method] = row.measured
    for case, rmse in by_case.items():
        floor = rmse["mode KF, true switch times"]
        assert all(floor <= 1.001 * v for v in rmse.values()), case
