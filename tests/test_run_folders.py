"""One study, one folder (issue 53): a configuration with ``run.name`` writes under results/<name>/,
logs/<name>/ and benchmarks/out/<name>/, so that two studies in one working folder never write over
each other; without a name (the paper's configuration) nothing moves."""

from __future__ import annotations

import re
import shutil

import pytest

from conftest import REPO, copy_workflow, run_snakemake
from jointid.config.load import load_config
from jointid.config.snakefile import run_folders
from jointid.errors import ConfigError

EXAMPLE = "examples/single_carriage"


def test_run_folders_default_and_named():
    assert run_folders({}) == ("results", "logs", "benchmarks/out")
    assert run_folders({"run": {"name": ""}}) == ("results", "logs", "benchmarks/out")
    assert run_folders({"run": {"name": "rig_b"}}) == ("results/rig_b", "logs/rig_b", "benchmarks/out/rig_b")


@pytest.mark.parametrize("name, why", [("tables", "is the folder of a stage"), ("my run", "run.name")])
def test_a_run_name_that_would_mix_studies_or_paths_is_refused(name, why):
    with pytest.raises(ConfigError) as err:
        load_config(str(REPO / "config.yaml"), overrides={"run": {"name": name}})
    assert why in str(err.value)


def test_the_examples_plan_touches_only_its_own_folders(tmp_path):
    """Known truth: the planned outputs, logs and benchmark files of the shipped single-carriage example
    (dry run) all lie under its run.name folders; none is one of the paper's files."""
    work = copy_workflow(tmp_path / "work")
    shutil.copytree(REPO / EXAMPLE, work / EXAMPLE)
    proc = run_snakemake(work, "-n", configs=[f"{EXAMPLE}/config.yaml"], check=True)
    text = proc.stdout + proc.stderr
    planned = set()
    for key in ("output", "log", "benchmark"):
        for line in re.findall(rf"^\s+{key}: (.+)$", text, flags=re.M):
            planned.update(p.strip() for p in line.split(","))
    assert len(planned) > 50, text[-2000:]
    own = ("results/single_carriage/", "logs/single_carriage/", "benchmarks/out/single_carriage/")
    assert all(p.startswith(own) for p in planned), sorted(p for p in planned if not p.startswith(own))[:10]
