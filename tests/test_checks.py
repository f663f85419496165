"""CI acceptance checks (jointid.reporting.checks): Table 1 gates on an honest, complete table (a status per
state, finite numbers, the ranges present); the increase is required only with --require-increase."""

from __future__ import annotations

import subprocess
import sys

import pandas as pd
import pytest

from jointid.reporting import checks
from jointid.reporting.tables import RANGE_COLUMNS

HEADER = ("state,status,dynamic_stiffness_N_per_mm,paper_dynamic_stiffness_N_per_mm,governing_mode,"
          "static_stiffness_N_per_mm,not_identified_dynamic_stiffness_N_per_mm,paired_dynamic_stiffness_N_per_mm\n")
NOT_ID = "not identified: the governing mode (FE mode 2, 1308.1 Hz, table bounce) has no measured partner"


def _row(state, k, paper, status="identified", paired=""):
    if status == "identified":
        return f"{state},{status},{k},{paper},4,500000,,{paired}\n"
    return f'{state},"{status}",,{paper},2,500000,{k},{paired}\n'


def _ranges(folder, low=-10.0, high=50.0):
    row = {c: 1.0 for c in RANGE_COLUMNS}
    row.update(state="power_on", reference_state="power_off", basis="paired modes", over="points × damping laws",
               n_cases=54, increase_low_pct=low, increase_high_pct=high, paper_increase_pct=42.1, paper_inside=True)
    pd.DataFrame([row]).to_csv(folder / checks.TABLE1_RANGES, index=False)


def _table1(folder, k_off, k_on, status_off="identified", status_on="identified", ranges=True):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / checks.TABLE1).write_text(HEADER + _row("power_off", k_off, 104547, status_off, 120000)
                                        + _row("power_on", k_on, 148551, status_on, 150000))
    if ranges:
        _ranges(folder)
    return folder


def _tables23(folder, err_off, err_on):
    for name, err in (("table2_power_off.csv", err_off), ("table3_power_on.csv", err_on)):
        pd.DataFrame({"order": [1, 2], "experimental_Hz": [100.0, 200.0],
                      "simulation_Hz": [100.0, 200.0 * (1 + err / 100)],
                      "relative_error_pct": [0.0, err], "paper_simulation_Hz": [99.0, 201.0],
                      "paper_relative_error_pct": [-1.0, 0.5]}).to_csv(folder / name, index=False)


def test_table1_increase_is_computed_from_the_stiffnesses(tmp_path):
    inc, problems = checks.table1_increase_pct(_table1(tmp_path, 100000.0, 142100.0))
    assert problems == [] and inc == pytest.approx(42.1, rel=1e-12)
    assert checks.check_table1(tmp_path) == []
    assert checks.check_table1(tmp_path, require_increase=True) == []


@pytest.mark.parametrize("k_on", [100000.0, 90000.0])
def test_no_increase_is_a_finding_and_fails_only_when_required(tmp_path, k_on):
    assert checks.check_table1(_table1(tmp_path, 100000.0, k_on)) == []
    (problem,) = checks.check_table1(tmp_path, require_increase=True)
    assert "not positive" in problem and checks.TABLE1 in problem


def test_a_state_not_identified_passes_with_its_number_aside(tmp_path, capsys):
    _table1(tmp_path, 61519.0, 59120.0, status_off=NOT_ID, status_on=NOT_ID)
    inc, problems = checks.table1_increase_pct(tmp_path)
    assert inc is None and problems == []
    assert checks.check_table1(tmp_path) == []
    assert "no increase: a state is not identified" in capsys.readouterr().out
    (problem,) = checks.check_table1(tmp_path, require_increase=True)
    assert "--require-increase" in problem


def test_a_state_not_identified_with_a_number_in_the_result_column_fails(tmp_path):
    _table1(tmp_path, 100000.0, 142100.0)
    path = tmp_path / checks.TABLE1
    df = pd.read_csv(path, dtype=str, keep_default_na=False)
    df.loc[0, "status"] = NOT_ID  # dynamic_stiffness_N_per_mm still holds 100000
    df.loc[0, "not_identified_dynamic_stiffness_N_per_mm"] = "100000"
    df.to_csv(path, index=False)
    (problem,) = checks.check_table1(tmp_path)
    assert "power_off is not identified but dynamic_stiffness_N_per_mm = 100000.0" in problem
    df.loc[0, "dynamic_stiffness_N_per_mm"] = ""
    df.to_csv(path, index=False)
    assert checks.check_table1(tmp_path) == []


@pytest.mark.parametrize("status", ["", "identified?", "not identified"])
def test_a_state_without_a_valid_status_fails(tmp_path, status):
    _table1(tmp_path, 100000.0, 142100.0)
    path = tmp_path / checks.TABLE1
    df = pd.read_csv(path, dtype=str, keep_default_na=False)
    df.loc[1, "status"] = status
    df.to_csv(path, index=False)
    (problem,) = checks.check_table1(tmp_path)
    assert "power_on status" in problem and "neither 'identified' nor 'not identified: <why>'" in problem


def test_missing_or_non_finite_ranges_fail(tmp_path):
    _table1(tmp_path, 100000.0, 142100.0, ranges=False)
    (problem,) = checks.check_table1(tmp_path)
    assert f"{tmp_path / checks.TABLE1_RANGES}: missing" in problem
    _ranges(tmp_path, low=float("nan"))
    (problem,) = checks.check_table1(tmp_path)
    assert "increase_low_pct = (empty) is not a finite number" in problem


