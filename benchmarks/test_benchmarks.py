"""The benchmarks' hot paths as pytest-benchmark tests, on the coarse test mesh.

    pip install -e ".[bench]"
    pytest benchmarks --benchmark-only                        # statistics table
    pytest benchmarks --benchmark-only --benchmark-autosave   # keep a run (.benchmarks/)
    pytest benchmarks --benchmark-only --benchmark-compare    # compare with the last kept run

Each test times one path in-process with the ``benchmark`` fixture and checks that it still gives
the right answer, so a speed-up that breaks a result fails.  The figures against the targets (default
mesh, subprocesses, peak memory) come from ``python -m benchmarks``; these tests are for tracking
regressions between commits.  They are not part of the test suite (``testpaths = tests``).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pytest_benchmark")

from jointid.config import load_config  # noqa: E402
from jointid.identification.doe import to_physical  # noqa: E402
from jointid.fe.modal import solve_model  # noqa: E402
from jointid.fe.model import base_coefficients, build_model  # noqa: E402
from jointid.identification.rom import frequency_error  # noqa: E402
from jointid.identification.rom_build import RomOptions, build_rom  # noqa: E402
from jointid.config.typed import ModelSpec

from .common import COARSE, ROOT  # noqa: E402

N_MODES = 12


@pytest.fixture(scope="module")
def cfg():
    return load_config(ROOT / "config.yaml", overrides=COARSE)


@pytest.fixture(scope="module")
def model(cfg):
    return build_model(ModelSpec.from_config(cfg))


def _random_points(cfg, n, seed):
    names = list(cfg["joints"]["parameters"])
    lo = [cfg["joints"]["parameters"][k]["lower"] for k in names]
    hi = [cfg["joints"]["parameters"][k]["upper"] for k in names]
    X = to_physical(np.random.default_rng(seed).uniform(-1, 1, size=(n, len(names))), lo, hi)
    return [dict(zip(names, row.tolist())) for row in X]


def test_a_model_assembly(benchmark, cfg):
    model = benchmark.pedantic(build_model, args=(cfg,), rounds=3, iterations=1)
    benchmark.extra_info["n_dofs"] = model.n_dofs
    assert model.stiffness["K0"].shape == (model.n_dofs, model.n_dofs)


def test_a_modal_solve(benchmark, cfg, model):
    kc, mc = base_coefficients(ModelSpec.from_config(cfg), model)
    s = cfg["solver"]
    modes = benchmark.pedantic(solve_model, args=(model, kc, mc, N_MODES),
                               kwargs={"shift_Hz": s["shift_Hz"], "backend": s["backend"]}, rounds=3, iterations=1)
    benchmark.extra_info["n_dofs"] = model.n_dofs
    assert np.all(np.diff(modes.freqs_Hz) >= 0) and modes.freqs_Hz[0] > 0


def test_a_idiomatic_scikit_fem_path(benchmark):
    from .worker import task_idiomatic

    out = benchmark.pedantic(task_idiomatic, args=({"overrides": COARSE, "n_modes": N_MODES},), rounds=1,
                             iterations=1)
    benchmark.extra_info["solid_assembly_ratio"] = out["t_solid_idiomatic_s"] / out["t_solid_jointid_s"]
    assert out["K0_max_rel_diff"] < 1e-12 and out["M0_max_rel_diff"] < 1e-12


@pytest.fixture(scope="module")
def rom(cfg, model):
    return build_rom(model, ModelSpec.from_config(cfg), "corners", RomOptions(N_MODES, seed=0, keep_basis=False))


def test_b_rom_evaluation(benchmark, cfg, model, rom):
    theta = _random_points(cfg, 1, seed=1)[0]
    kc, mc = base_coefficients(ModelSpec.from_config(cfg), model, theta)
    f_rom = benchmark(rom.frequencies, *rom.coefficients(theta), check=False)
    full = solve_model(model, kc, mc, N_MODES, shift_Hz=cfg["solver"]["shift_Hz"])
    err = np.nanmax(frequency_error(f_rom, full.freqs_Hz, cfg["solver"]["min_freq_Hz"]))
    benchmark.extra_info.update({"rom_size": rom.size, "max_relative_error": float(err)})
    assert err <= 1e-4


def test_c_workflow_coarse(benchmark):
    from .bench_c_workflow import _run_workflow

    out = benchmark.pedantic(_run_workflow, args=(True, 1, False, "full"), rounds=1, iterations=1)
    benchmark.extra_info.update({"peak_memory_MB": out["peak_tree_MB"], "n_jobs": out["n_jobs"]})
    assert out["exit"] == 0, out["log_tail"]
