"""Measurement tasks run in a subprocess: ``python -m benchmarks.worker <task> '<json args>'``.

Each task prints one JSON line with its timings and ``peak_rss_MB`` (this process's ``ru_maxrss``).
Args common to all tasks: ``overrides`` (nested mapping merged over ``config.yaml``), ``n_modes``.
"""

from __future__ import annotations

import json
import resource
import sys
import time
from pathlib import Path

import numpy as np
from jointid.config.typed import ModelSpec

ROOT = Path(__file__).resolve().parents[1]


def _cfg(args: dict) -> dict:
    from jointid.config import load_config

    return load_config(ROOT / "config.yaml", overrides=args.get("overrides") or None)


def _peak_rss_MB() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB on Linux


def _full_solve(cfg, model, kc, mc, n, backend=None):
    from jointid.fe.modal import solve_model

    s = cfg["solver"]
    return solve_model(model, kc, mc, n, shift_Hz=s["shift_Hz"], backend=backend or s["backend"])


def task_solve(args: dict) -> dict:
    """Model assembly (``build_model``) and one modal solve at the default joint parameters."""
    from jointid.fe.modal import available_backend
    from jointid.fe.model import base_coefficients, build_model

    cfg = _cfg(args)
    n = int(args.get("n_modes", 12))
    t0 = time.perf_counter()
    model = build_model(ModelSpec.from_config(cfg))
    t1 = time.perf_counter()
    kc, mc = base_coefficients(ModelSpec.from_config(cfg), model, args.get("theta"))
    modes = _full_solve(cfg, model, kc, mc, n, args.get("backend"))
    t2 = time.perf_counter()
    return {"n_dofs": model.n_dofs, "n_free": int(model.n_dofs - len(model.fixed)),
            "n_elements": model.meta["n_elements"], "t_assembly_s": t1 - t0, "t_solve_s": t2 - t1,
            "t_total_s": t2 - t0, "freqs_Hz": modes.freqs_Hz.tolist(),
            "shapes": (model.probe @ modes.phi).tolist(),
            "backend": available_backend(args.get("backend") or cfg["solver"]["backend"]),
            "peak_rss_MB": _peak_rss_MB()}


def _material_groups(cfg, rmesh, rig):
    from jointid.fe import fem
    from jointid.geometry.rig import PART_IDS

    inv = {v: k for k, v in PART_IDS.items()}
    lam = np.empty(len(rmesh.part))
    mu = np.empty(len(rmesh.part))
    rho = np.empty(len(rmesh.part))
    for pid in np.unique(rmesh.part):
        m = cfg["materials"][rig.materials[inv[pid]]]
        sel = rmesh.part == pid
        lam[sel], mu[sel] = fem.lame(m["youngs_modulus_Pa"], m["poisson_ratio"])
        rho[sel] = m["density_kg_per_m3"]
    return lam, mu, rho


