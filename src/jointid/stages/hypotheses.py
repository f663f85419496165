"""Workflow stages of the reconstruction hypotheses (rules ``hypothesis`` and ``hypotheses``).

* :func:`run_hypothesis` fits one hypothesis (``hypotheses.<name>`` in config.yaml) to the run's
  measured states under the linked two-state law and writes ``results/hypotheses/<name>/fit.json``;
* :func:`run_ranking` ranks the fitted hypotheses by AICc: ``results/hypotheses/ranking.csv``,
  ``spread.csv`` (joint parameters over the hypotheses within delta AICc < 4) and ``ranking.md``.

See :mod:`jointid.diagnosis.hypotheses` and docs/reconstruction.md, "Hypotheses".
"""

from __future__ import annotations

import os
import time

import numpy as np
import pandas as pd

from jointid import io
from jointid.config import load_config
from jointid.config.datasets import dataset_folder
from jointid.data.dataset import read_dataset
from jointid.diagnosis.fitting import print_log
from jointid.diagnosis.hypotheses import fit_hypothesis, hypothesis_config, needs_own_model, rank_hypotheses
from jointid.diagnosis.terms import build_system
from jointid.diagnosis.variants import dataset_states
from jointid.errors import ConfigError
from jointid.fe.model import build_model, load_model
from jointid.threads import limit_threads

CONFIG = ("materials", "rig", "mesh", "joints", "states", "measurements", "datasets", "solver", "identify",
          "harmonic", "effects", "linked", "hypotheses")
"""Config sections a hypothesis reads (its own entry of ``hypotheses`` only, see the rule)."""
ADMISSIBLE_DELTA_AICC = 4.0


def measured_states(cfg: dict, system) -> list:
    """:class:`~jointid.diagnosis.variants.StateData` of every configured state, read from its dataset
    folder (states sharing a folder are read together)."""
    folders: dict[str, list[str]] = {}
    for state in cfg["states"]:
        folders.setdefault(dataset_folder(cfg, state), []).append(state)
    data = []
    for folder, states in folders.items():
        ds = read_dataset(folder, measuring_points=system.meta["points"])
        data += dataset_states(ds, system, cfg, states)
    return data


def run_hypothesis(cfg: dict, name: str, matrices: str | None, out_json: str, *, log=print_log) -> dict:
    """Fit hypothesis ``name`` and write its record to ``out_json``.

    The hypothesis's configuration is validated like config.yaml (its problems name the
    hypothesis).  It reuses the run's model (``matrices``) unless it overrides ``materials``,
    ``rig`` or ``mesh``; then it builds its own.
    """
    limit_threads(1)
    t0 = time.time()
    hyp = dict((cfg.get("hypotheses") or {}).get(name) or {})
    if not hyp and name not in (cfg.get("hypotheses") or {}):
        raise ConfigError(f"config.yaml: hypotheses.{name}: no such hypothesis — the configured ones are "
                          f"{', '.join(cfg.get('hypotheses') or {}) or 'none'}")
    raw = hypothesis_config(cfg, name, hyp)
    cfg_h = load_config(raw, source=f"config.yaml (hypothesis {name})")
    own = needs_own_model(hyp)
    log(f"hypothesis {name}: {'building its own model' if own else 'the run model'}")
    model = build_model(cfg_h) if own else load_model(matrices)
    system = build_system(model, cfg_h)
    data = measured_states(cfg_h, system)
    rec = fit_hypothesis(system, cfg_h, data, log=log)
    rec.update({"hypothesis": name, "description": str(hyp.get("description", "")), "own_model": own,
                "n_dofs": system.n_dofs, "time_s": time.time() - t0})
    io.write_json(out_json, rec)
    log(f"hypothesis {name}: chi2 {rec['chi2']:.2f}, AICc {rec['aicc']:.2f} ({rec['time_s']:.0f} s)")
    return rec


def run_ranking(fit_jsons: list[str], out_csv: str, spread_csv: str, out_md: str) -> pd.DataFrame:
    """Rank the fitted hypotheses by AICc and write the ranking, the parameter spread and a summary."""
    records = {}
    for path in fit_jsons:
        rec = io.read_json(path)
        records[rec["hypothesis"]] = rec
    rows, spread = rank_hypotheses(records, delta=ADMISSIBLE_DELTA_AICC)
    ranking = pd.DataFrame(rows)
    io.write_csv(ranking, out_csv)
    io.write_csv(pd.DataFrame(spread), spread_csv)
    io.write_text(out_md, ranking_markdown(ranking, pd.DataFrame(spread), records))
    return ranking


def ranking_markdown(ranking: pd.DataFrame, spread: pd.DataFrame, records: dict) -> str:
    """The ranking as a short Markdown page (report and README)."""
    lines = ["# Reconstruction hypotheses ranked by AICc", "",
             "Each hypothesis is fitted to both states at once under the linked contact law "
             "(docs/reconstruction.md, \"Hypotheses\"); unpaired, clearly visible model modes count as "
             "misfits in chi-square and in the errors.", "",
             "| rank | hypothesis | ΔAICc | weight | χ² | max error per state (%) | unpaired visible | β | P (N) |",
             "|---:|---|---:|---:|---:|---|---|---:|---:|"]
    for _, r in ranking.iterrows():
        rec = records[r["hypothesis"]]
        errs = " / ".join(f"{s['max_abs_error_pct']:.2f}" for s in rec["states"])
        mis = " / ".join(str(s["n_unpaired_visible"]) for s in rec["states"])
        beta = r.get("em_preload.beta", np.nan)
        pre = "—" if rec.get("preload_N") is None else f"{rec['preload_N']:g}"
        lines.append(f"| {r['rank']} | {r['hypothesis']} | {r['delta_aicc']:.1f} | {r['akaike_weight']:.2f} | "
                     f"{r['chi2']:.1f} | {errs} | {mis} | {beta:.3f} | {pre} |")
    lines += ["", f"Joint parameters over the hypotheses within ΔAICc < {ADMISSIBLE_DELTA_AICC:g} (the "
              "reconstruction uncertainty; intervals scaled by max(1, √(χ²/dof))):", "",
              "| parameter | hypotheses | value range | combined 95 % interval |", "|---|---:|---|---|"]
    for _, s in spread.iterrows():
        lines.append(f"| {s['parameter']} | {s['n_hypotheses']} | {s['value_min']:.4g} … {s['value_max']:.4g} | "
                     f"{s['combined_ci95_low']:.4g} … {s['combined_ci95_high']:.4g} |")
    return "\n".join(lines) + "\n"


def hypothesis_names(cfg: dict) -> list[str]:
    """The configured hypotheses, in config order."""
    return list((cfg.get("hypotheses") or {}))


def fit_path(results: str, name: str) -> str:
    """Where hypothesis ``name``'s record goes."""
    return os.path.join(results, "hypotheses", name, "fit.json")
