"""(j) Coverage study (issue 50, item 4): how often the diagnosis names the hidden effect, claims none
when there is none, and how often its nominal 95 % intervals hold the truth, when the model is a little
wrong (the truth solved on a finer mesh) and the noise is stated right, 2x too small or 2x too large.

A benchmark, not a CI test.  Each case is a synthetic dataset (:mod:`jointid.synthetic.generate`) drawn
from the design below, diagnosed by :func:`jointid.diagnosis.loop.diagnose` on the rig of the
synthetic diagnosis tests (``benchmarks.common.diagnosis_rig``: normal and lateral joint stiffness
identified, feed fixed), and scored from the public results only (``Diagnosis.ranking``,
``.explained_by``, ``.parameters``, ``.model_error`` and ``verdict_record(...)["supported"]``).

Design (``design()``; seeds and sizes deterministic, case ``i`` draws with seed ``SEED0 + i``)
-----------------------------------------------------------------------------------------------
=============  =====  ========================================================================
kind           cases  truth
=============  =====  ========================================================================
single         24     each library effect alone, 4 cases each, its size drawn uniformly from
                      ``SIZES`` below
pair           8      two effects at once (``PAIRS``), each size drawn from ``SIZES``
none           16     no effect
=============  =====  ========================================================================

Every case: two states (power_off 0 N, power_on 1000 N); true joints drawn log-uniformly,
k_normal 5e11..1.2e12, k_lateral 4e11..9e11 N/m^3 (the analysis bounds are 2e11..4e12); true noise
0.2 % on the frequencies and 2 % (of each mode's RMS) on the shapes; the band 100..3500 Hz with
``max_modes`` 4..8 per state; the truth solved on a finer mesh than the analysis (``TRUTH_MESH``:
on the coarse rig ``mesh.refine: 2``, every grid cell halved along all three axes, so the cells
through the thickness, in the joint zone and at the re-entrant edges are all halved once; on the
default rig the thickness and joint-zone cells are halved and the re-entrant edges get one level of
local refinement, a uniform refinement there being ~470k DOFs).  Strata, cycled over the cases of
each kind so every kind meets every cell: the noise statement (``right``: stated = true; ``small``:
stated = true / 2, frequencies and shapes; ``large``: stated = 2 x true) and shapes measured at every
point (x, y, z) or frequencies only.

Effect sizes (``SIZES``, physical units, inside each parameter's bounds in ``diagnosis/effects.py``):
em_preload beta 0.1..0.3; added_mass_table 2..4 kg; added_mass_edge 1..2 kg; rail_fixing
k_railfix 2e12..5e12 N/m^3; base_support k_foundation 1.5e11..3e11 N/m^3; feed_stiffness
k_feed_extra 3e9..8e9 N/m^3.

Scores (one row per case in ``benchmarks/out/coverage_cases.csv``)
-------------------------------------------------------------------
* **named**: what the diagnosis names: the effects of ``explained_by`` (``a``, ``a or b``, ``a+b``);
  when that is ``none needed`` or ``unexplained``, the first entry of the verdict record's
  ``supported`` list (a single or a pair, with the candidates tied to it in ``indistinguishable_from``)
  when there is one; else nothing.  An effect case is **found** when the named set holds every true
  effect (a named tie that holds the truth counts; a pair case needs both) and, when the answer is a
  combination ``a+b``, it is exactly the true effects (a single-effect case answered by its effect plus
  a spurious second one is wrong; ``found_loose`` counts it).
* **claimed** (no-effect cases): the verdict record's ``supported`` list is not empty (some refit or
  pair is strongly or moderately supported against the current model) or ``explained_by`` names an
  effect.
* **effect-parameter coverage**: the true value inside [ci95_low, ci95_high] of the true effect's row
  of the ranking (its single refit); in a pair case each true parameter inside its interval in the
  pair's fit (``Diagnosis.parameters``, variant ``+a+b``), else in its single row.  No interval (the
  effect not refitted) counts as a miss.
* **joint coverage**: the true k_normal and k_lateral inside their 95 % intervals in
  ``Diagnosis.parameters`` for the *reported model* (the fit of what is named; the current model when
  nothing is named).  The diagnosis reports these intervals itself (``parameter_table``: the fit's
  scaled covariance, as the ranking's).  Also recorded: the same in the fit of the *true* model
  (``+truth``, ``+a+b``, or the current model for no-effect cases), when it was fitted.
  Coverage is counted per interval (n/N intervals: one per effect parameter, two joints per case).

Targets (issue 50, never bent here): effect cases found >= 90 %; no-effect cases with no effect
claimed >= 90 %; the intervals hold the truth >= 90 % for effect parameters and joints alike; no cell
of the splits by noise statement and by shapes below 80 %.

``python -m benchmarks j [--quick] [--cases N] [--rig coarse|default] [--set KEY=VALUE ...] [--shard K/N]``
(``--shard``: every N-th case from the K-th, so that N processes share one run; then ``--doc-only``), or
``python -m benchmarks.bench_j_coverage`` with the same options (plus ``--no-doc``).  ``--set`` passes
``diagnosis`` options (e.g. ``--set shape_residuals=true``); each option set is a *run* of its own in
the CSV and in ``docs/validation.md`` (a rerun replaces its own rows only).  ``--quick``: 6 cases
(``QUICK_CASES``: one of each kind and stratum, coarse rig), no doc.  The datasets are kept in
``benchmarks/out/coverage_data/<rig>/<case>`` (keyed by the truth's hash; synthesised again when
``jointid/synthetic/generate.py`` changes): a second run with other options does not synthesise again.  Each case
starts from a fresh reduced solver, as a user's run does: a case's answer does not depend on the cases
run before it (a reused, grown subspace once changed which candidates a case refitted).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from .common import OUT, ROOT, Result, head_commit, machine

SEED0 = 5000
STATES = {"power_off": {"em_force_N": 0.0}, "power_on": {"em_force_N": 1000.0}}
BAND_HZ = [100.0, 3500.0]
FREQ_PCT, SHAPE_PCT = 0.2, 2.0
NOISE_FACTORS = {"right": 1.0, "small": 0.5, "large": 2.0}  # stated / true
JOINT_RANGES = {"k_normal_N_per_m3": (5.0e11, 1.2e12), "k_lateral_N_per_m3": (4.0e11, 9.0e11)}
SIZES = {  # effect -> (parameter, low, high), drawn uniformly
    "em_preload": ("beta", 0.1, 0.3),
    "added_mass_table": ("mass_kg", 2.0, 4.0),
    "added_mass_edge": ("mass_kg", 1.0, 2.0),
    "rail_fixing": ("k_railfix_N_per_m3", 2.0e12, 5.0e12),
    "base_support": ("k_foundation_N_per_m3", 1.5e11, 3.0e11),
    "feed_stiffness": ("k_feed_extra_N_per_m3", 3.0e9, 8.0e9),
}
EFFECT_NAMES = list(SIZES)
PAIRS = [("added_mass_table", "em_preload"), ("base_support", "added_mass_edge"), ("rail_fixing", "em_preload"),
         ("feed_stiffness", "added_mass_table"), ("base_support", "em_preload"), ("added_mass_edge", "rail_fixing"),
         ("feed_stiffness", "base_support"), ("added_mass_table", "rail_fixing")]
N_SINGLE_EACH, N_NONE = 4, 16
TRUTH_MESH = {"coarse": {"mesh": {"refine": 2}},
              "default": {"mesh": {"height_cell_fraction": 0.25, "joint_cell_fraction": 0.25,
                                   "edge_refine_levels": 1}}}
QUICK_CASES = ("S00", "S05", "P00", "P03", "N00", "N04")
DEFAULT_RIG_CASES = 8  # --rig default without --cases: the first cases of a spread over the design
TARGET, CELL_TARGET = 0.90, 0.80
CSV = OUT / "coverage_cases.csv"
DATA = OUT / "coverage_data"
DOC = ROOT / "docs" / "validation.md"
DOC_CSV = ROOT / "docs" / "validation_cases.csv"
SUPPORTED = ("strongly", "moderately")


# ------------------------------------------------------------------ design
def design() -> list[dict]:
    """The cases of the study (deterministic): id, kind, effects {name: {param: value}}, joints, noise
    statement, shapes, max_modes, seed."""
    cases = []

    def case(cid, kind, effects, noise, shapes, max_modes):
        i = len(cases)
        rng = np.random.default_rng(SEED0 + i)
        joints = {k: float(math.exp(rng.uniform(math.log(lo), math.log(hi)))) for k, (lo, hi) in JOINT_RANGES.items()}
        eff = {}
        for name in effects:
            par, lo, hi = SIZES[name]
            v = float(rng.uniform(lo, hi))
            eff[name] = {par: float(f"{v:.4g}")}
        cases.append({"case": cid, "kind": kind, "effects": eff,
                      "joints": {k: float(f"{v:.4g}") for k, v in joints.items()},
                      "noise": noise, "shapes": shapes, "max_modes": int(max_modes), "seed": SEED0 + i})

    noises = list(NOISE_FACTORS)
    k = 0
    for e, name in enumerate(EFFECT_NAMES):
        for r in range(N_SINGLE_EACH):
            case(f"S{k:02d}", "single", [name], noises[(e + r) % 3], r % 2 == 0, 4 + (e + 2 * r) % 5)
            k += 1
    for j, pair in enumerate(PAIRS):
        case(f"P{j:02d}", "pair", list(pair), noises[j % 3], (j // 3) % 2 == 0, 4 + (2 * j + 1) % 5)
    for j in range(N_NONE):
        case(f"N{j:02d}", "none", [], noises[j % 3], (j // 3) % 2 == 0, 4 + (3 * j) % 5)
    return cases


def truth_of(c: dict, rig: str) -> dict:
    """The synth truth of a case (:mod:`jointid.synthetic.generate`)."""
    f = NOISE_FACTORS[c["noise"]]
    return {"joints": dict(c["joints"]), "states": STATES, "effects": {k: dict(v) for k, v in c["effects"].items()},
            "overrides": TRUTH_MESH[rig],
            "measurement": {"band_Hz": BAND_HZ, "max_modes": c["max_modes"], "shapes": bool(c["shapes"])},
            "noise": {"seed": c["seed"], "frequency_pct": FREQ_PCT, "shape_pct": SHAPE_PCT,
                      "stated_frequency_pct": FREQ_PCT * f, "stated_shape_pct": SHAPE_PCT * f}}


def design_table(cases: list[dict]) -> str:
    """The design as a markdown table (one row per case)."""
    head = ["case", "kind", "truth effects", "k_normal", "k_lateral", "noise stated", "shapes", "modes/state", "seed"]
    rows = []
    for c in cases:
        eff = "; ".join(f"{n} {p}={v:.3g}" for n, d in c["effects"].items() for p, v in d.items()) or "-"
        rows.append([c["case"], c["kind"], eff, f"{c['joints']['k_normal_N_per_m3']:.3g}",
                     f"{c['joints']['k_lateral_N_per_m3']:.3g}", c["noise"], "yes" if c["shapes"] else "no",
                     str(c["max_modes"]), str(c["seed"])])
    return _md(head, rows)


def select(cases: list[dict], quick: bool, n: int | None, rig: str, subset: str = "all") -> list[dict]:
    """The cases a run takes: ``--quick`` the QUICK_CASES; ``--subset shapes|frequencies`` the cases with
    shapes or with frequencies only; ``--cases N`` N of them spread over the design (every kind and
    stratum early); the default rig without ``--cases`` DEFAULT_RIG_CASES.  A subset or a number runs in
    the spread order, so a run stopped early still holds every kind."""
    if quick:
        return [c for c in cases if c["case"] in QUICK_CASES]
    if subset != "all":
        cases = [c for c in cases if bool(c["shapes"]) == (subset == "shapes")]
    if n is None and rig == "default":
        n = DEFAULT_RIG_CASES
    if subset == "all" and (n is None or n >= len(cases)):
        return cases
    # interleave the kinds (single, none, pair, ...), the singles one of each effect in turn, so that
    # a prefix holds every kind, effect and stratum early
    singles = sorted((c for c in cases if c["kind"] == "single"), key=lambda c: (int(c["case"][1:]) % N_SINGLE_EACH,
                                                                                 int(c["case"][1:])))
    by_kind = [singles] + [[c for c in cases if c["kind"] == k] for k in ("none", "pair")]
    order = []
    while any(by_kind):
        for lst in by_kind:
            if lst:
                order.append(lst.pop(0))
    return order[:n]


# ------------------------------------------------------------------ running
class Runner:
    """The rig and the truth model (built once per rig)."""

    def __init__(self, rig: str, log=print):
        from .common import diagnosis_rig

        t0 = time.perf_counter()
        self.rig_name = rig
        self.rig = diagnosis_rig(rig)
        self.rig_s = time.perf_counter() - t0
        self.truth_model = None
        self.log = log
        log(f"[j] {rig} rig: {self.rig['model'].n_dofs} DOFs, built in {self.rig_s:.1f} s")

    def dataset(self, c: dict) -> tuple[Path, float]:
        """The case's dataset folder (synthesised unless kept from an earlier run) and the seconds spent."""
        from jointid.config.typed import ModelSpec
        from jointid.synthetic import generate as synth
        from jointid.fe.model import build_model

        from .common import truth_settings

        truth = truth_of(c, self.rig_name)
        key = hashlib.sha256(json.dumps(truth, sort_keys=True).encode()).hexdigest()[:12]
        folder = DATA / self.rig_name / f"{c['case']}-{key}"
        stamp = folder / "synth_source.sha256"  # the synthesiser's source: a changed one synthesises again
        code = hashlib.sha256(Path(synth.__file__).read_bytes()).hexdigest()
        if (folder / "modes.csv").exists():
            if not stamp.exists():
                stamp.write_text(code + "\n")
            if stamp.read_text().strip() == code:
                return folder, 0.0
            shutil.rmtree(folder)
        t0 = time.perf_counter()
        if self.truth_model is None:
            cfg_t = synth.truth_config(truth, self.rig["cfg"])
            self.truth_model = build_model(ModelSpec.from_config(cfg_t))
            self.log(f"[j] truth model ({json.dumps(TRUTH_MESH[self.rig_name])}): {self.truth_model.n_dofs} DOFs, "
                     f"built in {time.perf_counter() - t0:.1f} s")
        tmp = folder.with_name(folder.name + ".tmp")
        shutil.rmtree(tmp, ignore_errors=True)  # left by an interrupted run
        synth.write_synthetic(truth, truth_settings(truth, self.rig["cfg"]), tmp, model=self.truth_model)
        (tmp / stamp.name).write_text(code + "\n")
        tmp.rename(folder)
        return folder, time.perf_counter() - t0

    def diagnose(self, folder: Path, options: dict):
        from jointid.data.dataset import read_dataset
        from jointid.diagnosis.loop import diagnose
        from jointid.diagnosis.variants import dataset_states
        from jointid.config.typed_diagnosis import DiagnosisSettings

        rig = self.rig
        ds = read_dataset(folder, measuring_points=rig["system"].meta["points"])
        data = dataset_states(ds, rig["system"], DiagnosisSettings.from_config(rig["cfg"]))
        cfg = {**rig["cfg"], "diagnosis": {**(rig["cfg"].get("diagnosis") or {}), **options}}
        return diagnose(rig["system"], DiagnosisSettings.from_config(cfg), data, log=lambda m: None)