def test_table1_missing_or_incomplete_fails_with_the_fix(tmp_path):
    _ranges(tmp_path)
    assert checks.check_table1(tmp_path) == [
        f"{tmp_path / checks.TABLE1}: missing — run `snakemake -j2 {(tmp_path / checks.TABLE1).as_posix()}` "
        "(rule table1)"]
    (tmp_path / checks.TABLE1).write_text(HEADER + _row("power_off", 100000, 104547) + _row("power_on", "nan", 148551))
    (problem,) = checks.check_table1(tmp_path)
    assert "power_on dynamic_stiffness_N_per_mm = nan is not a positive number" in problem
    (tmp_path / checks.TABLE1).write_text(HEADER + _row("power_off", 100000, 104547))
    (problem,) = checks.check_table1(tmp_path)
    assert "0 rows for state power_on" in problem


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "jointid.reporting.checks", *map(str, args)], capture_output=True,
                          text=True, timeout=60)


def test_cli_gates_table1_separately_from_the_error_bounds(tmp_path):
    _table1(tmp_path, 100000.0, 111000.0)
    _tables23(tmp_path, 8.95, 3.0)  # Table 2 above the paper's 8.1 %
    ok = _cli("--table1", tmp_path)
    assert ok.returncode == 0, ok.stderr
    assert "+11.0 %" in ok.stdout
    bounds = _cli("--tables2-3", tmp_path)
    assert bounds.returncode == 1 and "8.95 % exceeds the required 8.1 %" in bounds.stderr
    assert checks.TABLE1 not in bounds.stderr + bounds.stdout
    assert _cli(tmp_path).returncode == 1  # no option: both groups
    _table1(tmp_path, 100000.0, 99000.0)
    assert _cli("--table1", tmp_path).returncode == 0  # a decrease is a finding
    bad = _cli("--table1", "--require-increase", tmp_path)
    assert bad.returncode == 1 and "-1.0 %" in bad.stderr
    _tables23(tmp_path, 8.0, 8.2)
    assert _cli("--tables2-3", tmp_path).returncode == 0


# ------------------------------------------------------------------ unreadable tables, bad cells

@pytest.mark.parametrize("content", ["", "\n\n", "\xff\xfe\x00garbage"])
def test_unreadable_frequency_table_names_the_file_and_the_rerun(tmp_path, content):
    _tables23(tmp_path, 1.0, 1.0)
    path = tmp_path / "table2_power_off.csv"
    path.write_bytes(content.encode("latin-1"))
    (problem,) = checks.check_frequency_tables(tmp_path)
    assert problem.startswith(f"{path}: not a readable CSV") and "rerun `snakemake -j2" in problem
    res = _cli("--tables2-3", tmp_path)
    assert res.returncode == 1 and "Traceback" not in res.stderr and str(path) in res.stderr


def test_unreadable_table1_fails_without_traceback(tmp_path):
    _ranges(tmp_path)
    (tmp_path / checks.TABLE1).write_bytes(b"")
    res = _cli("--table1", tmp_path)
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert f"{tmp_path / checks.TABLE1}: not a readable CSV" in res.stderr and "rule table1" in res.stderr


def test_frequency_table_missing_column_or_rows_is_named(tmp_path):
    _tables23(tmp_path, 1.0, 1.0)
    path = tmp_path / "table3_power_on.csv"
    pd.read_csv(path).drop(columns="relative_error_pct").to_csv(path, index=False)
    (problem,) = checks.check_frequency_tables(tmp_path)
    assert problem.startswith(f"{path}: columns relative_error_pct missing — rerun `snakemake -j2")
    path.write_text(",".join(checks.COLUMNS) + "\n")
    assert checks.check_frequency_tables(tmp_path) == [
        f"{path}: no data rows — rerun `snakemake -j2 {path.as_posix()}` (rule tables)"]


@pytest.mark.parametrize("bad, shown", [("n/a", "n/a"), ("", "(empty)"), ("nan", "nan"), ("inf", "inf")])
def test_non_numeric_relative_error_fails_naming_row_and_column(tmp_path, bad, shown):
    _tables23(tmp_path, 1.0, 1.0)
    path = tmp_path / "table2_power_off.csv"
    df = pd.read_csv(path).astype({"relative_error_pct": object})
    df.loc[1, "relative_error_pct"] = bad
    df.to_csv(path, index=False)
    (problem,) = checks.check_frequency_tables(tmp_path)
    assert problem.startswith(f"{path}: order 2: relative_error_pct = {shown} is not a finite number")
    res = _cli("--tables2-3", tmp_path)
    assert res.returncode == 1 and "order 2: relative_error_pct" in res.stderr


@pytest.mark.parametrize("bad, shown", [("n/a", "n/a"), ("", "(empty)")])
def test_non_numeric_table1_stiffness_fails_naming_state_and_column(tmp_path, bad, shown):
    (problem,) = checks.check_table1(_table1(tmp_path, bad, 142100.0))
    assert problem.startswith(f"{tmp_path / checks.TABLE1}: power_off dynamic_stiffness_N_per_mm = {shown} "
                              "is not a positive number")
