"""Measured-data layer: the paper's dataset, Dataset helpers, atomic write_dataset."""

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from jointid.data import dataset as measured
from jointid.errors import DataError
from jointid.data.dataset import read_dataset, validate_dataset, write_dataset

PAPER = Path(__file__).resolve().parents[1] / "data" / "paper"
TABLE2 = [344.3, 1416.1, 1879.9, 2017.1, 2519.6, 3096.6]  # paper, Table 2, experimental (Hz)
TABLE3 = [344.3, 1502.7, 2022.4, 2259.1, 2860.6, 3384.2]  # paper, Table 3, experimental (Hz)
POINTS = pd.DataFrame({"point": ["T01", "T02", "B01"], "x_m": [0.0, 0.1, 0.0],
                       "y_m": [0.2, 0.2, 0.0], "z_m": [0.0, 0.0, 0.0]})


# ------------------------------------------------------------------------------ data/paper
def test_paper_dataset_reads_with_the_published_frequencies():
    ds = read_dataset(PAPER, expected_states=["power_off", "power_on"])
    assert ds.states == ["power_off", "power_on"]
    np.testing.assert_array_equal(ds.freqs("power_off"), TABLE2)
    np.testing.assert_array_equal(ds.freqs("power_on"), TABLE3)
    assert ds.shapes is None and ds.frf is None and ds.damping("power_on") is None
    assert ds.state_conditions("power_off") == {"em_force_N": 0.0}
    assert ds.state_conditions("power_on")["em_force_N"] == 1000.0
    assert ds.conditions["frequency_uncertainty_pct"] == 1.0
    assert "CSCBD 2019" in ds.conditions["source"] and "978-1-60595-626-8" in ds.conditions["source"]


def test_paper_conditions_mark_the_assumptions():
    text = (PAPER / "conditions.yaml").read_text()
    assert "Assumption" in text and "2-5 x" in text and "350 N" in text


def test_paper_tables_consistent_with_modes_and_own_errors():
    tables = pd.read_csv(PAPER / "paper_tables.csv")
    assert list(tables.columns) == ["table", "state", "order", "experimental_Hz",
                                    "paper_simulation_Hz", "paper_relative_error_pct"]
    modes = pd.read_csv(PAPER / "modes.csv")
    np.testing.assert_array_equal(tables["experimental_Hz"], modes["freq_Hz"])
    assert list(tables["state"]) == list(modes["state"])
    assert list(tables["table"]) == [2] * 6 + [3] * 6
    recomputed = (100 * (tables["paper_simulation_Hz"] - tables["experimental_Hz"]).abs()
                  / tables["experimental_Hz"])
    off = (recomputed - tables["paper_relative_error_pct"]).abs()
    # one-decimal rounding of the printed errors (Table 3 order 6: 0.845 % printed as 0.9)
    bad = tables[off > 0.056]
    # the one misprint: Table 3 order 3 prints 8.2 % where |2118.0 - 2022.4| / 2022.4 = 4.7 %
    assert list(zip(bad["table"], bad["order"])) == [(3, 3)]
    assert recomputed[bad.index[0]] == pytest.approx(4.727, abs=1e-3)


def test_paper_table1_dynamic_stiffness():
    t1 = pd.read_csv(PAPER / "paper_table1.csv")
    k = dict(zip(t1["state"], t1["paper_dynamic_stiffness_N_per_mm"]))
    assert k == {"power_off": 104547, "power_on": 148551}
    increase = t1.set_index("state").loc["power_on", "paper_increase_pct"]
    assert increase == 42.1
    assert 100 * (k["power_on"] / k["power_off"] - 1) == pytest.approx(increase, abs=0.05)


# ------------------------------------------------------------------------------ helpers
def _tables():
    modes = pd.DataFrame({"state": ["b", "b", "a", "a"], "mode": [2, 1, 1, 2],
                          "freq_Hz": [900.0, 400.0, 350.0, 800.0],
                          "damping_ratio": [0.02, 0.01, 0.03, 0.04]})
    shapes = pd.DataFrame({"state": ["a", "a", "a", "b"], "mode": [1, 1, 2, 1],
                           "point": ["T01", "B01", "T01", "T02"],
                           "direction": ["y", "y", "x", "z"], "value": [1.0, -0.5, 0.25, 2.0]})
    frf = pd.DataFrame({"state": "a", "point": "T02", "direction": "y",
                        "freq_Hz": [300.0, 100.0, 200.0], "re": [3e-8, 1e-8, 2e-8],
                        "im": [-3e-8, -1e-8, -2e-8]})
    conditions = {"source": "unit test", "states": {
        "a": {"em_force_N": np.float64(0.0), "frf_drive_point": "T01", "frf_drive_direction": "y"},
        "b": {"em_force_N": 500.0, "currents": {"exciting_current_A": 3.0}}}}
    return modes, shapes, frf, conditions