# ------------------------------------------------------------------ scoring
def _ties(row) -> list[str]:
    return [n for n in str(row.get("indistinguishable_from") or "").split(";") if n and n != "nan"]


def named_effects(res, supported: list[str]) -> tuple[list[str], str]:
    """What the diagnosis names (see the module doc) and the label of the reported model's fit."""
    short = res.explained_by
    if short not in ("none needed", "unexplained"):
        if "+" in short:
            return short.split("+"), "+" + short
        names = short.split(" or ")
        return names, "+" + names[0]
    if supported:
        first = supported[0]
        if "+" in first:
            return first.split("+"), "+" + first
        rk = res.ranking.set_index("effect")
        ties = _ties(rk.loc[first]) if first in rk.index else []
        return [first] + [t for t in ties if t != first], "+" + first
    return [], "current"


def judge(truth: str, explained_by: str, supported, named) -> dict:
    """``found``, ``found_loose`` (effect cases) and ``claimed`` (no-effect cases) of one case from the
    CSV's own columns (``truth`` ``a`` / ``a+b`` / ``none``; ``supported`` and ``named`` ``;``-separated),
    so a saved CSV can be judged again.  ``found``: the named set holds every true effect and, when the
    answer is a combination, it is exactly the true effects (a pair naming a spurious second effect is
    wrong); ``found_loose``: the named set holds every true effect."""
    split = lambda v: [x for x in (v.split(";") if isinstance(v, str) else []) if x]  # noqa: E731
    sup, answer = split(supported), split(named)
    short = str(explained_by)
    combo = "+" in short or (short in ("none needed", "unexplained") and bool(sup) and "+" in sup[0])
    true = [] if truth == "none" else str(truth).split("+")
    if short.startswith("ERROR"):  # the diagnosis failed: wrong either way
        return {"found": False, "found_loose": False, "claimed": np.nan} if true else \
            {"found": np.nan, "found_loose": np.nan, "claimed": True}
    if not true:
        return {"found": np.nan, "found_loose": np.nan, "claimed": bool(answer) or bool(sup)}
    return {"found": all(t in answer for t in true) and (not combo or set(answer) == set(true)),
            "found_loose": all(t in answer for t in true), "claimed": np.nan}