def task_idiomatic(args: dict) -> dict:
    """The same model solved the idiomatic scikit-fem way.

    Solids: ``skfem.models.elasticity.linear_elasticity`` and a ``rho * dot(u, v)`` mass form on an
    ``ElementVector`` basis with scikit-fem's default quadrature, one basis per material; eigenpairs
    with ``solve(*condense(K, M, D=fixed), solver=solver_eigen_scipy_sym(k=n_modes))`` (defaults
    otherwise: sigma = 10, ARPACK, SuperLU).  The joint layers, added masses and supports are the
    jointid ones (identical in both paths): the idiomatic time is ``build_model`` minus jointid's own
    solid assembly plus the idiomatic solid assembly plus the idiomatic eigen-solve.
    """
    from skfem import Basis, BilinearForm, ElementVector, condense, solve, solver_eigen_scipy_sym
    from skfem.helpers import dot
    from skfem.models.elasticity import linear_elasticity

    from jointid.fe import fem
    from jointid.config.typed import MeshOptions
    from jointid.geometry.mesh import mesh_from_config
    from jointid.fe.model import base_coefficients, build_model
    from jointid.geometry.rig import build_rig

    cfg = _cfg(args)
    n = int(args.get("n_modes", 12))
    t0 = time.perf_counter()
    model = build_model(ModelSpec.from_config(cfg))
    t_build = time.perf_counter() - t0
    rig = build_rig(cfg["rig"])
    rmesh = mesh_from_config(rig, MeshOptions.from_section(cfg["mesh"]))
    elem_cls, intorder = fem.ELEMENTS[cfg["mesh"]["element"]]
    lam, mu, rho = _material_groups(cfg, rmesh, rig)
    t0 = time.perf_counter()  # jointid's solid assembly alone (it is part of t_build)
    basis = Basis(rmesh.mesh, elem_cls(), intorder=intorder)
    K0j, M0j = fem.assemble_elasticity(basis, lam, mu, rho)
    t_solid_j = time.perf_counter() - t0

    t0 = time.perf_counter()  # idiomatic solid assembly
    elem = ElementVector(elem_cls())
    groups = {}
    for i, key in enumerate(zip(lam, mu, rho)):
        groups.setdefault(key, []).append(i)
    K0 = M0 = None
    n_qp = None
    for (la, m_, r), idx in groups.items():
        ib = Basis(rmesh.mesh, elem) if len(groups) == 1 else Basis(rmesh.mesh, elem, elements=np.array(idx))
        n_qp = ib.X.shape[1]

        @BilinearForm
        def mass(u, v, w, r=r):
            return r * dot(u, v)

        Kg = linear_elasticity(la, m_).assemble(ib)
        Mg = mass.assemble(ib)
        K0 = Kg if K0 is None else K0 + Kg
        M0 = Mg if M0 is None else M0 + Mg
    t_solid_i = time.perf_counter() - t0
    dK = abs(K0 - K0j).max() / abs(K0j).max()
    dM = abs(M0 - M0j).max() / abs(M0j).max()

    kc, mc = base_coefficients(ModelSpec.from_config(cfg), model, None)
    K = K0 + sum(c * model.stiffness[k] for k, c in kc.items() if c)
    M = M0 + sum(c * model.mass[k] for k, c in mc.items() if c)
    t0 = time.perf_counter()
    lam_, _ = solve(*condense(K.tocsr(), M.tocsr(), D=model.fixed, expand=False),
                    solver=solver_eigen_scipy_sym(k=n))
    t_eig_i = time.perf_counter() - t0
    freqs = np.sqrt(np.clip(np.sort(lam_), 0, None)) / (2 * np.pi)
    return {"n_dofs": model.n_dofs, "n_qp_per_element": n_qp, "t_build_jointid_s": t_build,
            "t_solid_jointid_s": t_solid_j, "t_solid_idiomatic_s": t_solid_i, "t_eig_idiomatic_s": t_eig_i,
            "t_total_idiomatic_s": t_build - t_solid_j + t_solid_i + t_eig_i,
            "K0_max_rel_diff": float(dK), "M0_max_rel_diff": float(dM), "freqs_Hz": freqs.tolist(),
            "peak_rss_MB": _peak_rss_MB()}


