"""Bad-input corpus for measured datasets: each case breaks one thing and pins the exact message."""

import re

import pandas as pd
import pytest

from jointid.errors import DataError
from jointid.data.dataset import read_dataset, validate_dataset

POINTS = pd.DataFrame({"point": ["T01", "T02", "B01", "B02"],
                       "x_m": [0.0, 0.1, 0.0, 0.1], "y_m": [0.2, 0.2, 0.0, 0.0],
                       "z_m": [0.0, 0.0, 0.0, 0.0]})

MODES = """state,mode,freq_Hz,damping_ratio
power_off,1,344.3,0.02
power_off,2,1416.1,0.015
power_off,3,1879.9,0.01
power_on,1,344.3,0.02
power_on,2,1502.7,0.015
power_on,3,2022.4,0.01
"""
CONDITIONS = """source: test rig, hammer test 2024-05-01
frequency_uncertainty_pct: 1.0
states:
  power_off:
    em_force_N: 0.0
    frf_drive_point: T01
    frf_drive_direction: y
  power_on:
    em_force_N: 1000.0
    currents: {exciting_current_A: 5.0, eddy_current_A: 1.0}
    motor_position_m: 0.25
    frf_drive_point: T01
    frf_drive_direction: y
"""


def _shapes():
    rows = ["state,mode,point,direction,value"]
    for state in ("power_off", "power_on"):
        for mode in (1, 2, 3):
            for k, point in enumerate(("T01", "T02", "B01")):
                rows.append(f"{state},{mode},{point},y,{0.1 * (k + 1) * mode}")
    return "\n".join(rows) + "\n"


def _frf():
    rows = ["state,point,direction,freq_Hz,re,im"]
    for state in ("power_off", "power_on"):
        for f in (100.0, 200.0, 300.0):
            rows.append(f"{state},T02,y,{f},1.0e-8,-2.0e-8")
    return "\n".join(rows) + "\n"


def make_valid(folder):
    folder.mkdir()
    (folder / "modes.csv").write_text(MODES)
    (folder / "shapes.csv").write_text(_shapes())
    (folder / "frf.csv").write_text(_frf())
    (folder / "conditions.yaml").write_text(CONDITIONS)
    return folder


def edit(name, old, new):
    def mutate(folder):
        path = folder / name
        text = path.read_text()
        assert old in text, (old, name)
        path.write_text(text.replace(old, new, 1))
    return mutate


def write(name, text):
    def mutate(folder):
        (folder / name).write_text(text)
    return mutate


def remove(name):
    def mutate(folder):
        (folder / name).unlink()
    return mutate