def rejudge(df: pd.DataFrame) -> pd.DataFrame:
    """:func:`judge` again over the rows of a saved CSV."""
    df = df.copy()
    judged = [judge(r.truth, r.explained_by, r.get("supported"), r.get("named")) for _, r in df.iterrows()]
    for col in ("found", "found_loose", "claimed"):
        df[col] = pd.Series([j[col] for j in judged], index=df.index, dtype=object)
    return df


def _fit_params(res, label: str, names_set=None) -> pd.DataFrame | None:
    """Rows of ``res.parameters`` of the fit ``label`` (``current``: the current model, the last fit
    without candidates; a pair label matched in either order)."""
    p = res.parameters
    if p is None or not len(p):
        return None
    if label == "current":
        label = "baseline" if "baseline" in set(p["variant"]) else p["variant"].iloc[0]
    rows = p[p["variant"] == label]
    if not len(rows) and label.count("+") == 2:
        a, b = label[1:].split("+")
        rows = p[p["variant"] == f"+{b}+{a}"]
    return rows if len(rows) else None


def _inside(v, lo, hi) -> bool:
    return bool(np.isfinite(lo) and lo <= v <= hi) if lo is not None and hi is not None else False


def score(c: dict, res) -> dict:
    """One CSV row: the case, what was named, the intervals and whether they hold the truth."""
    from jointid.reporting.diagnosis_outputs import verdict_record

    rec = verdict_record(res, c["case"], {})
    supported = list(rec["supported"])
    truth = list(c["effects"])
    named, reported = named_effects(res, supported)
    top = res.ranking.iloc[0]
    row = {"case": c["case"], "kind": c["kind"], "truth": "+".join(truth) or "none",
           "noise": c["noise"], "shapes": bool(c["shapes"]), "max_modes": c["max_modes"], "seed": c["seed"],
           "explained_by": res.explained_by, "supported": ";".join(supported), "named": ";".join(named),
           "top": top.effect, "top_support": top.support, "top_ties": ";".join(_ties(top)),
           "top_delta_qaicc": float(top.delta_qaicc) if pd.notna(top.delta_qaicc) else np.nan,
           "reported_model": reported}
    row.update(judge(row["truth"], res.explained_by, row["supported"], row["named"]))
    # effect parameters
    pair_rows = _fit_params(res, "+" + "+".join(truth)) if len(truth) == 2 else None
    rk = res.ranking.set_index("effect")
    for i, name in enumerate(truth, 1):
        par, true_v = next(iter(c["effects"][name].items()))
        est = lo = hi = np.nan
        src = "none"
        if pair_rows is not None:
            r = pair_rows[pair_rows["parameter"] == f"{name}.{par}"]
            if len(r):
                est, lo, hi, src = float(r.value.iloc[0]), float(r.ci95_low.iloc[0]), float(r.ci95_high.iloc[0]), "pair"
        if src == "none" and name in rk.index and pd.notna(rk.loc[name, "estimate"]):
            r = rk.loc[name]
            est, lo, hi, src = float(r.estimate), float(r.ci95_low), float(r.ci95_high), "single"
        row.update({f"eff{i}": name, f"eff{i}_true": true_v, f"eff{i}_est": est, f"eff{i}_lo": lo,
                    f"eff{i}_hi": hi, f"eff{i}_source": src, f"eff{i}_in": _inside(true_v, lo, hi)})
    # joints: the reported model, and the true model's fit
    for tag, label in (("rep", reported), ("true", "+" + "+".join(truth) if truth else "current")):
        rows = _fit_params(res, label)
        for jn, short in (("k_normal_N_per_m3", "kn"), ("k_lateral_N_per_m3", "kl")):
            true_v = c["joints"][jn]
            est = lo = hi = np.nan
            if rows is not None:
                r = rows[rows["parameter"] == jn]
                if len(r):
                    est, lo, hi = float(r.value.iloc[0]), float(r.ci95_low.iloc[0]), float(r.ci95_high.iloc[0])
            row.update({f"{short}_{tag}_true": true_v, f"{short}_{tag}_est": est, f"{short}_{tag}_lo": lo,
                        f"{short}_{tag}_hi": hi, f"{short}_{tag}_in": _inside(true_v, lo, hi),
                        f"{short}_{tag}_fitted": rows is not None})
    ranks = {e: i + 1 for i, e in enumerate(res.ranking["effect"])}
    row["truth_rank"] = ";".join(str(ranks.get(t, "")) for t in truth)
    fits = res.parameters
    if fits is not None and len(fits):
        rep = _fit_params(res, reported)
        row["interval_scale_reported"] = float(rep.interval_scale.iloc[0]) if rep is not None else np.nan
    me = rec["model_error"]
    row.update({"c_hat": me.get("c_hat"), "sigma_model_pct": me.get("sigma_model_pct"),
                "sigma_known_pct": me.get("sigma_known_pct"), "verdict": res.verdict})
    return row


