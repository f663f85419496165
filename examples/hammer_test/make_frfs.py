"""Make the example's measured FRFs: the coarse FE model with known joints, hit with a hammer.

Run from the repository root:  python examples/hammer_test/make_frfs.py [OUT_FOLDER]

The truth (truth.yaml): joint stiffness, a joint loss factor, a structural damping ratio, two states
(the motor's attraction preloads the joints in power_on: library effect em_preload).
Per state the FE modes give receptances (modal superposition, the hysteretic law's damping
ratio per mode) at the first 18 measuring points in x, y and z, for two hammer references (T05:y and
T05:x), on 2 Hz lines from 250 to 2700 Hz, with complex noise of 2 % of |H| (seed 52).  Written: OUT/frf.csv (a reference
column per line) and OUT/conditions.yaml (the states' motor force).  Nothing else of the truth is written.
"""

import sys
from pathlib import Path

import numpy as np
import yaml

from jointid.yamlio import read_merged
from jointid.config.typed import ModelSpec
from jointid.diagnosis.effects import apply_effects, enabled_effects
from jointid.synthetic.generate import hysteretic_ratios, load_truth, truth_config
from jointid.diagnosis.terms import StateInfo, baseline_coefficients, build_system
from jointid.ema.synthetic import frf_table, modal_frfs
from jointid.fe.model import build_model
from jointid.fe.modal import solve_model

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
GRID_HZ = np.arange(250.0, 2700.0, 2.0)
REFERENCES = ("T05:y", "T05:x")
NOISE_PCT, SEED, N_POINTS = 2.0, 52, 18


def main(out: Path) -> None:
    truth = load_truth(HERE / "truth.yaml")
    cfg = truth_config(truth, read_merged([ROOT / "config.yaml", ROOT / "tests" / "coarse_config.yaml"]))
    spec = ModelSpec.from_config(cfg)
    system = build_system(build_model(spec), spec)
    points = list(dict.fromkeys(lab.split(":")[0] for lab in system.labels))[:N_POINTS]
    dofs = [(p, d) for p in points for d in "xyz"]
    rows = [system.labels.index(f"{p}:{d}") for p, d in dofs]
    refs = [dofs.index(tuple(r.split(":"))) for r in REFERENCES]
    tables, states = [], {}
    for k, (state, scfg) in enumerate(truth["states"].items()):
        kc, mc = baseline_coefficients(system, spec, {n: float(v) for n, v in truth["joints"].items()})
        effects = [(e.effect, e.values, e.options) for e in enabled_effects(truth.get("effects") or {})]
        kc, mc = apply_effects(system, kc, mc, StateInfo(state, float(scfg["em_force_N"])), effects)
        modes = solve_model(system, kc, mc, 20, shift_Hz=cfg["solver"]["shift_Hz"], backend=cfg["solver"]["backend"])
        zeta, _ = hysteretic_ratios(system, spec, kc, modes, truth)
        keep = (modes.freqs_Hz > 1.0) & (modes.freqs_Hz < 5000.0)
        phi = np.asarray(system.probe @ modes.phi)[rows][:, keep]
        fs = modal_frfs(GRID_HZ, modes.freqs_Hz[keep], zeta[keep], phi, dofs, refs, noise_pct=NOISE_PCT,
                        seed=SEED + k, state=state)
        tables.append(frf_table(fs))
        states[state] = {"em_force_N": float(scfg["em_force_N"])}
        band = (modes.freqs_Hz > GRID_HZ[0]) & (modes.freqs_Hz < GRID_HZ[-1])
        print(f"{state}: true modes in the band " + ", ".join(
            f"{f:.1f} Hz (zeta {z:.4f})" for f, z in zip(modes.freqs_Hz[band], zeta[band])))
    out.mkdir(parents=True, exist_ok=True)
    import pandas as pd

    pd.concat(tables).to_csv(out / "frf.csv", index=False, float_format="%.8g")
    from jointid.config.hashing import mesh_digest

    (out / "conditions.yaml").write_text(yaml.safe_dump(
        {"source": f"hammer test example (synthetic FE FRFs, {NOISE_PCT:g} % noise, seed {SEED})", "states": states,
         "computed_on_mesh": mesh_digest(cfg)},  # FRFs of the analysis's own mesh: no discretisation error
        sort_keys=False))
    print(f"wrote {out / 'frf.csv'} ({sum(len(t) for t in tables)} lines) and {out / 'conditions.yaml'}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "work" / "frfs")
