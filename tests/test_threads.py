"""jointid.threads: pypardiso is pointed at MKL's runtime once, and a user's own setting is kept."""

from __future__ import annotations

import glob
import os
import subprocess
import sys

import pytest

SCRIPT = ("import os, time; from jointid.threads import import_pypardiso; t = time.perf_counter(); "
          "import_pypardiso(); print(os.environ.get('PYPARDISO_MKL_RT', '')); print(time.perf_counter() - t)")


def _run(env_extra: dict) -> list[str]:
    env = {k: v for k, v in os.environ.items() if k != "PYPARDISO_MKL_RT"} | env_extra
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, check=True)
    return out.stdout.split()


def test_the_runtime_in_the_environment_is_found_without_a_tree_search():
    pytest.importorskip("pypardiso")
    libs = sorted(glob.glob(os.path.join(sys.prefix, "lib", "libmkl_rt.so*")), key=len)
    if not libs:
        pytest.skip("MKL's runtime is not in <prefix>/lib here (pypardiso searches itself)")
    path, seconds = _run({})
    assert path == libs[0]
    print(f"import pypardiso: {float(seconds):.3f} s")


def test_a_users_own_setting_is_kept(tmp_path):
    pytest.importorskip("pypardiso")
    libs = sorted(glob.glob(os.path.join(sys.prefix, "lib", "libmkl_rt.so*")), key=len)
    if not libs:
        pytest.skip("MKL's runtime is not in <prefix>/lib here")
    link = tmp_path / "libmkl_rt.so.user"
    link.symlink_to(libs[0])
    assert _run({"PYPARDISO_MKL_RT": str(link)})[0] == str(link)
