"""The hammer-test example: FRFs -> EMA -> a dataset with measured per-mode uncertainties -> the model.

Run from the repository root:  python examples/hammer_test/run.py

1. make_frfs.py makes the measured FRFs from the coarse FE model with known joints (truth.yaml).
2. The EMA (jointid.ema.run.run_ema) extracts the modes of both states: LSCF over orders, the stable
   poles, each refined with its covariance, LSFD shapes, a bootstrap over response rows.
3. The dataset is checked against the model's measuring points (what `jointid data check --points` does).
4. The model at the true joints is compared with the extracted modes: error over the EMA's own sigma.
5. The joint stiffness is identified from the power_off modes (Study.identify, the FE polish), from the
   geometric mean of the bounds, and set beside the truth.
6. The joint damping of power_off (jointid.identification.joint_damping, the hysteretic law
   zeta_r = zeta0 + sum_j eta_j e_rj / 2): the EMA's damping ratios of the modes paired by MAC with the
   identified model, weighted by the EMA's own damping uncertainties, against each joint direction's
   share of the paired model mode's strain energy; eta per direction and zeta0 with 95 % intervals,
   beside the truth (or what the fit says it cannot identify).
7. The diagnosis of both states on the EMA's own uncertainties names the effect hidden in power_on (the
   motor's attraction, em_preload) with its interval; no noise level is typed in anywhere.  The same
   data with one noise stated by hand at half the EMA's give a misfit (c_hat) the noise cannot explain.
Everything lands in examples/hammer_test/work/ (git-ignored).
"""

import sys
import time
from pathlib import Path

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))

from make_frfs import main as make_frfs  # noqa: E402

from jointid import Study  # noqa: E402
from jointid.config.typed import ModelSpec  # noqa: E402
from jointid.data.dataset import validate_dataset  # noqa: E402
from jointid.ema.options import EmaOptions  # noqa: E402
from jointid.ema.run import run_ema  # noqa: E402
from jointid.identification.direction_shares import model_direction_shares  # noqa: E402
from jointid.identification.joint_damping import direction_label, fit_joint_damping  # noqa: E402

t0 = time.perf_counter()
work = HERE / "work"
make_frfs(work / "frfs")
print(f"FRFs made in {time.perf_counter() - t0:.1f} s")

t1 = time.perf_counter()
options = EmaOptions.from_section(n_bootstrap=20)
dataset, results = run_ema(work / "frfs", work / "dataset", report=work / "ema", options=options,
                           log=lambda m: print(m, flush=True))
print(f"EMA in {time.perf_counter() - t1:.1f} s")

study = Study.from_config([ROOT / "config.yaml", ROOT / "tests" / "coarse_config.yaml"])
problems = validate_dataset(work / "dataset", measuring_points=study.points(), expected_states=["power_off", "power_on"])
print("data check against the model's measuring points:", "valid" if not problems else problems)
ds = study.dataset(work / "dataset")

truth = yaml.safe_load((HERE / "truth.yaml").read_text())
theta = {k: float(v) for k, v in truth["joints"].items()}
cmp = study.compare(ds, theta=theta, state="power_off")
cmp = cmp[cmp.status == "paired"].copy()
sigma_pct = 100 * ds.frequency_sigma_rel("power_off")[cmp["mode"].to_numpy() - 1]
cmp["ema_sigma_pct"] = sigma_pct
cmp["error_over_sigma"] = cmp["error_pct"] / sigma_pct
print("power_off, the model at the true joints against the EMA's modes:")
print(cmp[["mode", "freq_meas_Hz", "freq_model_Hz", "error_pct", "ema_sigma_pct", "error_over_sigma", "mac"]]
      .round(4).to_string(index=False))

t2 = time.perf_counter()
fit = study.identify(ds, "power_off", max_iter=6)
print(f"identify power_off in {time.perf_counter() - t2:.1f} s: {fit.iterations} iterations, max |error| "
      f"{fit.max_abs_error_pct:.3f} %")
table = fit.table()
print(table.to_string(index=False, float_format="%.4g"))
for name, value in theta.items():
    est = fit.theta[name]
    print(f"{name}: identified {est:.4g}, truth {value:.4g} N/m^3 (ratio {est / value:.3f})")


