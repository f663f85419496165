"""The API runs the method: ``docs/examples/05_tables.py`` (:meth:`jointid.Study.run_method`) reproduces the
coarse workflow's Tables 2-3, and the identification and verification files behind them, byte for byte
(the shared coarse run, ``conftest.coarse_run``); a study comes from a file, the shipped defaults or typed
objects; ``import jointid`` does not load Snakemake."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from conftest import COARSE_CONFIG, REPO, STATES, TABLES, run_example

WORKFLOW_FILES = ("params.json", "verify.csv", "unpaired_visible.csv")


@pytest.fixture(scope="module")
def api_run(tmp_path_factory):
    """The example's output folder (the workflow's files of each state) and its standard output."""
    out = tmp_path_factory.mktemp("api_method")
    stdout, _ = run_example("05_tables.py", str(out), timeout=900)
    return out, stdout


# make test-all, not make test: the example runs the method again beside the shared coarse run (about 70 s on
# the worker that holds that run's group), which took CI to 11 min (659 s at 245373e, idle)
@pytest.mark.extended
def test_the_api_reproduces_tables_2_and_3_of_the_workflow(api_run, coarse_run, capsys):
    """The same numbers as ``snakemake`` on the coarse configuration, not merely close: the same stage
    functions, each handed what the rule's file holds (``jointid.stages.method``)."""
    out, stdout = api_run
    lines = []
    for state, workflow_table in zip(STATES, TABLES):
        ours, theirs = pd.read_csv(out / "tables" / f"{state}.csv"), pd.read_csv(coarse_run / workflow_table)
        assert list(ours.columns) == list(theirs.columns)
        numbers = [c for c in theirs.columns if c != "order"]
        diff = np.nanmax(np.abs(ours[numbers].to_numpy(float) - theirs[numbers].to_numpy(float)))
        lines.append(f"{state}: simulation_Hz API {ours.simulation_Hz.round(4).tolist()}, workflow "
                     f"{theirs.simulation_Hz.round(4).tolist()}; max |difference| {diff:g}")
        assert diff == 0.0, lines[-1]
        assert (out / "tables" / f"{state}.csv").read_bytes() == (coarse_run / workflow_table).read_bytes()
        for name in WORKFLOW_FILES:
            assert (out / "identify" / state / name).read_bytes() == \
                (coarse_run / "results" / "identify" / state / name).read_bytes(), f"{state}/{name} differs"
    with capsys.disabled():
        print("\n" + "\n".join(lines))
    assert "Table 2 (power_off)" in stdout and "Table 3 (power_on)" in stdout


def test_a_study_from_a_file_the_shipped_defaults_or_typed_objects():
    """``Study.from_config`` (YAML files merged in order), ``Study.default`` (no file) and ``Study(settings)``
    (:class:`jointid.config.study.StudySettings`) give the same study for the same configuration."""
    from jointid import Study
    from jointid.config import load_config
    from jointid.config.study import StudySettings
    from jointid.yamlio import read_merged

    files = [REPO / "config.yaml", COARSE_CONFIG]
    from_files = Study.from_config(files)
    typed = Study(StudySettings.from_config(load_config(read_merged(files))))
    assert typed.config == from_files.config
    assert Study.default().config == load_config({})
    assert Study.default(dict(read_merged(files))).config == from_files.config


@pytest.mark.parametrize("module", ["jointid", "jointid.api"])
def test_importing_jointid_does_not_load_snakemake(module):
    """The package and its API load without Snakemake (a notebook, a plain Python session)."""
    code = f"import {module}, sys; assert 'snakemake' not in sys.modules, sorted(m for m in sys.modules if 'snake' in m)"
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