# (id, mutation, key phrases (each must occur in one problem line), number of problem lines)
CASES = [
    ("modes_missing", remove("modes.csv"),
     ["modes.csv: file is missing — add modes.csv with columns state,mode,freq_Hz"], None),
    ("missing_column", edit("modes.csv", "state,mode,freq_Hz,damping_ratio",
                            "state,mode,damping_ratio"),
     ["modes.csv:1: missing column 'freq_Hz' — add it (required columns: state, mode, freq_Hz)"],
     None),
    ("unknown_column", edit("modes.csv", "damping_ratio\n", "damping_ratio,temperature_C\n"),
     ["modes.csv:1: unknown column 'temperature_C' — allowed columns are state, mode, freq_Hz, "
      "damping_ratio"], None),
    ("khz_column_name", edit("modes.csv", "freq_Hz", "freq_kHz"),
     ["modes.csv:1: unknown column 'freq_kHz' — convert the values to Hz and rename the column "
      "to freq_Hz", "modes.csv:1: missing column 'freq_Hz'"], 2),
    ("semicolons", write("modes.csv", MODES.replace(",", ";")),
     ["modes.csv:1: header is not comma-separated (found ';') — save as comma-separated CSV"], 1),
    ("empty_modes", write("modes.csv", "state,mode,freq_Hz\n"),
     ["modes.csv:2: no modes — add one row per measured mode"], None),
    ("non_numeric", edit("modes.csv", "1416.1", "abc"),
     ["modes.csv:3: freq_Hz = 'abc' is not a number — write a plain number such as 344.3"], 1),
    ("decimal_comma", edit("modes.csv", "power_off,2,1416.1,0.015", "power_off,2,1416,1,0.015"),
     ["modes.csv:3: row has 5 fields but the header has 4 — check for a decimal comma"], 1),
    ("empty_value", edit("modes.csv", "1416.1", ""),
     ["modes.csv:3: freq_Hz is empty — fill in the value or delete the row"], 1),
    ("nan_value", edit("modes.csv", "1416.1", "NaN"),
     ["modes.csv:3: freq_Hz = NaN is not a finite number — replace it by a measured value"], 1),
    ("negative_freq", edit("modes.csv", "1416.1", "-1416.1"),
     ["modes.csv:3: freq_Hz = -1416.1 is not positive — natural frequencies are > 0 Hz"], 1),
    ("zero_freq", edit("modes.csv", "power_on,1,344.3", "power_on,1,0"),
     ["modes.csv:5: freq_Hz = 0 is not positive"], 1),
    ("khz_values", write("modes.csv", "state,mode,freq_Hz\npower_off,1,0.3443\npower_off,2,1.4161\n"
                         "power_off,3,1.8799\npower_on,1,0.3443\npower_on,2,1.5027\n"
                         "power_on,3,2.0224\n"),
     ["modes.csv:7: largest freq_Hz = 2.0224 is below 20 Hz; values look like kHz — multiply all "
      "frequencies by 1000 to convert to Hz"], 1),
    ("duplicate_mode", edit("modes.csv", "power_off,3,1879.9", "power_off,2,1879.9"),
     ["modes.csv:4: duplicate mode 2 of state power_off (also on line 3) — keep one row per "
      "(state, mode)"], 1),
    ("unsorted", edit("modes.csv", "power_off,3,1879.9", "power_off,3,1000.0"),
     ["modes.csv:4: mode 3 of state power_off (1000 Hz) is below mode 2 (1416.1 Hz) — number the "
      "modes by increasing frequency"], 1),
    ("mode_gap", edit("modes.csv", "power_off,3,1879.9", "power_off,4,1879.9"),
     ["modes.csv:4: state power_off has modes 1, 2, 4; mode 4 breaks the sequence — number the "
      "modes 1..3 without gaps"], None),
    ("mode_not_integer", edit("modes.csv", "power_off,2,", "power_off,1.5,"),
     ["modes.csv:3: mode = 1.5 is not a whole number — number the modes 1, 2, 3, ... per state"],
     1),
    ("damping_percent", edit("modes.csv", "1416.1,0.015", "1416.1,1.5"),
     ["modes.csv:3: damping_ratio = 1.5 looks like percent — divide by 100"], 1),
    ("damping_zero", edit("modes.csv", "1416.1,0.015", "1416.1,0"),
     ["modes.csv:3: damping_ratio = 0 is outside (0, 1) — give the viscous damping ratio"], 1),
    ("shapes_unknown_state", edit("shapes.csv", "power_off,1,T01", "power_of,1,T01"),
     ["shapes.csv:2: state 'power_of' is not in modes.csv — fix the name (states: power_off, "
      "power_on) or add its modes"], 1),
    ("shapes_unknown_mode", edit("shapes.csv", "power_off,1,T01", "power_off,7,T01"),
     ["shapes.csv:2: mode 7 of state power_off is not in modes.csv — delete these shape rows or "
      "add the mode"], 1),
    ("shapes_unknown_point", edit("shapes.csv", "power_off,1,T01", "power_off,1,T001"),
     ["shapes.csv:2: point 'T001' is not a measuring point — did you mean 'T01'? use a name from "
      "the measuring-point table"], 1),
    ("shapes_bad_direction", edit("shapes.csv", "power_off,1,T01,y", "power_off,1,T01,w"),
     ["shapes.csv:2: direction = 'w' is not x, y or z — use x (lateral), y (vertical) or z (feed)"],
     1),
    ("shapes_rotation", edit("shapes.csv", "power_off,1,T01,y", "power_off,1,T01,rx"),
     ["shapes.csv:2: direction = 'rx' is a rotation — keep translations x, y, z only"], 1),
    ("shapes_all_zero", lambda f: (f / "shapes.csv").write_text(
        _shapes().replace("power_off,1,T01,y,0.1", "power_off,1,T01,y,0")
                 .replace("power_off,1,T02,y,0.2", "power_off,1,T02,y,0.0")
                 .replace("power_off,1,B01,y,0.30000000000000004", "power_off,1,B01,y,0")),
     ["shapes.csv:2: mode shape 1 of state power_off is all zeros — check the export"], 1),
    ("shapes_duplicate", edit("shapes.csv", "power_off,1,T02", "power_off,1,T01"),
     ["shapes.csv:3: duplicate shape value for state power_off, mode 1, T01:y (also on line 2) — "
      "keep one row"], 1),
    ("frf_zero_freq", edit("frf.csv", "power_off,T02,y,100.0", "power_off,T02,y,0"),
     ["frf.csv:2: freq_Hz = 0 is not positive — delete the 0 Hz line"], 1),
    ("frf_unknown_state", edit("frf.csv", "power_off,T02,y,100.0", "state3,T02,y,100.0"),
     ["frf.csv:2: state 'state3' is not in modes.csv"], 1),
    ("frf_accelerance", write("frf.csv", _frf().replace("1.0e-8,-2.0e-8", "0.5,-1.5")),
     ["frf.csv:2: median |H| = 1.58 is too large for a receptance in m/N; values look like "
      "accelerance ((m/s^2)/N) or mm/N — convert to receptance in m/N"], 1),
    ("frf_no_drive_point", edit("conditions.yaml", "    em_force_N: 0.0\n    frf_drive_point: T01\n",
                                "    em_force_N: 0.0\n"),
     ["conditions.yaml:states.power_off: frf.csv has FRFs for this state but the drive point is "
      "not given — add frf_drive_point and frf_drive_direction"], 1),
    ("conditions_missing", remove("conditions.yaml"),
     ["conditions.yaml: file is missing — add conditions.yaml with 'source:' and 'states:'"], 1),
    ("conditions_empty", write("conditions.yaml", "# nothing yet\n"),
     ["conditions.yaml:1: file is empty — write 'source: ...' and 'states:'"], 1),
    ("conditions_not_mapping", write("conditions.yaml", "- power_off\n- power_on\n"),
     ["conditions.yaml:1: top level is a list, not a mapping — write 'source: ...'"], 1),
    ("yaml_syntax", edit("conditions.yaml", "    motor_position_m: 0.25\n",
                         "    motor_position_m: 0.25\n   bad: [1, 2\n"),
     ["conditions.yaml:12: YAML syntax error: ", "— fix the indentation, colon or quoting on "
      "that line"], 1),
    ("yaml_duplicate_key", edit("conditions.yaml", "  power_on:\n", "  power_off:\n"),
     ["conditions.yaml:8: key states.power_off appears twice — keep one of them"], None),
    ("source_missing", edit("conditions.yaml", "source: test rig, hammer test 2024-05-01\n", ""),
     ["conditions.yaml:source: source is missing or empty — add 'source: <where the data came "
      "from"], 1),
    ("state_missing", edit("conditions.yaml", "  power_on:\n    em_force_N: 1000.0\n",
                           "  power_on_:\n    em_force_N: 1000.0\n"),
     ["conditions.yaml:states: state 'power_on' of modes.csv is missing — add states.power_on "
      "with em_force_N", "conditions.yaml:states.power_on_: state is not in modes.csv — fix the "
      "name (states: power_off, power_on) or remove it"], 2),
    ("em_force_missing", edit("conditions.yaml", "    em_force_N: 1000.0\n", ""),
     ["conditions.yaml:states.power_on: em_force_N is missing — add em_force_N: <vertical motor "
      "attraction in N, 0 when powered off>"], 1),
    ("em_force_negative", edit("conditions.yaml", "em_force_N: 1000.0", "em_force_N: -5.0"),
     ["conditions.yaml:states.power_on.em_force_N: em_force_N = -5.0 is negative — give the "
      "attraction as a magnitude (>= 0 N)"], 1),
    ("em_force_text", edit("conditions.yaml", "em_force_N: 1000.0", "em_force_N: 1 kN"),
     ["conditions.yaml:states.power_on.em_force_N: em_force_N = '1 kN' is not a number — write "
      "the force in N"], 1),
    ("current_negative", edit("conditions.yaml", "exciting_current_A: 5.0",
                              "exciting_current_A: -2.0"),
     ["conditions.yaml:states.power_on.currents.exciting_current_A: exciting_current_A = -2.0 is "
      "negative — give the RMS current magnitude (>= 0 A)"], 1),
    ("state_key_typo", edit("conditions.yaml", "motor_position_m: 0.25", "motor_pos_m: 0.25"),
     ["conditions.yaml:states.power_on.motor_pos_m: unknown key 'motor_pos_m' — allowed keys are "
      "em_force_N, currents, motor_position_m, frf_drive_point, frf_drive_direction, notes (did "
      "you mean 'motor_position_m'?)"], 1),
    ("drive_point_unknown", edit("conditions.yaml", "frf_drive_point: T01", "frf_drive_point: X01"),
     ["conditions.yaml:states.power_off.frf_drive_point: frf_drive_point 'X01' is not a "
      "measuring point — use a name from the measuring-point table (B01, B02, T01, T02)"], 1),
    ("uncertainty_negative", edit("conditions.yaml", "frequency_uncertainty_pct: 1.0",
                                  "frequency_uncertainty_pct: -1.0"),
     ["conditions.yaml:frequency_uncertainty_pct: frequency_uncertainty_pct = -1.0 is not a number "
      "in (0, 100) — give the 1-sigma frequency uncertainty in percent"], 1),
]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_bad_dataset_reports_file_row_and_fix(tmp_path, case):
    _, mutate, phrases, n_lines = case
    folder = make_valid(tmp_path / "ds")
    mutate(folder)
    problems = validate_dataset(folder, POINTS)
    for phrase in phrases:
        assert any(phrase in line for line in problems), (phrase, problems)
    for line in problems:  # every line: where: what — fix
        assert re.match(r"^\S.*: .+ — .+$", line), line
    if n_lines is not None:
        assert len(problems) == n_lines, problems
    with pytest.raises(DataError) as err:
        read_dataset(folder, POINTS)
    assert err.value.problems == problems