def task_rom(args: dict) -> dict:
    """Build a ROM, then compare it with full solves at random interior points (speed and error)."""
    from jointid.identification.doe import to_physical
    from jointid.correlate.mac import mac
    from jointid.fe.model import base_coefficients, build_model
    from jointid.identification.rom import frequency_error
    from jointid.identification.rom_build import RomOptions, build_rom

    cfg = _cfg(args)
    n = int(args.get("n_modes", 12))
    seed = int(args.get("seed", 0))
    model = build_model(ModelSpec.from_config(cfg))
    t0 = time.perf_counter()
    rom = build_rom(model, ModelSpec.from_config(cfg), "corners", RomOptions(n, seed=seed, keep_basis=False))
    t_build = time.perf_counter() - t0
    names = list(cfg["joints"]["parameters"])
    lo = [cfg["joints"]["parameters"][k]["lower"] for k in names]
    hi = [cfg["joints"]["parameters"][k]["upper"] for k in names]
    rng = np.random.default_rng(seed + 1000)
    min_f = cfg["solver"]["min_freq_Hz"]
    checks = []
    for row in to_physical(rng.uniform(-1, 1, size=(int(args.get("n_check", 3)), len(names))), lo, hi):
        theta = dict(zip(names, row.tolist()))
        kc, mc = base_coefficients(ModelSpec.from_config(cfg), model, theta)
        t0 = time.perf_counter()
        modes = _full_solve(cfg, model, kc, mc, n)
        t_full = time.perf_counter() - t0
        f_rom, sh_rom = rom.solve(kc, mc)
        err = frequency_error(f_rom, modes.freqs_Hz, min_f)
        checks.append({"theta": theta, "t_full_s": t_full, "max_error": float(np.nanmax(err)),
                       "errors": err.tolist(),
                       "min_mac": float(np.diag(mac(sh_rom, model.probe @ modes.phi)).min())})
    # evaluation speed: many random interior points, including the coefficient dict handling
    X = to_physical(rng.uniform(-1, 1, size=(int(args.get("n_eval", 2000)), len(names))), lo, hi)
    coeffs = [rom.coefficients(dict(zip(names, r.tolist()))) for r in X]
    rom.solve(*coeffs[0])
    t0 = time.perf_counter()
    for kc, mc in coeffs:
        rom.solve(kc, mc, check=False)
    t_eval = (time.perf_counter() - t0) / len(coeffs)
    t0 = time.perf_counter()
    for kc, mc in coeffs:
        rom.frequencies(kc, mc, check=False)
    t_freq = (time.perf_counter() - t0) / len(coeffs)
    return {"n_dofs": model.n_dofs, "rom_size": rom.size, "t_rom_build_s": t_build, "t_rom_eval_s": t_eval, "t_rom_freq_s": t_freq,
            "t_full_mean_s": float(np.mean([c["t_full_s"] for c in checks])), "checks": checks,
            "max_error": max(c["max_error"] for c in checks), "report": rom.report,
            "peak_rss_MB": _peak_rss_MB()}


def task_eigen(args: dict) -> dict:
    """One factorisation at the default joint parameters, then the eigen-solve alone by block Lanczos
    and by ARPACK for each ``n_modes_list`` (best of ``repeat``): times and agreement."""
    import jointid.fe.modal as fm
    from jointid.fe.model import base_coefficients, build_model

    cfg = _cfg(args)
    s = cfg["solver"]
    model = build_model(ModelSpec.from_config(cfg))
    kc, mc = base_coefficients(ModelSpec.from_config(cfg), model, None)
    free = fm.free_dofs(model.n_dofs, model.fixed)
    Kf, Mf = fm.restrict(model.K(kc), free), fm.restrict(model.M(mc), free)
    sigma = fm.shift_sigma(s["shift_Hz"])
    t0 = time.perf_counter()
    fac = fm.factorize_shifted(Kf, Mf, sigma, s["backend"], getattr(model, "ordering", None))
    out = {"n_free": int(Kf.shape[0]), "t_factor_s": time.perf_counter() - t0, "cases": []}
    min_dofs = fm.MIN_DOFS
    for n in args.get("n_modes_list", [12, 20]):
        times, res = {}, {}
        for method, threshold in (("block", 0), ("arpack", 10**12)):
            fm.MIN_DOFS = threshold
            best = np.inf
            for _ in range(int(args.get("repeat", 2))):
                t = time.perf_counter()
                res[method] = fm.shift_invert_lanczos(Kf, Mf, fac, n, sigma)
                best = min(best, time.perf_counter() - t)
            times[method] = best
        fm.MIN_DOFS = min_dofs
        (vb, fb), (va, fa) = res["block"], res["arpack"]
        out["cases"].append({"n_modes": n, "t_block_s": times["block"], "t_arpack_s": times["arpack"],
                             "max_rel_freq_diff": float(np.max(np.abs(fb / fa - 1))),
                             "max_shape_diff": float(np.max(np.abs(vb - va)) / np.max(np.abs(va)))})
    out["peak_rss_MB"] = _peak_rss_MB()
    return out


TASKS = {"solve": task_solve, "idiomatic": task_idiomatic, "rom": task_rom, "eigen": task_eigen}


def main(argv: list[str]) -> int:
    task, args = argv[0], json.loads(argv[1]) if len(argv) > 1 else {}
    out = TASKS[task](args)
    print(json.dumps(out, default=float), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
