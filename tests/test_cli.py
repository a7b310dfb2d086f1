"""The command line: the demo runs end to end and prints its comparison."""

import pytest

from switchest.cli import main


def test_demo_prints_the_comparison(capsys):
    assert main(["demo", "--trials", "2", "--duration", "0.02", "--seed", "1"]) == 0
    out = capsys.readouterr().out
    assert "clairvoyant" in out and "IMM" in out and "RMSE" in out


def test_bad_arguments_exit_with_usage(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["demo", "--trials", "0"])
    assert exc.value.code == 2
    assert "--trials must be >= 1" in capsys.readouterr().err
