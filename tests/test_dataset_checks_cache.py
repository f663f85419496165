"""jointid.data.checked: a dataset folder's checks are remembered by its content and the code, and computed
again when either changes."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import jointid.data.dataset as dataset
import jointid.version
from jointid.data import checked

PAPER = Path(__file__).resolve().parents[1] / "data" / "paper"


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv("JOINTID_CACHE_DIR", str(tmp_path / "cache"))
    out = tmp_path / "ds"
    shutil.copytree(PAPER, out)
    return out


def _count_validations(monkeypatch) -> list:
    calls = []
    real = dataset.validate_dataset

    def counted(path, *a, **k):
        calls.append(str(path))
        return real(path, *a, **k)

    monkeypatch.setattr(dataset, "validate_dataset", counted)
    return calls


def test_an_unchanged_folder_is_answered_from_the_cache(folder, monkeypatch):
    calls = _count_validations(monkeypatch)
    first = checked.folder_checks(folder)
    assert first == ({"power_off": 6, "power_on": 6}, [])  # data/paper: six modes per state, valid
    assert checked.folder_checks(folder) == first and len(calls) == 1  # the second answer is the kept one


def test_a_changed_file_or_code_is_checked_again(folder, monkeypatch):
    calls = _count_validations(monkeypatch)
    checked.folder_checks(folder)
    modes = folder / "modes.csv"
    modes.write_text(modes.read_text().replace("power_off,2,1416.1", "power_off,2,-1416.1"))
    states, problems = checked.folder_checks(folder)
    assert len(calls) == 2 and any("-1416.1" in p for p in problems), problems  # the new problem is found
    monkeypatch.setattr(jointid.version, "code_digest", lambda: "other code")
    assert checked.folder_checks(folder) == (states, problems) and len(calls) == 3  # other code: checked again


def test_a_cache_that_cannot_be_written_changes_nothing(folder, monkeypatch, tmp_path):
    (tmp_path / "a_file").write_text("")
    monkeypatch.setenv("JOINTID_CACHE_DIR", str(tmp_path / "a_file" / "cache"))  # below a file: not creatable
    calls = _count_validations(monkeypatch)
    assert checked.folder_checks(folder) == checked.folder_checks(folder) == ({"power_off": 6, "power_on": 6}, [])
    assert len(calls) == 2 and not list(tmp_path.glob("a_file*/**"))


def test_other_files_in_the_folder_are_not_read(folder, monkeypatch):
    calls = _count_validations(monkeypatch)
    checked.folder_checks(folder)
    (folder / "raw_time_histories.bin").write_bytes(b"\0" * 1000)  # not a dataset file: the key stays
    checked.folder_checks(folder)
    assert len(calls) == 1
    (folder / "modes.csv").unlink()  # a dataset file gone: checked again, and said
    states, problems = checked.folder_checks(folder)
    assert len(calls) == 2 and states is None and any("modes.csv" in p for p in problems)