def test_write_then_read_round_trip(tmp_path):
    modes, shapes, frf, conditions = _tables()
    ds = write_dataset(tmp_path / "ds", modes, shapes, frf, conditions=conditions,
                       measuring_points=POINTS)
    assert ds.name == "ds"
    assert ds.states == ["b", "a"]  # order of first appearance
    np.testing.assert_array_equal(ds.freqs("b"), [400.0, 900.0])
    np.testing.assert_array_equal(ds.damping("a"), [0.03, 0.04])
    assert ds.state_conditions("b")["currents"] == {"exciting_current_A": 3.0}
    again = read_dataset(tmp_path / "ds", POINTS)  # the dataset returned is the one the files hold, whole
    for name in ("modes", "shapes", "frf"):
        pd.testing.assert_frame_equal(getattr(again, name), getattr(ds, name), check_exact=True)
    assert (again.name, again.conditions, again.states) == (ds.name, ds.conditions, ds.states)
    assert sorted(os.listdir(tmp_path)) == ["ds"]  # no temporary folders left


def test_shape_matrix_fills_measured_and_nan_elsewhere(tmp_path):
    modes, shapes, frf, conditions = _tables()
    ds = write_dataset(tmp_path / "ds", modes, shapes, frf, conditions=conditions)
    phi = ds.shape_matrix("a", ["T01:y", ("B01", "y"), "T01:x", "T02:z"])
    assert phi.shape == (4, 2)
    expected = np.array([[1.0, np.nan], [-0.5, np.nan], [np.nan, 0.25], [np.nan, np.nan]])
    np.testing.assert_array_equal(phi, expected)
    assert ds.shape_matrix("b", ["T02:z"]).tolist() == [[2.0, pytest.approx(np.nan, nan_ok=True)]]
    with pytest.raises(DataError, match="is not '<point>:<direction>'"):
        ds.shape_matrix("a", ["T01-y"])
    with pytest.raises(DataError, match="direction 'q' is not x, y or z"):
        ds.shape_matrix("a", ["T01:q"])


def test_frf_curve_sorted_complex(tmp_path):
    modes, shapes, frf, conditions = _tables()
    ds = write_dataset(tmp_path / "ds", modes, shapes, frf, conditions=conditions)
    f, h = ds.frf_curve("a", "T02", "y")
    np.testing.assert_array_equal(f, [100.0, 200.0, 300.0])
    np.testing.assert_allclose(h, np.array([1, 2, 3]) * (1e-8 - 1e-8j))
    f, h = ds.frf_curve("b", "T02", "y")
    assert f.size == 0 and h.size == 0


def test_unknown_state_raises_with_choices(tmp_path):
    ds = read_dataset(PAPER)
    with pytest.raises(DataError, match="unknown state 'power' — use one of power_off, power_on"):
        ds.freqs("power")


def test_write_refuses_invalid_data_and_leaves_nothing(tmp_path):
    modes, shapes, frf, conditions = _tables()
    modes.loc[0, "freq_Hz"] = -1.0
    with pytest.raises(DataError) as err:
        write_dataset(tmp_path / "ds", modes, conditions=conditions)
    assert str(tmp_path / "ds" / "modes.csv") + ":" in str(err.value)
    assert "is not positive" in str(err.value)
    assert os.listdir(tmp_path) == []


def test_write_replaces_existing_dataset_atomically(tmp_path):
    modes, shapes, frf, conditions = _tables()
    write_dataset(tmp_path / "ds", modes, shapes, frf, conditions=conditions)
    ds = write_dataset(tmp_path / "ds", modes[modes["state"] == "a"],
                       conditions={"source": "v2", "states": {"a": {"em_force_N": 1.0}}})
    assert ds.states == ["a"] and ds.shapes is None and ds.frf is None
    assert sorted(os.listdir(tmp_path / "ds")) == ["conditions.yaml", "modes.csv"]
    assert sorted(os.listdir(tmp_path)) == ["ds"]


def test_failed_swap_keeps_the_old_dataset(tmp_path, monkeypatch):
    modes, shapes, frf, conditions = _tables()
    write_dataset(tmp_path / "ds", modes, conditions=conditions)
    before = (tmp_path / "ds" / "modes.csv").read_text()
    real_replace = os.replace
    calls = []

    def flaky_replace(src, dst):
        calls.append((Path(src).name, Path(dst).name))
        if len(calls) == 2:  # moving the new folder into place fails
            raise OSError("disk full")
        return real_replace(src, dst)

    monkeypatch.setattr(measured.os, "replace", flaky_replace)
    with pytest.raises(OSError, match="disk full"):
        write_dataset(tmp_path / "ds", modes.assign(freq_Hz=modes["freq_Hz"] * 2),
                      conditions=conditions)
    assert (tmp_path / "ds" / "modes.csv").read_text() == before
    assert sorted(os.listdir(tmp_path)) == ["ds"]