def test_corpus_is_large_and_distinct():
    assert len(CASES) >= 25
    assert len({c[0] for c in CASES}) == len(CASES)


def test_valid_dataset_passes(tmp_path):
    folder = make_valid(tmp_path / "ds")
    assert validate_dataset(folder, POINTS, expected_states=["power_off", "power_on"]) == []
    ds = read_dataset(folder, POINTS)
    assert ds.states == ["power_off", "power_on"]


def test_folder_missing(tmp_path):
    problems = validate_dataset(tmp_path / "nope")
    assert len(problems) == 1
    assert "nope: dataset folder does not exist — check the path" in problems[0]


def test_folder_is_a_file(tmp_path):
    (tmp_path / "modes.csv").write_text(MODES)
    problems = validate_dataset(tmp_path / "modes.csv")
    assert problems == [f"{tmp_path / 'modes.csv'}: is a file, not a folder — pass the folder "
                        "that holds modes.csv and conditions.yaml"]


def test_expected_state_missing(tmp_path):
    folder = make_valid(tmp_path / "ds")
    problems = validate_dataset(folder, POINTS, expected_states=["power_off", "power_mid"])
    assert len(problems) == 2
    assert "modes.csv: expected state 'power_mid' has no modes" in problems[0]
    assert "conditions.yaml:states: expected state 'power_mid' is missing — add " \
           "states.power_mid with em_force_N" in problems[1]


def test_three_faults_give_three_lines_at_once(tmp_path):
    folder = make_valid(tmp_path / "ds")
    edit("modes.csv", "1416.1", "-1416.1")(folder)
    edit("shapes.csv", "power_off,1,T01,y", "power_off,1,T01,w")(folder)
    edit("conditions.yaml", "em_force_N: 1000.0", "em_force_N: -5.0")(folder)
    with pytest.raises(DataError) as err:
        read_dataset(folder, POINTS)
    lines = str(err.value).splitlines()
    assert len(lines) == 3 == len(err.value.problems)
    assert "modes.csv:3: freq_Hz = -1416.1 is not positive" in lines[0]
    assert "shapes.csv:2: direction = 'w' is not x, y or z" in lines[1]
    assert "conditions.yaml:states.power_on.em_force_N: em_force_N = -5.0 is negative" in lines[2]