def joint_damping(state: str) -> dict:
    """The hysteretic joint damping of ``state`` at its identified joints, beside the truth."""
    names = list(fit.theta)
    modal = study.modes(state=state)  # starts from what identify found for the state
    pairs = study.compare(ds, state=state)
    pairs = pairs[pairs.status == "paired"]
    meas, model = pairs["mode"].to_numpy() - 1, pairs["model_mode"].to_numpy() - 1
    shares = model_direction_shares(modal.energy, ModelSpec.from_config(study.config), names)[model]
    res = fit_joint_damping(ds.damping(state)[meas], shares, modal.freqs_Hz[model], names,
                            sigma_rel=ds.mode_uncertainty_pct(state, "damping")[meas] / 100,
                            reference=f"hammer test {state} joint damping")
    rec = res.record()
    eta = {f"eta_{direction_label(n)}": float(truth["joint_loss_factors"].get(n, 0.0)) for n in names}
    out = {"n_modes": rec["n_modes"], "law": rec["law"], "c_hat": rec["c_hat"], "noise_source": rec["noise_source"],
           "energy_shares": {direction_label(n): shares[:, j].round(4).tolist() for j, n in enumerate(names)}}
    for key, t in {"zeta0": float(truth["zeta0"]), **eta}.items():
        out[key] = {"value": rec[key], "low": rec[f"{key}_ci95_low"], "high": rec[f"{key}_ci95_high"], "truth": t,
                    "r2": rec["hysteretic"]["collinearity_r2"][key], "note": rec["hysteretic"].get(f"{key}_note")}
        print(f"{state} {key}: " + (out[key]["note"] if rec[key] is None else
              f"{rec[key]:.4g} [{out[key]['low']:.4g}, {out[key]['high']:.4g}]") + f", truth {t:g}")
    print(f"{state} joint damping over {rec['n_modes']} paired modes: {rec['law_note']}; c_hat {rec['c_hat']:.2f}")
    return out


t4 = time.perf_counter()
damping = joint_damping("power_off")
print(f"joint damping in {time.perf_counter() - t4:.1f} s")


def diagnosis_line(label: str, res) -> dict:
    """The answer of one diagnosis: the verdict's first sentence, em_preload's row and the model error."""
    row = res.ranking.set_index("effect").loc["em_preload"]
    me = res.raw.model_error
    print(f"{label}: {res.verdict.split('. ')[0]}.")
    print(f"{label}: em_preload beta {row.estimate:.3g} [{row.ci95_low:.3g}, {row.ci95_high:.3g}] "
          f"(truth {truth['effects']['em_preload']['beta']}), c_hat {me.c_hat:.2f}")
    return {"beta": float(row.estimate), "low": float(row.ci95_low), "high": float(row.ci95_high),
            "c_hat": float(me.c_hat), "explained_by": res.explained_by}


t3 = time.perf_counter()
measured = diagnosis_line("diagnosis, the EMA's own uncertainties", study.diagnose(ds, candidates=["em_preload"]))
half = work / "dataset_half_noise"  # the same modes, one noise stated by hand at half the EMA's
import pandas as pd  # noqa: E402

half.mkdir(exist_ok=True)
modes = pd.read_csv(work / "dataset" / "modes.csv")
rms = float(np.sqrt(np.mean(modes["freq_uncertainty_pct"] ** 2)))
modes.drop(columns=[c for c in modes if c.endswith("_uncertainty_pct")]).to_csv(half / "modes.csv", index=False)
cond = yaml.safe_load((work / "dataset" / "conditions.yaml").read_text())
cond["frequency_uncertainty_pct"] = rms / 2
(half / "conditions.yaml").write_text(yaml.safe_dump(cond, sort_keys=False))
for name in ("shapes.csv",):
    if (work / "dataset" / name).exists():
        (half / name).write_text((work / "dataset" / name).read_text())
stated = diagnosis_line(f"diagnosis, one noise stated at {rms / 2:.3g} % (half the EMA's RMS)",
                        study.diagnose(half, candidates=["em_preload"]))
print(f"diagnoses in {time.perf_counter() - t3:.1f} s")

summary = {
    "seconds": time.perf_counter() - t0, "data_check": problems, "modes": {s: len(ds.freqs(s)) for s in ds.states},
    "error_over_sigma": cmp["error_over_sigma"].round(3).tolist(),
    "identified": {n: {"value": float(r.value_N_per_m3), "low": float(r.ci95_low_N_per_m3),
                       "high": float(r.ci95_high_N_per_m3), "truth": theta.get(n)} for n, r in
                   zip(table.parameter, table.itertuples())},
    "joint_damping_power_off": damping, "diagnosis_measured_noise": measured, "diagnosis_half_stated_noise": stated,
}
(work / "summary.yaml").write_text(yaml.safe_dump(summary, sort_keys=False))
print(f"total {summary['seconds']:.1f} s")
