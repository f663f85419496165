"""jointid.config.remembered: the Snakefile's validated configuration is remembered by what it depends on, and
validated again when any of that changes."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml

from jointid.config.load import load_config
from jointid.config.remembered import validated_once
from jointid.data import checked
from jointid.errors import ConfigError

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def counted(tmp_path, monkeypatch):
    monkeypatch.setenv("JOINTID_CACHE_DIR", str(tmp_path / "cache"))
    calls = []

    def validate(raw):
        calls.append(raw)
        return load_config(raw)

    return calls, validate


def test_the_same_configuration_is_validated_once_and_given_back_equal(counted):
    calls, validate = counted
    raw = yaml.safe_load((REPO / "config.yaml").read_text())
    first = validated_once(dict(raw), validate)
    again = validated_once(dict(raw), validate)
    assert len(calls) == 1 and again == first == load_config(dict(raw))
    assert [type(v) for v in again.values()] == [type(v) for v in first.values()]
    changed = validated_once({**raw, "solver": {**raw.get("solver", {}), "n_modes": 13}}, validate)
    assert len(calls) == 2 and changed["solver"]["n_modes"] == 13  # another configuration: validated


def test_a_changed_dataset_folder_or_mesh_file_is_validated_again(counted, tmp_path, monkeypatch):
    calls, _ = counted
    folder = tmp_path / "ds"
    shutil.copytree(REPO / "data" / "paper", folder)
    mesh = tmp_path / "frame.msh"

    def validate(raw):  # what the real validation asks: the folder's checks, a mesh model's files
        calls.append(raw)
        checked.folder_checks(folder)
        return {"model": {"kind": "mesh", "path": str(mesh), "points": str(folder / "points.csv")}, "n": 1}

    validated_once({"a": 1}, validate)
    validated_once({"a": 1}, validate)
    assert len(calls) == 1
    (folder / "modes.csv").write_text((folder / "modes.csv").read_text() + "\n")
    validated_once({"a": 1}, validate)
    assert len(calls) == 2  # the folder's files changed
    mesh.write_text("$MeshFormat\n")
    validated_once({"a": 1}, validate)
    assert len(calls) == 3  # the mesh file now exists
    validated_once({"a": 1}, validate)
    assert len(calls) == 3


def test_a_configuration_with_problems_is_never_remembered(counted):
    calls, _ = counted

    def validate(raw):
        calls.append(raw)
        raise ConfigError("solver.n_modes: -1 is below 1 — give a positive number")

    for _ in range(2):
        with pytest.raises(ConfigError):
            validated_once({"solver": {"n_modes": -1}}, validate)
    assert len(calls) == 2


def test_a_configuration_json_would_change_is_validated_every_time(counted):
    calls, _ = counted

    def validate(raw):
        calls.append(raw)
        return {"pair": (1, 2)}  # a tuple comes back from JSON as a list: not remembered

    assert validated_once({"b": 1}, validate) == validated_once({"b": 1}, validate) == {"pair": (1, 2)}
    assert len(calls) == 2