def test_write_refuses_folder_with_foreign_files(tmp_path):
    modes, _, _, conditions = _tables()
    (tmp_path / "ds").mkdir()
    (tmp_path / "ds" / "notes.txt").write_text("keep me")
    with pytest.raises(DataError, match=r"notes.txt\) — write to a new folder"):
        write_dataset(tmp_path / "ds", modes, conditions=conditions)
    assert os.listdir(tmp_path / "ds") == ["notes.txt"]


def test_write_requires_columns(tmp_path):
    modes, _, _, conditions = _tables()
    with pytest.raises(DataError, match="lacks column"):
        write_dataset(tmp_path / "ds", modes.drop(columns="freq_Hz"), conditions=conditions)


def test_measuring_points_without_point_column_is_reported(tmp_path):
    problems = validate_dataset(PAPER, pd.DataFrame({"name": ["T01"]}))
    assert problems == ["measuring_points:1: missing column 'point' — pass the table with columns "
                        "point, x_m, y_m, z_m"]


def test_uppercase_direction_is_normalised(tmp_path):
    modes, shapes, _, conditions = _tables()
    ds = write_dataset(tmp_path / "ds", modes, shapes.assign(direction=["Y", "Y", "X", "Z"]),
                       conditions=conditions)
    assert list(ds.shapes["direction"]) == ["y", "y", "x", "z"]


# ------------------------------------------------------------------------------ conditions.yaml numbers
def _write_conditions(folder, text):
    folder.mkdir()
    (folder / "modes.csv").write_text("state,mode,freq_Hz\npower_off,1,344.3\npower_on,1,350.0\n")
    (folder / "conditions.yaml").write_text(text)
    return folder


def test_conditions_accept_exponent_numbers_that_yaml_1_1_reads_as_text(tmp_path):
    # PyYAML (YAML 1.1) reads 1e3, 5e-1 and 2.5E-1 as strings; config.yaml accepts them, so must this
    folder = _write_conditions(tmp_path / "ds", (
        "source: test\nfrequency_uncertainty_pct: 5e-1\nstates:\n"
        "  power_off: {em_force_N: 0e0}\n"
        "  power_on:\n    em_force_N: 1e3\n    motor_position_m: 2.5E-1\n"
        "    currents: {exciting_current_A: 4e0, eddy_current_A: '1.5'}\n"))
    assert validate_dataset(folder) == []
    ds = read_dataset(folder)
    on = ds.state_conditions("power_on")
    assert on["em_force_N"] == 1000.0 and isinstance(on["em_force_N"], float)
    assert on["motor_position_m"] == 0.25
    assert on["currents"] == {"exciting_current_A": 4.0, "eddy_current_A": 1.5}
    assert ds.state_conditions("power_off")["em_force_N"] == 0.0
    assert ds.conditions["frequency_uncertainty_pct"] == 0.5


@pytest.mark.parametrize("text, line", [
    ("em_force_N: 1e3 N", "states.power_on.em_force_N: em_force_N = '1e3 N' is not a number — write the force in N"),
    ("em_force_N: one", "states.power_on.em_force_N: em_force_N = 'one' is not a number — write the force in N"),
    ("em_force_N: .inf", "states.power_on.em_force_N: em_force_N = inf is not a number — write the force in N"),
    ("em_force_N: -1e3", "states.power_on.em_force_N: em_force_N = -1000.0 is negative — give the attraction"),
    ("motor_position_m: 1,5e-1", "states.power_on.motor_position_m: motor_position_m = '1,5e-1' is not a number"),
])
def test_conditions_still_reject_non_numbers(tmp_path, text, line):
    body = "em_force_N: 5.0\n    " + text if not text.startswith("em_force_N") else text
    folder = _write_conditions(tmp_path / "ds", (
        "source: test\nstates:\n  power_off: {em_force_N: 0.0}\n  power_on:\n    " + body + "\n"))
    problems = validate_dataset(folder)
    assert len(problems) == 1 and problems[0].startswith(f"{folder / 'conditions.yaml'}:{line}"), problems