# ------------------------------------------------------------------ tables
def _md(head: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    out += ["| " + " | ".join(str(x) for x in r) + " |" for r in rows]
    return "\n".join(out)


def _rate(k: int, n: int) -> str:
    return f"{k}/{n} ({100 * k / n:.0f} %)" if n else "-"


def metrics(df: pd.DataFrame) -> dict:
    """The study's four figures over the rows ``df``: (hits, count) each."""
    eff = df[df.kind != "none"]
    none = df[df.kind == "none"]
    ins = []
    for i in (1, 2):
        if f"eff{i}_in" in eff:
            m = eff[f"eff{i}"].notna() & (eff[f"eff{i}"].astype(str) != "nan") & (eff[f"eff{i}"].astype(str) != "")
            ins += list(eff.loc[m, f"eff{i}_in"].astype(bool))
    joints = list(df["kn_rep_in"].astype(bool)) + list(df["kl_rep_in"].astype(bool))
    joints_true = list(df["kn_true_in"].astype(bool)) + list(df["kl_true_in"].astype(bool))
    loose = eff.found_loose if "found_loose" in eff else eff.found
    return {"found": (int(eff.found.astype(bool).sum()), len(eff)),
            "found_loose": (int(loose.astype(bool).sum()), len(eff)),
            "no_claim": (int((~none.claimed.astype(bool)).sum()), len(none)),
            "effect_ci": (int(sum(ins)), len(ins)),
            "joint_ci": (int(sum(joints)), len(joints)),
            "joint_ci_true_model": (int(sum(joints_true)), len(joints_true))}


LABELS = {"found": "effect cases: the named set holds the truth (top-1 or a tie)",
          "found_loose": "(information) the same, a combination naming a spurious second effect counted too",
          "no_claim": "no-effect cases: no effect claimed",
          "effect_ci": "95 % intervals of the effect parameters hold the truth",
          "joint_ci": "95 % intervals of k_normal, k_lateral (reported model) hold the truth",
          "joint_ci_true_model": "(information) the same in the fit of the true model"}
TARGETED = ("found", "no_claim", "effect_ci", "joint_ci")


def summary_tables(df: pd.DataFrame) -> tuple[str, str, dict]:
    """The summary table (with targets), the splits table and whether each target is met."""
    m = metrics(df)
    met = {}
    rows = []
    for k, label in LABELS.items():
        hit, n = m[k]
        ok = n > 0 and hit / n >= TARGET
        if k in TARGETED:
            met[k] = ok
        rows.append([label, _rate(hit, n), f">= {100 * TARGET:.0f} %" if k in TARGETED else "",
                     ("yes" if ok else "NO") if k in TARGETED else ""])
    main = _md(["quantity", "measured", "target", "met"], rows)
    splits = []
    cells_ok = True
    groups = [("noise stated " + k, df[df.noise == k]) for k in NOISE_FACTORS]
    groups += [("shapes" if s else "frequencies only", df[df.shapes.astype(bool) == s]) for s in (True, False)]
    groups += [(f"kind {k}", df[df.kind == k]) for k in ("single", "pair", "none")]
    for name, g in groups:
        mg = metrics(g)
        cells = []
        for k in TARGETED:
            hit, n = mg[k]
            cell = _rate(hit, n)
            if n and hit / n < CELL_TARGET and not name.startswith("kind"):
                cell += " **<80 %**"
                cells_ok = False
            cells.append(cell)
        splits.append([name] + cells)
    met["cells"] = cells_ok
    split_md = _md(["split", "found (effect cases)", "no claim (no-effect)", "effect-parameter CI",
                    "joint CI"], splits)
    return main, split_md, met


def case_table(df: pd.DataFrame) -> str:
    rows = []
    for _, r in df.iterrows():
        eff = []
        for i in (1, 2):
            if f"eff{i}" in r and isinstance(r.get(f"eff{i}"), str) and r[f"eff{i}"]:
                eff.append(f"{r[f'eff{i}_true']:.3g} in [{r[f'eff{i}_lo']:.3g}, {r[f'eff{i}_hi']:.3g}] "
                           f"{'yes' if r[f'eff{i}_in'] else 'NO'}")
        ok = ("yes" if r.found else "NO") if r.kind != "none" else ("NO (claimed)" if r.claimed else "yes")
        rows.append([r.case, r.truth, r.noise, "yes" if r.shapes else "no", r.max_modes, r.explained_by,
                     r.supported or "-", ok, "; ".join(eff) or "-",
                     f"{'yes' if r.kn_rep_in else 'NO'}/{'yes' if r.kl_rep_in else 'NO'}",
                     f"{r.c_hat:.2f}", f"{r.time_s:.0f}"])
    return _md(["case", "truth", "noise", "shapes", "modes", "explained_by", "supported", "right",
                "effect parameter: truth in [95 % CI]", "k_n/k_l in CI", "c_hat", "s"], rows)


# ------------------------------------------------------------------ the run
def parse_options(items) -> dict:
    """``KEY=VALUE`` pairs (YAML values) -> dict."""
    import yaml

    out = {}
    for it in items or []:
        k, _, v = it.partition("=")
        if not _:
            raise SystemExit(f"--set {it}: give KEY=VALUE, e.g. shape_residuals=true")
        out[k.strip()] = yaml.safe_load(v)
    return out


def run_label(rig: str, options: dict) -> str:
    opts = ",".join(f"{k}={json.dumps(v)}" for k, v in sorted(options.items()))
    return f"{rig}" + (f" {opts}" if opts else " (defaults)")


def _slug(label: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_=." else "_" for ch in label).strip("_")


def shard_of(cases: list[dict], shard: tuple[int, int] | None) -> list[dict]:
    """Shard ``(k, n)`` of the cases: every n-th from the k-th (1-based), so that n processes share one
    run's cases (each saves its own rows of the run; :func:`save` merges them case by case)."""
    if shard is None:
        return cases
    k, n = shard
    if not 1 <= k <= n:
        raise SystemExit(f"--shard {k}/{n}: K must be 1..N")
    return cases[k - 1::n]


def run(quick: bool = False, blas_threads: int | None = 1, cases: int | None = None, rig: str = "coarse",
        options: dict | None = None, doc: bool = True, command: str = "", subset: str = "all",
        only: tuple = (), shard: tuple[int, int] | None = None, resume: bool = False) -> Result:
    from jointid.threads import limit_threads

    limit_threads(blas_threads or 1)
    options = dict(options or {})
    label = run_label(rig, options) + (" --quick" if quick else "") + (f" ({subset} only)" if subset != "all" else "")
    todo = shard_of(select(design(), quick, cases, rig, subset), shard)
    if shard is not None:  # one of several processes: the page is written once all have run (--doc-only)
        doc = False
    if only:  # a probe of named cases: a run of its own, never in the doc
        todo = [c for c in design() if c["case"] in only]
        label, doc = label + " (probe)", False
    if resume:  # after a stop: the cases this run already has at this commit are kept, not run again
        done = done_cases(label)
        todo = [c for c in todo if c["case"] not in done]
        print(f"[j] --resume: {len(done)} cases of '{label}' already run at {head_commit()[:10]}", flush=True)
    res = Result("j")
    t0 = time.perf_counter()
    print(f"[j] coverage study: {len(todo)} cases, run '{label}'", flush=True)
    runner = Runner(rig, log=lambda m: print(m, flush=True))
    rows = []
    for k, c in enumerate(todo, 1):
        tc = time.perf_counter()
        folder, synth_s = runner.dataset(c)
        td = time.perf_counter()
        try:
            out = runner.diagnose(folder, options)
            row = score(c, out)
            keep = OUT / "coverage_runs" / _slug(label) / c["case"]  # the tables, for a later reading
            keep.mkdir(parents=True, exist_ok=True)
            out.ranking.to_csv(keep / "ranking.csv", index=False)
            if out.parameters is not None:
                out.parameters.to_csv(keep / "parameters.csv", index=False)
            out.combinations.to_csv(keep / "combinations.csv", index=False)
            (keep / "verdict.txt").write_text(out.verdict + "\n")
            from jointid.reporting.diagnosis_outputs import verdict_record

            rec = verdict_record(out, c["case"], {})
            (keep / "verdict.json").write_text(json.dumps({k: rec[k] for k in ("explained_by", "supported",
                                                                               "model_error")}, default=float) + "\n")
        except Exception as exc:  # a case that fails is a result too: counted as wrong, said why
            row = {"case": c["case"], "kind": c["kind"], "truth": "+".join(c["effects"]) or "none",
                   "noise": c["noise"], "shapes": bool(c["shapes"]), "max_modes": c["max_modes"], "seed": c["seed"],
                   "explained_by": f"ERROR {type(exc).__name__}", "verdict": str(exc)[:500],
                   "found": False if c["effects"] else np.nan, "claimed": True if not c["effects"] else np.nan}
            for i, name in enumerate(c["effects"], 1):
                row.update({f"eff{i}": name, f"eff{i}_in": False})
            for s in ("kn", "kl"):
                row.update({f"{s}_rep_in": False, f"{s}_true_in": False})
        row.update({"run": label, "rig": rig, "options": json.dumps(options, sort_keys=True),
                    "synth_s": synth_s, "time_s": time.perf_counter() - td})
        rows.append(row)
        if k < len(todo):  # the cases so far, kept should the run be stopped
            save_run(pd.DataFrame(rows), label, rig, options, quick, time.perf_counter() - t0, runner,
                     command or _command(quick, cases, rig, options, subset), len(todo))
        ok = ("found" if row["found"] else "MISSED") if c["effects"] else ("CLAIMED" if row["claimed"] else "none claimed")
        cis = [("in" if row.get(f"eff{i}_in") else "OUT") for i in (1, 2) if f"eff{i}" in row]
        print(f"[j] {k:2d}/{len(todo)} {c['case']} {row['truth']:<30s} {c['noise']:5s} "
              f"{'shapes' if c['shapes'] else 'freq  '} {c['max_modes']} modes: {row['explained_by']:<32s} "
              f"{ok:<12s} effect CI {'/'.join(cis) or '-':<6s} joints "
              f"{'in' if row.get('kn_rep_in') else 'OUT'}/{'in' if row.get('kl_rep_in') else 'OUT'}  "
              f"{row['time_s']:.1f} s (synth {synth_s:.0f} s), elapsed {time.perf_counter() - t0:.0f} s", flush=True)
    df = pd.DataFrame(rows)
    total = time.perf_counter() - t0
    main, splits, met = summary_tables(df)
    print(f"\n[j] run '{label}': {len(df)} cases in {total:.0f} s "
          f"(diagnosis {df.time_s.mean():.1f} s per case on average)\n\n{main}\n\n{splits}\n", flush=True)
    m = metrics(df)
    for k in TARGETED:
        hit, n = m[k]
        res.add(LABELS[k] + f" [{label}]", _rate(hit, n), f">= {100 * TARGET:.0f} %", met[k])
    res.add(f"no cell of the splits below 80 % [{label}]", "yes" if met["cells"] else "no", "yes", met["cells"])
    res.add(f"time per case (diagnosis) [{label}]", f"{df.time_s.mean():.1f} s (total {total:.0f} s)")
    res.data = {"label": label, "cases": len(df), "total_s": total, "rig_s": runner.rig_s,
                "mean_case_s": float(df.time_s.mean()), "met": met}
    save_run(df, label, rig, options, quick, total, runner, command or _command(quick, cases, rig, options, subset), len(todo))
    if doc and not quick:
        write_doc()
        res.notes.append(f"docs/validation.md written ({DOC})")
    res.notes.append(f"cases: {CSV}")
    return res


def done_cases(label: str) -> set[str]:
    """The cases of run ``label`` in the CSV that were run at the checked-out commit."""
    if not CSV.exists():
        return set()
    old = pd.read_csv(CSV)
    old = old[old["run"] == label]
    here = head_commit()
    return {c for c, m in zip(old["case"], old["meta"]) if json.loads(m)["commit"] == here}


def _command(quick, cases, rig, options, subset="all") -> str:
    return (f"python -m benchmarks j{' --quick' if quick else ''}{f' --cases {cases}' if cases else ''}"
            f"{' --subset ' + subset if subset != 'all' else ''}"
            f"{' --rig ' + rig if rig != 'coarse' else ''}"
            + "".join(f" --set {k}={json.dumps(v)}" for k, v in options.items()))


def save_run(df: pd.DataFrame, label: str, rig: str, options: dict, quick: bool, total: float, runner,
             command: str, planned: int) -> None:
    """The run's rows with its record (machine, commit, times) into the CSV."""
    meta = {"label": label, "rig": rig, "options": options, "quick": quick, "n_cases": len(df),
            "planned_cases": planned, "total_s": total,
            "rig_build_s": runner.rig_s, "rig_dofs": runner.rig["model"].n_dofs,
            "truth_dofs": runner.truth_model.n_dofs if runner.truth_model is not None else None,
            "mean_case_s": float(df.time_s.mean()), "mean_synth_s": float(df.synth_s.mean()),
            "machine": machine(), "commit": head_commit(), "when": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "command": command, "load_average_1min": os.getloadavg()[0]}
    df = df.copy()
    df["meta"] = json.dumps(meta)
    save(df, label)


def save(df: pd.DataFrame, label: str) -> None:
    """Replace the rows of run ``label`` in the CSV, case by case (the run's other cases, e.g. another
    shard's, and the other runs' rows are kept), under a lock: shards of one run save side by side."""
    import fcntl

    OUT.mkdir(parents=True, exist_ok=True)
    with open(CSV.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if CSV.exists():
            old = pd.read_csv(CSV)
            mine = (old["run"] == label) & old["case"].isin(set(df["case"]))
            df = pd.concat([old[~mine], df], ignore_index=True)
        tmp = CSV.with_suffix(".tmp")
        df.to_csv(tmp, index=False)
        tmp.replace(CSV)


# ------------------------------------------------------------------ the page
DOC_HEAD = """# Validation: coverage of the diagnosis (issue 50)

Generated by `python -m benchmarks j` (benchmarks/bench_j_coverage.py); do not edit by hand.  Every
case below is a synthetic dataset with a known truth, diagnosed as a user's data would be; the page
says how often the diagnosis names the hidden effect, how often it claims an effect where there is
none, and how often its nominal 95 % intervals hold the truth, when the model is a little wrong (the
truth solved on a finer mesh than the analysis) and the noise is stated right, 2x too small or 2x too
large.  The per-case results are in `docs/validation_cases.csv` (written with this page).

## Design

{design_text}

## Definitions

{definitions}

## Targets (issue 50)

- effect cases: the named set holds the truth (top-1, or a named tie that holds it) in >= 90 %;
- no-effect cases: no effect claimed in >= 90 %;
- nominal 95 % intervals hold the truth in >= 90 %, for the effect parameters and for the joint
  stiffnesses alike;
- split by noise statement (right, 2x small, 2x large) and by shapes present or not: no cell below 80 %
  (the split by kind is shown for information).
"""


def _doc_sections() -> tuple[str, str]:
    """The module doc's design and definitions as markdown (its table of kinds rebuilt from ``design()``)."""
    doc = __doc__.replace("``", "`")
    design_text = doc[doc.index("Design (") : doc.index("Scores (")].strip().split("\n", 2)[2]
    definitions = doc[doc.index("Scores (") : doc.index("Targets (")].strip().split("\n", 2)[2]
    cases = design()
    what = {"single": f"each library effect alone, {N_SINGLE_EACH} cases each, its size drawn uniformly from the "
                      "ranges below",
            "pair": "two effects at once: " + ", ".join(f"{a} + {b}" for a, b in PAIRS),
            "none": "no effect"}
    kinds = _md(["kind", "cases", "truth"], [[k, sum(c["kind"] == k for c in cases), what[k]] for k in what])
    lines = design_text.split("\n")
    table_end = max(i for i, ln in enumerate(lines) if ln.startswith("====="))
    return kinds + "\n" + "\n".join(lines[table_end + 1:]), definitions


def bias_table(df: pd.DataFrame) -> str:
    """Where the misses lie: per quantity, the median and range of estimate / truth - 1, the median
    half-width of the 95 % interval (relative) and the misses below / above the truth."""
    rows = []
    items = [("k_normal (reported model)", "kn_rep"), ("k_lateral (reported model)", "kl_rep")]
    for name in EFFECT_NAMES:
        items.append((name, name))
    for label, key in items:
        if key in EFFECT_NAMES:
            parts = []
            for i in (1, 2):
                if f"eff{i}" in df:
                    g = df[df[f"eff{i}"] == key]
                    parts.append(pd.DataFrame({"true": g[f"eff{i}_true"], "est": g[f"eff{i}_est"],
                                               "lo": g[f"eff{i}_lo"], "hi": g[f"eff{i}_hi"]}))
            g = pd.concat(parts) if parts else pd.DataFrame()
        else:
            g = pd.DataFrame({"true": df[f"{key}_true"], "est": df[f"{key}_est"], "lo": df[f"{key}_lo"],
                              "hi": df[f"{key}_hi"]})
        g = g.astype(float)
        have = g.dropna(subset=["est"])
        if not len(g):
            continue
        rel = 100 * (have.est / have.true - 1)
        half = 100 * (have.hi - have.lo) / 2 / have.est.abs()
        below = int((have.hi < have.true).sum())
        above = int((have.lo > have.true).sum())
        rows.append([label, f"{len(have)}/{len(g)}",
                     f"{rel.median():+.1f} % ({rel.min():+.1f} .. {rel.max():+.1f})" if len(have) else "-",
                     f"{half.median():.1f} %" if len(have) else "-", f"{below} / {above}"])
    return _md(["quantity", "estimated", "estimate / truth - 1: median (range)", "95 % half-width (median)",
                "misses: interval below / above the truth"], rows)


def write_doc() -> Path:
    """docs/validation.md from every run in the CSV (and docs/validation_cases.csv)."""
    design_text, definitions = _doc_sections()
    parts = [DOC_HEAD.format(design_text=design_text, definitions=definitions),
             "The cases (coarse rig; the default rig runs the first cases of `--cases`):\n",
             design_table(design()), ""]
    df = rejudge(pd.read_csv(CSV))
    df = df[~df["run"].str.endswith("--quick") & ~df["run"].str.endswith("(probe)")]
    for label, g in df.groupby("run", sort=False):
        metas = [json.loads(m) for m in g["meta"].unique()]  # shards and resumed parts save their own record
        meta = max(metas, key=lambda m: m["when"])
        commits = sorted({m["commit"] for m in metas})
        main, splits, met = summary_tables(g)
        parts += [f"## Run: {label}", "",
                  f"- command: `{meta['command']}`"
                  + (f" ({len(metas)} processes: shards, or a run resumed with `--resume`)" if len(metas) > 1 else ""),
                  (f"- commit: `{commits[0]}`, last case {meta['when']}" if len(commits) == 1 else
                   f"- commits: MIXED ({', '.join(f'`{c[:10]}`' for c in commits)}): rows of different code"),
                  f"- machine: {meta['machine']}, shared with other jobs"
                  + (f" (load average {meta['load_average_1min']:.1f} at the end of the run)"
                     if meta.get("load_average_1min") is not None else "")
                  + ": the times are wall times under that load",
                  f"- rig: {meta['rig']}, {meta['rig_dofs']} DOFs (built in {meta['rig_build_s']:.0f} s); truth model "
                  f"{meta['truth_dofs'] or '(datasets kept from an earlier run)'} DOFs",
                  f"- {len(g)} cases"
                  + (f" (of {meta['planned_cases']} planned: the run was stopped)"
                     if len(metas) == 1 and meta.get("planned_cases", len(g)) > len(g) else "")
                  + f", diagnosis {g['time_s'].mean():.1f} s per case on average ({g['time_s'].sum() / 60:.0f} min "
                  f"in all; synthesis {g['synth_s'].mean():.1f} s, 0 when the dataset was kept)",
                  *([f"- note: {meta['note']}"] if meta.get("note") else []),
                  f"- targets met: " + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in met.items()), "",
                  main, "", "Splits (no cell of the noise and shapes splits may fall below 80 %):", "", splits, "",
                  "Where the estimates and the misses lie (compliance parameters: rail_fixing, base_support "
                  "in N/m^3):", "", bias_table(g), "",
                  "<details><summary>Per case</summary>", "", case_table(g), "", "</details>", ""]
    DOC.write_text("\n".join(parts) + "\n")
    df.drop(columns=["meta"]).to_csv(DOC_CSV, index=False)
    return DOC


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_j_coverage", description=__doc__.split("\n\n")[0])
    add_arguments(ap)
    ap.add_argument("--no-doc", action="store_true", help="do not rewrite docs/validation.md")
    ap.add_argument("--doc-only", action="store_true", help="rewrite docs/validation.md from the CSV, run nothing")
    a = ap.parse_args(argv)
    if a.doc_only:
        print(write_doc())
        return 0
    from .common import format_table, write_result

    res = run(quick=a.quick, cases=a.cases, rig=a.rig, options=parse_options(a.set), doc=not a.no_doc, subset=a.subset,
              only=tuple(x for x in a.only.split(",") if x), shard=parse_shard(a.shard), resume=a.resume,
              command="python -m benchmarks.bench_j_coverage " + " ".join(argv if argv is not None else sys.argv[1:]))
    write_result(res, a.quick)
    print(format_table([res]))
    return 0


def parse_shard(text: str | None) -> tuple[int, int] | None:
    """``K/N`` -> ``(K, N)`` (None for no shard)."""
    if not text:
        return None
    try:
        k, n = (int(v) for v in text.split("/"))
    except ValueError:
        raise SystemExit(f"--shard {text!r}: give K/N, e.g. 1/2") from None
    return k, n


def add_arguments(ap: argparse.ArgumentParser) -> None:
    """The options of benchmark j (also on ``python -m benchmarks``)."""
    if not any("--quick" in a.option_strings for a in ap._actions):
        ap.add_argument("--quick", action="store_true", help="6 cases, no doc")
    ap.add_argument("--cases", type=int, default=None, help="(j) run N cases of the design (default: all)")
    ap.add_argument("--rig", choices=("coarse", "default"), default="coarse", help="(j) the analysis rig")
    ap.add_argument("--only", default="", help="(j) a probe of the named cases (comma-separated), not in the doc")
    ap.add_argument("--subset", choices=("all", "shapes", "frequencies"), default="all",
                    help="(j) only the cases with shapes, or with frequencies only (default: all)")
    ap.add_argument("--shard", default=None, metavar="K/N",
                    help="(j) every N-th case from the K-th: N processes share one run (then --doc-only)")
    ap.add_argument("--resume", action="store_true",
                    help="(j) after a stop: run only the cases the run has not yet run at this commit")
    ap.add_argument("--set", action="append", metavar="KEY=VALUE",
                    help="(j) a diagnosis option, e.g. shape_residuals=true (repeatable)")


if __name__ == "__main__":
    sys.exit(main())
