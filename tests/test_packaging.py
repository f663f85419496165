"""The wheel of the project ships the config schema, and an installed jointid works outside the checkout.

An installed jointid must validate a config file anywhere: the schema is package data
(``jointid/config/schema.yaml``, read with importlib.resources), not a file found by walking up from
the working directory.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCHEMA_IN_WHEEL = "jointid/config/schema.yaml"
# pip output when the build backend itself is unavailable (not when the project fails to build)
NO_BUILDER = ("invalid command 'bdist_wheel'", "No module named 'setuptools'", "No module named 'wheel'",
              "Cannot import 'setuptools.build_meta'", "Could not find a version that satisfies the requirement",
              "No matching distribution found")


def _run(args: list[str], cwd: Path, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """A wheel built by pip from a copy of the project (setuptools builds inside the source tree, so a
    copy keeps the checkout clean): without build isolation first, else with it (the venv may lack
    setuptools or wheel)."""
    tmp = tmp_path_factory.mktemp("packaging")
    source = tmp / "source"
    source.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(REPO / name, source / name)
    shutil.copytree(REPO / "src", source / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    outputs = []
    for isolation in (["--no-build-isolation"], []):
        out = tmp / f"dist{len(outputs)}"
        res = _run([sys.executable, "-m", "pip", "wheel", "--no-deps", *isolation, "-w", str(out), str(source)],
                   cwd=tmp)
        wheels = sorted(out.glob("jointid-*.whl"))
        if res.returncode == 0 and wheels:
            return wheels[0]
        outputs.append(res.stdout + res.stderr)
    if any(marker in outputs[-1] for marker in NO_BUILDER):
        pytest.skip("pip cannot build a wheel on this machine (no setuptools/wheel in the venv, and none "
                    "to install for an isolated build): " + outputs[-1].strip().splitlines()[-1])
    pytest.fail("pip wheel failed for the project:\n" + "\n".join(outputs[-1].splitlines()[-40:]))


@pytest.fixture(scope="module")
def installed(wheel, tmp_path_factory) -> Path:
    """The wheel installed into a folder of its own (``pip install --target``)."""
    site = tmp_path_factory.mktemp("site")
    res = _run([sys.executable, "-m", "pip", "install", "--no-deps", "--target", str(site), str(wheel)],
               cwd=site.parent)
    assert res.returncode == 0, res.stdout + res.stderr
    return site


def _env(site: Path) -> dict:
    """Environment that imports jointid from ``site`` only (not the checkout's src)."""
    env = {k: v for k, v in os.environ.items() if k != "JOINTID_SCHEMA"}
    env["PYTHONPATH"] = str(site)
    return env


def test_wheel_contains_the_config_schema(wheel):
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
    assert SCHEMA_IN_WHEEL in names
    assert "jointid/config/__main__.py" in names


def test_installed_package_checks_a_config_outside_the_checkout(installed, tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "data").symlink_to(REPO / "data")  # the check also looks for the dataset folder
    env = _env(installed)
    where = _run([sys.executable, "-c", "import jointid.config as c; print(c.find_schema())"], cwd=elsewhere,
                 env=env)
    assert where.returncode == 0, where.stderr
    assert Path(where.stdout.strip()) == (installed / SCHEMA_IN_WHEEL).resolve()

    config = (REPO / "config.yaml").resolve()
    res = _run([sys.executable, "-m", "jointid.config", "check", str(config)], cwd=elsewhere, env=env)
    assert res.returncode == 0, res.stdout + res.stderr
    assert res.stdout.strip() == f"{config}: OK"


def test_installed_cli_prints_the_version(installed, tmp_path):
    version = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]["version"]
    res = _run([sys.executable, "-m", "jointid.cli", "--version"], cwd=tmp_path, env=_env(installed))
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == f"jointid {version}"
