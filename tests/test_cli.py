"""The ``jointid`` console script (jointid.cli): usage, unknown commands and dispatch to the module mains."""

from __future__ import annotations

import subprocess
import sys

import pytest
from conftest import REPO

from jointid import cli


def test_help_lists_every_command(capsys):
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: jointid <command>")
    for name in ("diagnose", "config", "checks", "synth", "uff"):
        assert f"\n  {name} " in out


@pytest.mark.parametrize("argv, what", [(["frobnicate"], "unknown command 'frobnicate'"),
                                        ([], "no command given")])
def test_unknown_or_missing_command_exits_2_naming_the_valid_ones(capsys, argv, what):
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert f"jointid: {what}; choose one of: diagnose, config, checks, synth, uff" in err


def test_config_check_is_dispatched(capsys, monkeypatch):
    monkeypatch.chdir(REPO)
    assert cli.main(["config", "check", "config.yaml"]) == 0
    assert capsys.readouterr().out.strip() == "config.yaml: OK"


def test_subcommand_help_reaches_its_own_parser(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["diagnose", "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "usage: python -m jointid.diagnosis " in out and "--dataset" in out


def test_python_dash_m_runs_the_dispatcher():
    res = subprocess.run([sys.executable, "-m", "jointid.cli", "nope"], capture_output=True, text=True,
                         timeout=60)
    assert res.returncode == 2 and "choose one of: diagnose" in res.stderr and "Traceback" not in res.stderr


def test_data_check_validates_folders_without_running_anything(capsys, tmp_path):
    assert cli.main(["data", "check", str(REPO / "data" / "paper")]) == 0
    assert "valid (power_off: 6 modes, power_on: 6 modes)" in capsys.readouterr().out
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "modes.csv").write_text("state;mode;freq_Hz\npower_on;1;350,5\n")
    assert cli.main(["data", "check", str(bad)]) == 1
    err = capsys.readouterr().err.splitlines()
    assert any(line.startswith(f"{bad}/modes.csv") and "';'" in line for line in err), err
    assert any(line.startswith(f"{bad}/conditions.yaml: file is missing") for line in err), err
    assert cli.main(["data", "check", str(REPO / "data" / "paper"), "--points", str(tmp_path / "none.csv")]) == 1
    assert "written by the mesh rule" in capsys.readouterr().err
