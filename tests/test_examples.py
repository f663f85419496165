"""The runnable examples of docs/examples/ (the Python API, :class:`jointid.Study`), run as a user would.

Each example runs as ``python docs/examples/<name>.py`` from the repository root (a subprocess of the
test venv's Python, BLAS single-threaded) and its printed numbers are checked against what is known
without its solve:

* the table-feed mode against a one-mass estimate ``sqrt(k_feed A / m) / (2 pi)``: the carried mass
  ``m`` (table, carriages, motors; row sums of the mass matrix) on the feed springs of the contact
  area ``A``.  The mode stores 97 % of its strain energy in the joints, so the estimate is within a
  few % of the FE frequency;
* the paper's measured frequencies as ``data/paper/modes.csv`` holds them;
* the identified feed stiffness against the one-mass estimate inverted at the measured 344.3 Hz;
* the hidden effect of a synthetic test named first by the diagnosis, its magnitude recovered.

The four together take well under two minutes on the 2-core machine; each prints its time.  The fifth,
``05_tables.py`` (the whole method: Tables 2-3), runs in tests/test_api_method.py beside the workflow's
coarse run, whose numbers it must equal.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pandas as pd
import pytest
from conftest import run_example as run_in_repo

ROOT = Path(__file__).resolve().parents[1]
TIMES: dict[str, float] = {}
NUMBER = r"(-?[\d.]+(?:e[+-]?\d+)?)"


def run_example(name: str) -> str:
    """Run ``docs/examples/<name>`` from the repository root (:func:`conftest.run_example`); its standard output."""
    out, TIMES[name] = run_in_repo(name)
    return out


@pytest.fixture(scope="module")
def feed_oscillator():
    """``(carried mass kg, joint contact area m^2, default k_feed N/m^3)`` of the coarse rig: the
    one-mass model of the table-feed mode."""
    from jointid import Study
    from jointid.diagnosis.terms import carried_mass_kg

    study = Study.from_config([ROOT / "config.yaml", ROOT / "tests" / "coarse_config.yaml"])
    bounds = study.config["joints"]["parameters"]["k_feed_N_per_m3"]
    model = study.model()
    area = sum(model.meta["contact_area_m2"].values())
    return carried_mass_kg(model), area, math.sqrt(bounds["lower"] * bounds["upper"])


def one_mass_Hz(k_N_per_m3: float, oscillator) -> float:
    mass, area, _ = oscillator
    return math.sqrt(k_N_per_m3 * area / mass) / (2 * math.pi)


def test_01_modes(feed_oscillator):
    out = run_example("01_modes.py")
    rows = re.findall(rf"^\s*(\d+)\s+{NUMBER}\s+(table \w+)\s+{NUMBER}\s*$", out, flags=re.M)
    assert [int(r[0]) for r in rows] == list(range(1, 9)), out
    f1, what = float(rows[0][1]), rows[0][2]
    assert what == "table feed"
    assert f1 == pytest.approx(one_mass_Hz(feed_oscillator[2], feed_oscillator), rel=0.05)
    assert all(float(a[1]) < float(b[1]) for a, b in zip(rows, rows[1:])), "frequencies not ascending"
    stiff = {int(m): (float(a), float(b))
             for m, a, b in re.findall(rf"mode (\d) table \w+\s+{NUMBER} ->\s+{NUMBER} Hz", out)}
    before, after = stiff[1]
    # 3x the feed stiffness: the feed mode rises by less than the one-mass sqrt(3) (the rest of the rig
    # gives too), the first bounce mode hardly moves
    assert 1.5 < after / before < math.sqrt(4.0e10 / feed_oscillator[2])
    assert stiff[2][1] / stiff[2][0] - 1 < 0.02


def test_02_compare(feed_oscillator):
    out = run_example("02_compare.py")
    paper, uff = out.split("UFF test")
    rows = re.findall(rf"^\s*(power_\w+)\s+([1-9])\s+{NUMBER}\s+{NUMBER}\s+{NUMBER}\s+NaN\s+paired\s+(.+?)\s*$",
                      paper, flags=re.M)
    measured = pd.read_csv(ROOT / "data" / "paper" / "modes.csv")
    assert [(s, int(m), float(f)) for s, m, f, *_ in rows] == list(
        measured[["state", "mode", "freq_Hz"]].itertuples(index=False, name=None))
    first = rows[0]
    assert first[5] == "table feed"
    expect = 100 * (one_mass_Hz(feed_oscillator[2], feed_oscillator) / 344.3 - 1)
    assert float(first[4]) == pytest.approx(expect, abs=2.0)
    tested = re.findall(rf"^\s*power_off\s+([1-9])\s+{NUMBER}\s+{NUMBER}\s+{NUMBER}\s+{NUMBER}\s+paired\s+(.+?)\s*$",
                        uff, flags=re.M)
    assert len(tested) == 8, uff
    assert min(float(r[4]) for r in tested) > 0.9  # shapes with 5 % noise still pair clearly by MAC
    feed = next(r for r in tested if r[5] == "table feed")
    # the test has 2.5e10 N/m^3, the model the default: the one-mass ratio, within 3 points
    assert float(feed[3]) == pytest.approx(100 * (math.sqrt(feed_oscillator[2] / 2.5e10) - 1), abs=3.0)


def test_03_identify(feed_oscillator):
    out = run_example("03_identify.py")
    errors = {s: float(e) for s, e in re.findall(rf"^(power_\w+): \d+ iterations.*max \|error\| {NUMBER} %$",
                                                 out, flags=re.M)}
    assert set(errors) == {"power_off", "power_on"}
    assert max(errors.values()) < 10.0  # from 26 % at the defaults (02_compare)
    theta = {n: (float(a), float(b)) for n, a, b in
             re.findall(rf"^(k_\w+_N_per_m3): power_off {NUMBER}, power_on {NUMBER} N/m\^3", out, flags=re.M)}
    mass, area, _ = feed_oscillator
    k_feed = (2 * math.pi * 344.3) ** 2 * mass / area  # the one-mass model at the measured feed mode
    assert theta["k_feed_N_per_m3"][0] == pytest.approx(k_feed, rel=0.05)
    assert theta["k_normal_N_per_m3"][1] > theta["k_normal_N_per_m3"][0]  # powered, the joints stiffen
    # the model at the identified stiffness, compared afresh (a full solve, not the fit's reduced one)
    final = re.search(r"max \|error\| per state: power_off ([\d.]+) %, power_on ([\d.]+) %", out)
    assert max(float(final[1]), float(final[2])) < 10.0


def test_04_diagnose():
    out = run_example("04_diagnose.py")
    assert re.search(r"^best-ranked effect: em_preload$", out, flags=re.M), out
    top = re.search(rf"^\s*em_preload\s+{NUMBER}\s+True\s+{NUMBER}\s+{NUMBER}\s*$", out, flags=re.M)
    assert top, out
    assert float(top[2]) == pytest.approx(0.15, rel=0.25)  # the hidden beta
    ladder = dict(re.findall(rf"^\s*(baseline|\+em_preload \(suggested\))\s+{NUMBER}\s*$", out, flags=re.M))
    assert float(ladder["baseline"]) > 1.0 and float(ladder["+em_preload (suggested)"]) < 1.0  # noise: 0.2 %
    assert "verdict: Missing effect: em_preload" in out


def test_examples_total_time(capsys):
    """Print the examples' times (pytest -s shows them in any case)."""
    if not TIMES:
        pytest.skip("no example ran")
    with capsys.disabled():
        print("\nexamples: " + ", ".join(f"{k} {v:.1f} s" for k, v in TIMES.items())
              + f"; total {sum(TIMES.values()):.1f} s")


def test_the_shipped_defaults_make_a_study_without_a_file():
    """``Study.default()``: the schema's defaults (the paper's rig and data), no config file read; overrides
    merge on top as in ``from_config``."""
    from jointid import Study
    from jointid.config import load_config

    study = Study.default({"mesh": {"element": "hex1"}})
    assert study.config == load_config({}, {"mesh": {"element": "hex1"}})
    assert study.config["measurements"]["dataset"] == "data/paper"
    assert list(study.parameters()["parameter"])[:2] == ["k_normal_N_per_m3", "k_lateral_N_per_m3"]