def test_uncertainty_as_text_number_is_accepted_and_text_rejected(tmp_path):
    ok = _write_conditions(tmp_path / "ok", "source: t\nfrequency_uncertainty_pct: 2e0\nstates:\n"
                           "  power_off: {em_force_N: 0}\n  power_on: {em_force_N: 1e3}\n")
    assert read_dataset(ok).conditions["frequency_uncertainty_pct"] == 2.0
    bad = _write_conditions(tmp_path / "bad", "source: t\nfrequency_uncertainty_pct: 2 %\nstates:\n"
                            "  power_off: {em_force_N: 0}\n  power_on: {em_force_N: 1e3}\n")
    assert validate_dataset(bad) == [
        f"{bad / 'conditions.yaml'}:frequency_uncertainty_pct: frequency_uncertainty_pct = '2 %' is not a "
        "number in (0, 100) — give the 1-sigma frequency uncertainty in percent, e.g. 1.0"]


def test_modes_states_is_a_cheap_look_at_the_state_column(tmp_path):
    assert measured.modes_states(PAPER) == ["power_off", "power_on"]
    folder = tmp_path / "ds"
    folder.mkdir()
    assert measured.modes_states(folder) is None  # no modes.csv
    (folder / "modes.csv").write_text("state,mode,freq_Hz\na,1,-5\nb,1,1,2\na,2,100\n")  # bad rows count too
    assert measured.modes_states(folder) == ["a", "b"]
    (folder / "modes.csv").write_text("mode,freq_Hz\n1,100\n")
    assert measured.modes_states(folder) is None  # no state column


def test_a_problem_repeated_on_many_lines_is_said_once_with_its_lines(tmp_path):
    modes, shapes, frf, conditions = _tables()
    many = pd.DataFrame({"state": "a", "point": "T99", "direction": "y", "freq_Hz": np.arange(1.0, 101.0),
                         "re": 1e-8, "im": -1e-8})
    many.loc[50, "point"] = "T02"  # one good line splits the run of bad ones
    with pytest.raises(DataError) as err:
        write_dataset(tmp_path / "ds", modes, shapes, many, conditions=conditions, measuring_points=POINTS)
    about_t99 = [p for p in err.value.problems if "'T99'" in p]
    assert about_t99 == [f"{tmp_path / 'ds' / 'frf.csv'}, 99 lines (2-51, 53-101): point 'T99' is not a measuring "
                         "point — use a name from the measuring-point table (B01, T01, T02)"]
    # a problem on a few lines keeps one line each
    few = many.copy()
    few["point"] = "T02"
    few.loc[[3, 7], "point"] = "T98"
    problems = validate_dataset(_written(tmp_path / "few", modes, shapes, few, conditions), POINTS)
    assert [p.split(": ")[0] for p in problems if "'T98'" in p] == [
        f"{tmp_path / 'few' / 'frf.csv'}:5", f"{tmp_path / 'few' / 'frf.csv'}:9"]


def _written(folder, modes, shapes, frf, conditions):
    """A dataset folder written without validation (to validate it afterwards)."""
    folder.mkdir()
    modes.to_csv(folder / "modes.csv", index=False)
    shapes.to_csv(folder / "shapes.csv", index=False)
    frf.to_csv(folder / "frf.csv", index=False)
    (folder / "conditions.yaml").write_text(yaml.safe_dump(
        {"source": conditions["source"], "states": {s: {k: (float(v) if isinstance(v, np.floating) else v)
                                                       for k, v in c.items()} for s, c in conditions["states"].items()}}))
    return folder


# ------------------------------------------------------------------------------ conditions.yaml test_setup
def test_test_setup_is_read_and_checked(tmp_path):
    good = _write_conditions(tmp_path / "good", (
        "source: t\ntest_setup:\n  excitation: [T05:x, T05:y]\n  response_points: all\n"
        "  response_directions: [x, y, z]\n  note: roving 3-axis sensor\n"
        "states:\n  power_off: {em_force_N: 0}\n  power_on: {em_force_N: 1e3}\n"))
    assert validate_dataset(good) == []
    assert read_dataset(good).conditions["test_setup"]["excitation"] == ["T05:x", "T05:y"]
    bad = _write_conditions(tmp_path / "bad", (
        "source: t\ntest_setup:\n  excitation: [T05-y, 'T05:w']\n  response_directions: [y, q]\n  hammer: steel\n"
        "states:\n  power_off: {em_force_N: 0}\n  power_on: {em_force_N: 1e3}\n"))
    problems = validate_dataset(bad)
    text = "\n".join(problems)
    assert len(problems) == 4, problems
    assert "test_setup.excitation[0]: 'T05-y' is not '<point>:<direction>'" in text
    assert "test_setup.excitation[1]: 'T05:w' is not '<point>:<direction>'" in text
    assert "test_setup.response_directions" in text and "test_setup.hammer: unknown key" in text
