"""Estimation from tables: CSV round trip through the CLI, missing samples, refused tables."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from switchest.cli import main
from switchest.modelfile import load_model
from switchest.models.catalog import catalog
from switchest.simulate import simulate
from switchest.tabular import estimate_table, read_measurements, transition_for

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "models"


def boost_csv(tmp_path, trials_rng=3, missing=()):
    spec = catalog()["shankar-boost"]
    t = spec.sample_times(0.02)
    traj = simulate(spec.system, lambda r: spec.signal(r, t), t, spec.initial, u=np.array([100.0]),
                    rng=trials_rng)
    y = traj.y[0, :, 0].copy()
    y[list(missing)] = np.nan
    df = pd.DataFrame({"t": t, "u": 100.0, "y": y, "mode": traj.mode[0]})
    path = tmp_path / "data.csv"
    df.to_csv(path, index=False)
    return spec, df, path, traj


@pytest.mark.parametrize("method", ["kalman", "switch-time", "imm", "imm-ev1"])
def test_cli_reproduces_the_python_api_exactly(method, tmp_path):
    spec, df, path, _ = boost_csv(tmp_path)
    out = tmp_path / "est.csv"
    code = main(["estimate", "--model", str(EXAMPLES / "shankar-boost.toml"), "--data", str(path),
                 "--method", method, "--grid", "3", "--out", str(out), "--plot", str(tmp_path / "e.png")])
    assert code == 0 and (tmp_path / "e.png").exists()
    api = estimate_table(load_model(EXAMPLES / "shankar-boost.toml"), df, method=method, grid=3)
    cli = pd.read_csv(out)
    assert list(cli.columns) == list(api.columns)
    np.testing.assert_allclose(cli.to_numpy(dtype=float), api.to_numpy(dtype=float), rtol=1e-15, atol=0,
                               equal_nan=True)


def test_missing_samples_are_skipped_not_propagated(tmp_path):
    spec, df, path, traj = boost_csv(tmp_path, missing=(5, 6, 20))
    table = estimate_table(spec, path, method="kalman")
    full = estimate_table(spec, boost_csv(tmp_path)[1], method="kalman")
    assert np.all(np.isfinite(table.filter(regex="^x").to_numpy()))
    assert table["std_x1"][6] > full["std_x1"][6]  # no measurement: more uncertainty than with one
    np.testing.assert_allclose(table.iloc[:5].to_numpy(), full.iloc[:5].to_numpy())


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda d: d.assign(t=d["t"].iloc[::-1].to_numpy()), r"row 1: time .* is before the previous row's"),
        (lambda d: d.assign(t=np.r_[d["t"].iloc[:3], d["t"].iloc[2:-1]]), r"row 3: time .* repeats"),
        (lambda d: d.assign(y=d["y"].astype(object).where(d.index != 4, "12,5")), r"row 4, column 'y': not a number"),
        (lambda d: d.drop(columns="u"), r"missing column\(s\) \['u'\]"),
        (lambda d: d.assign(u=d["u"].where(d.index != 2)), r"row 2, column 'u': empty"),
        (lambda d: d.assign(mode=d["mode"] + 5), r"'mode' must hold mode indices 0..1"),
    ],
)
def test_bad_tables_are_refused_with_the_row_and_column(edit, match, tmp_path):
    spec, df, _, _ = boost_csv(tmp_path)
    with pytest.raises(ValueError, match=match):
        read_measurements(edit(df), spec)


def test_methods_needing_modes_say_so_and_cli_reports_errors(tmp_path, capsys):
    spec, df, path, _ = boost_csv(tmp_path)
    with pytest.raises(ValueError, match="needs the known modes"):
        estimate_table(spec, df.drop(columns="mode"), method="switch-time")
    df.drop(columns="mode").to_csv(tmp_path / "nomode.csv", index=False)
    code = main(["estimate", "--model", str(EXAMPLES / "shankar-boost.toml"), "--data",
                 str(tmp_path / "nomode.csv"), "--method", "kalman", "--out", str(tmp_path / "o.csv")])
    assert code == 2 and "needs the known modes" in capsys.readouterr().out


def test_transition_from_the_switching_model():
    spec = catalog()["shankar-boost"]
    P = transition_for(spec, 0.5e-3)
    np.testing.assert_allclose(P.sum(axis=1), 1.0)
    assert P[0, 0] == pytest.approx(1 - 0.5e-3 / 1.05e-3)
    P_iid = transition_for(catalog()["wang-ieee5bus"], 0.7)
    np.testing.assert_allclose(P_iid[0], P_iid[3])
