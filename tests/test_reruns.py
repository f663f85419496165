"""Targeted reruns: after a complete run, changing one config value schedules exactly the stages
that use it (checked on a dry run with ``--rerun-triggers params input``)."""

from __future__ import annotations

import pytest

from conftest import CORE_RULES, clone_run, file_hashes, run_snakemake, scheduled_jobs, write_config

pytestmark = pytest.mark.slow

TRIGGERS = ("--rerun-triggers", "params", "input")


@pytest.fixture(scope="module")
def finished(coarse_run, tmp_path_factory):
    """A private copy of the complete coarse run (results and .snakemake metadata)."""
    return clone_run(coarse_run, tmp_path_factory.mktemp("reruns") / "wf")


def dry_run(wd, *configs, triggers=TRIGGERS):
    before = file_hashes(wd)
    proc = run_snakemake(wd, "-n", *triggers, configs=configs)
    assert proc.returncode == 0, proc.stderr
    assert file_hashes(wd) == before, "a dry run must not touch results"
    return scheduled_jobs(proc.stdout + proc.stderr), proc.stdout + proc.stderr


def core(jobs: dict) -> dict:
    return {r: n for r, n in jobs.items() if r in CORE_RULES}


def test_complete_run_is_up_to_date(finished):
    jobs, out = dry_run(finished, triggers=())  # Snakemake's default triggers (mtime, params, code ...)
    assert jobs == {}, f"a complete run schedules jobs again: {jobs}"
    assert "Nothing to be done" in out


DOE_JOBS = 1
"""Jobs of one DOE's modes: solver.method reduced (the default, and the coarse run's) solves every
point in one job (one job per point is method full's fan-out: tests/test_cluster.py)."""


def zoom_chain(finished) -> dict:
    """Jobs of the zoomed second DOE once a first-stage optimum may have moved."""
    return {"scout": 2, "doe_zoom": 1, "modal_zoom": DOE_JOBS, "gather_zoom": 1, "fit_zoom": 1}


@pytest.mark.parametrize("change, expected, zoom", [
    ("identify:\n  frequency_uncertainty_pct: 2.0\n",
     {"identify": 2, "verify": 2, "tables": 1}, True),
    ("identify:\n  fe_polish: false\n",
     {"identify": 2, "verify": 2, "tables": 1}, False),
    ("harmonic:\n  band_Hz: [300.0, 3200.0]\n",
     {"fit_surface": 1, "identify": 2, "verify": 2, "tables": 1}, True),
    ("doe:\n  zoom:\n    half_width_decades: 0.2\n",
     {"identify": 2, "verify": 2, "tables": 1}, "box"),
    ("mesh:\n  extrapolate_edges: false\n",
     {"identify": 2, "verify": 2, "tables": 1}, False),
], ids=["frequency_uncertainty", "fe_polish", "harmonic_band", "zoom_width", "extrapolate_edges"])
def test_one_changed_value_reruns_only_its_stages(finished, change, expected, zoom):
    """The first-stage optima (scout) feed the zoomed DOE: what changes them reruns its fan-out;
    what only the final identification reads (the FE polish switch) does not."""
    override = write_config(finished / "override.yaml", change)
    try:
        jobs, out = dry_run(finished, override)
    finally:
        override.unlink()
    if zoom:  # True: from the scout on; "box": from the zoomed DOE on (the scout is unchanged)
        expected = {**zoom_chain(finished), **expected}
        if zoom == "box":
            expected.pop("scout")
    assert core(jobs) == expected, out[-3000:]
    assert not {"mesh", "doe", "modal", "gather_modal"} & set(jobs)


def test_solver_change_reruns_the_fanout_but_not_the_mesh(finished):
    override = write_config(finished / "override.yaml", "solver:\n  n_modes: 14\n")
    try:
        jobs, out = dry_run(finished, override)
    finally:
        override.unlink()
    assert core(jobs) == {"modal": DOE_JOBS, "gather_modal": 1, "fit_surface": 1, **zoom_chain(finished),
                          "identify": 2, "verify": 2, "tables": 1}, out[-3000:]


@pytest.mark.parametrize("change, unaffected", [
    ("harmonic:\n  n_freq: 801\n", {"fit_surface": 0, "identify": 0, "verify": 0, "tables": 0}),
    ("states:\n  power_on:\n    em_force_N: 1200.0\n", {"scout": 0, "doe_zoom": 0, "identify": 1, "verify": 1,
                                                      "harmonic": 1}),
    ("solver:\n  rom_tolerance: 2.0e-4\n", {"modal": 0, "fit_surface": 0, "modal_zoom": 0, "identify": 0,
                                           "verify": 0}),
    ("carriage_rigidity:\n  cell_size_m: 0.01\n", {"carriage_rigidity": 1, "identify": 0, "verify": 0,
                                                   "harmonic": 0, "mesh": 0, "report": 1}),
], ids=["harmonic_n_freq", "one_state", "rom_tolerance_unused", "carriage_rigidity_only"])
def test_value_used_elsewhere_does_not_rerun_the_chain(finished, change, unaffected):
    """harmonic.n_freq is not used by the identification chain; power_on's force not by power_off
    (exactly the power_on jobs rerun)."""
    override = write_config(finished / "override.yaml", change)
    try:
        jobs, out = dry_run(finished, override)
    finally:
        override.unlink()
    for rule, n in unaffected.items():
        assert jobs.get(rule, 0) == n, f"{rule}: {jobs.get(rule, 0)} jobs scheduled\n" + out[-3000:]
    assert not {"mesh", "doe", "modal", "gather_modal"} & set(jobs)
