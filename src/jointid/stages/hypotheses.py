"""Workflow stages of the reconstruction hypotheses (rules ``hypothesis`` and ``hypotheses``).

* :func:`run_hypothesis` fits one hypothesis (``hypotheses.<name>`` in config.yaml) to the run's
  measured states under the linked two-state law and writes ``results/hypotheses/<name>/fit.json``;
* :func:`run_ranking` ranks the fitted hypotheses by QAICc (AICc with the model error of the best):
  ``results/hypotheses/ranking.csv``, ``spread.csv`` (joint parameters over the hypotheses within
  delta QAICc < 4: the reconstruction range), ``ranking.md`` and ``next_measurements.csv`` (the
  measurement that would best narrow that range, :mod:`jointid.reconstruction.next_measurement`).

See :mod:`jointid.reconstruction.hypotheses` and docs/reconstruction.md, "Hypotheses".
"""

from __future__ import annotations

import dataclasses
import os
import time
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from jointid import io
from jointid.diagnosis.fitting import Diagnoser, print_log
from jointid.progress import Steps
from jointid.reconstruction.hypotheses import SHAPE_SEARCH_TOL, fit_hypothesis, not_certified, record, search, search_tol
from jointid.reconstruction.ranking import admissible, rank_hypotheses, reconstruction_ranges
from jointid.reconstruction.next_measurement import ProposalOptions, next_measurement_markdown, propose
from jointid.diagnosis.terms import build_system, build_systems
from jointid.identification.model_error import NO_MODEL_ERROR, ModelError
from jointid.stages.basis import load_basis, measured_states
from jointid.fe.model import build_model, load_model
from jointid.threads import limit_threads

if TYPE_CHECKING:
    from jointid.config.hypotheses import HypothesisJob, RankingOptions

ADMISSIBLE_DELTA_AICC = 4.0


def may_be_admissible(records: dict, rows: list[dict] | None = None) -> list[str]:
    """The hypotheses of ``records`` that are admissible (:func:`jointid.reconstruction.ranking.admissible`) with
    every uncertified one's QAICc lowered by its ``chi2_solver_bound`` (:func:`jointid.reconstruction.hypotheses.chi2_bound`:
    how far its search's tolerance can have left its chi-square above the exact model's; QAICc divides chi-square
    by c-hat >= 1, so the chi-square bound bounds it too).  These get the certificate: a fit that the exact solve
    could bring into the admissible set is not ranked out on a looser solve.  ``rows``: the ranking of ``records``
    (:func:`rank_hypotheses`), when already made."""
    if rows is None:
        rows, _, _ = rank_hypotheses(records, delta=ADMISSIBLE_DELTA_AICC)
    ranked = [r for r in rows if r.get("rank") is not None and np.isfinite(r.get("qaicc", np.nan))]
    if not ranked:
        return []
    q = [r["qaicc"] - (0.0 if records[r["hypothesis"]]["certified"]
                       else float(records[r["hypothesis"]].get("chi2_solver_bound", 0.0))) for r in ranked]
    return [r["hypothesis"] for r, a in zip(ranked, admissible(q, ADMISSIBLE_DELTA_AICC)) if a]


def _to_certify(every: dict, mine: set) -> list[tuple[str, str]]:
    """``(name, why)`` of the records of ``every`` not certified yet that :func:`may_be_admissible` names and whose
    names are in ``mine`` (those this job can certify: its own, and those apart)."""
    rows, _, _ = rank_hypotheses(every, delta=ADMISSIBLE_DELTA_AICC)
    plain = {r["hypothesis"] for r in rows if r.get("admissible")}
    return [(n, "admissible" if n in plain else "within its search tolerance of the admissible set")
            for n in may_be_admissible(every, rows) if not every[n]["certified"] and n in mine]


def run_hypothesis(job: HypothesisJob, matrices: str | None, out_json: str, *, basis: str | None = None,
                   certify: bool = True, log=print_log) -> dict:
    """Fit the hypothesis of ``job`` (:meth:`jointid.config.hypotheses.HypothesisJob.from_config`) and write
    its record to ``out_json``.

    The hypothesis's configuration is validated like config.yaml (its problems name the
    hypothesis).  It reuses the run's model (``matrices``) unless it changes the model beyond its
    coefficients (geometry, support kind, mesh: :func:`~jointid.config.hypotheses.needs_own_model`);
    then it builds its own.  A part's material (Young's modulus, density, Poisson's ratio), the motor
    mass and the like are coefficients of the run's model.
    An override of ``states.<state>.em_force_N`` is the hypothesis's attraction in that state and
    wins over the dataset's ``conditions.yaml`` (which otherwise gives the force).  ``basis``: the
    run model's shared reduced basis (rule ``diagnosis_basis``, :mod:`jointid.stages.basis`), the start
    of the reduced solver of a hypothesis on the run's model.  ``certify=False``: the record is left
    uncertified (:data:`~jointid.reconstruction.hypotheses.PENDING`) for :func:`run_hypotheses`, which ranks
    it with the others and certifies it only if it is admissible.
    """
    limit_threads(1)
    t0 = time.time()
    rec, own, system = _fit_apart(job, matrices, basis, certify, log)
    return _write(job, rec, own, system, out_json, t0, log)


def _fit_apart(job: HypothesisJob, matrices: str | None, basis: str | None, certify: bool, log) -> tuple:
    """:func:`run_hypothesis`'s fit: ``(record, whether it built its own model, its system)``."""
    name, spec = job.name, job.settings.model
    own = job.own_model
    log(f"hypothesis {name}: {'building its own model' if own else 'the run model'}")
    model = build_model(spec) if own else load_model(matrices)
    if not own and job.overrides_model and "solids" not in model.meta and model.meta.get("kind") != "mesh":
        own = True  # a model file written before the solids were kept per part: no material coefficients
        log(f"hypothesis {name}: {matrices} has no per-part solids (written by an older version); building its own")
        model = build_model(spec)
    system = build_system(model, spec)
    data = _states(job, system, log)
    start = None if own else load_basis(basis, system, log)
    rec = fit_hypothesis(system, job.settings, job.law, data, start_basis=start, certify=certify, log=log)
    return rec, own, system


def run_hypotheses(jobs: list[HypothesisJob], matrices: str, out_jsons: list[str], *, basis: str | None = None,
                   others: list[str] = (), apart: list[HypothesisJob] = (), apart_jsons: list[str] = (),
                   log=print_log) -> list[dict]:
    # many parameters: a workflow stage: one parameter per file of its rule (the Snakefile stays as it is)
    """Fit the hypotheses of ``jobs``, which change only coefficients of the run's model
    (:func:`~jointid.config.hypotheses.needs_own_model` false), in one process: the model loaded once, one set
    of terms for all (:func:`jointid.diagnosis.terms.build_systems`) and one reduced solver, started from the
    shared ``basis`` and grown by each fit for the next.  Each record goes to its own file, as
    :func:`run_hypothesis` writes it; the values agree with separate jobs' to the solver's tolerance
    (another basis), not to the last digit.

    A certificate where an answer rests on it: the fits are ranked with the records of ``others`` (the
    run's other hypotheses' records, each fitted in its own job) as rule ``hypotheses`` ranks them,
    and only the admissible ones (:func:`jointid.reconstruction.ranking.admissible`), and those that their search's
    tolerance could make admissible (:func:`may_be_admissible`), get the certificate's Sturm count and the
    predictions of the next measurement; the ranking is made again after each round, until every admissible
    hypothesis is certified.  Every solve of every fit is checked in the full space
    (residuals); a rejected hypothesis's record says that it was not Sturm-counted, and why.

    ``apart`` (the jobs of ``others``, in their order): those records were left uncertified in their own
    jobs (:func:`run_hypothesis` with ``certify=False``).  An admissible one is fitted again here on its own
    model and certified; each is written to ``apart_jsons`` (its final record).  Without ``apart`` the
    records of ``others`` are taken as their jobs certified them."""
    limit_threads(1)
    model = load_model(matrices)
    if "solids" not in model.meta and model.meta.get("kind") != "mesh" and any(j.overrides_model for j in jobs):
        # a model file written before the solids were kept per part: each hypothesis as its own job would,
        # certified (those apart too: their jobs left it to this one)
        for job, path in zip(apart, apart_jsons):
            run_hypothesis(job, matrices, path, basis=basis, log=log)
        return [run_hypothesis(j, matrices, out, basis=basis, log=log) for j, out in zip(jobs, out_jsons)]
    systems = build_systems(model, [j.settings.model for j in jobs])
    start, solver = load_basis(basis, systems[0], log), None
    steps = Steps(len(jobs))
    by_name = {j.name: j for j in jobs}
    diags, found, recs, t0 = {}, {}, {}, time.time()
    for job, system in zip(jobs, systems):
        log(f"hypothesis {job.name} {steps.next()}: the run model"
            + (", the reduced solver of the hypotheses before" if solver is not None else ""))
        data = _states(job, system, log)
        diag = Diagnoser(system, job.settings, data, solver=solver, tol=search_tol(data),
                         start_basis=start if solver is None else None, log=log)
        diags[job.name], found[job.name] = diag, search(diag, job.law, log)
        solver = diag.solver
        recs[job.name] = _named(job, record(diag, found[job.name], certify=False), system)
    fixed = {}
    for path in others:
        rec = io.read_json(path)
        fixed[rec["hypothesis"]] = rec
    apart_by_name = {j.name: j for j in apart}
    while True:  # certify the admissible ones; a certificate may move a fit, so rank again
        todo = _to_certify({**fixed, **recs}, set(recs) | set(apart_by_name))
        if not todo:
            break
        for name, why in todo:
            log(f"hypothesis {name}: {why}, certified")
            if name in recs:
                recs[name] = _named(by_name[name], record(diags[name], found[name], certify=True), diags[name].system)
            else:  # fitted apart on its own model, uncertified there: fitted again on it, and certified
                rec, own, system = _fit_apart(apart_by_name[name], matrices, basis, True, log)
                fixed[name] = _named(apart_by_name[name], rec, system, own)
    out = []
    for job, path in zip(jobs, out_jsons):
        rec = recs[job.name]
        io.write_json(path, rec)
        log(f"hypothesis {job.name}: chi2 {rec['chi2']:.2f}, AICc {rec['aicc']:.2f}"
            + ("" if rec["certified"] else " (not admissible: no Sturm count)"))
        out.append(rec)
    for job, path in zip(apart, apart_jsons):
        rec = fixed[job.name]
        if not rec["certified"]:
            # a record written before its tolerance was kept was searched at SHAPE_SEARCH_TOL (1e-5)
            rec["certificate"] = not_certified(rec.get("search_tol", SHAPE_SEARCH_TOL))
        io.write_json(path, rec)
        log(f"hypothesis {job.name} (its own model): chi2 {rec['chi2']:.2f}, AICc {rec['aicc']:.2f}"
            + ("" if rec["certified"] else " (not admissible: no Sturm count)"))
    log(f"hypotheses on the run model: {len(jobs)} in {time.time() - t0:.0f} s")
    return out


def _states(job: HypothesisJob, system, log) -> list:
    """The measured states of hypothesis ``job`` on ``system``, with the attraction its overrides give."""
    data = measured_states(job.settings, system)
    for d in data:
        if d.name in job.forces_N and float(job.forces_N[d.name]) != d.info.em_force_N:
            log(f"hypothesis {job.name}: {d.name} attraction {float(job.forces_N[d.name]):g} N (the dataset's: "
                f"{d.info.em_force_N:g} N)")
            d.info = dataclasses.replace(d.info, em_force_N=float(job.forces_N[d.name]))
    return data


def _named(job: HypothesisJob, rec: dict, system, own: bool = False) -> dict:
    """The hypothesis's record with its name, description and model (no timing: the record is byte-identical
    run to run)."""
    rec.update({"hypothesis": job.name, "description": job.description, "own_model": own, "n_dofs": system.n_dofs})
    return rec


def _write(job: HypothesisJob, rec: dict, own: bool, system, out_json: str, t0: float, log) -> dict:
    """The hypothesis's record with its name, description and model, written to ``out_json``."""
    io.write_json(out_json, _named(job, rec, system, own))
    log(f"hypothesis {job.name}: chi2 {rec['chi2']:.2f}, AICc {rec['aicc']:.2f} ({time.time() - t0:.0f} s)")
    return rec


CREDIBLE_RATIO = (0.6, 1.5)
"""Lateral/normal rigidity ratio of a carriage on its rail that a guide catalogue makes credible."""


def run_ranking(opts: RankingOptions, fit_jsons: list[str], out_csv: str, spread_csv: str, out_md: str,
                linked_json: str | None = None, ranges_csv: str | None = None, next_csv: str | None = None, *,
                log=print_log) -> pd.DataFrame:
    # many parameters: a workflow stage: one parameter per file of its rule (the Snakefile stays as it is)
    """Rank the fitted hypotheses by QAICc and write the ranking, the parameter spread and a summary;
    with ``linked_json`` (``opts``: :meth:`jointid.config.hypotheses.RankingOptions.from_config` of
    :data:`RANKING_CONFIG`) also the best hypothesis's linked fit per state with the rigidity of one carriage
    on its rail under its joints; with ``next_csv`` the candidate measurements over the admissible
    hypotheses, best first (``next_measurement`` of the configuration,
    :func:`jointid.reconstruction.next_measurement.propose`; ranking.md has them either way)."""
    records = {}
    for path in fit_jsons:
        rec = io.read_json(path)
        records[rec["hypothesis"]] = rec
    rows, spread, me = rank_hypotheses(records, delta=ADMISSIBLE_DELTA_AICC)
    ranking = pd.DataFrame(rows)
    ranking["rank"] = ranking["rank"].astype("Int64")  # blank for the hypotheses listed apart
    linked = None
    if linked_json:
        linked = linked_summary(opts, records[rows[0]["hypothesis"]], log)
    io.write_csv(ranking, out_csv)
    io.write_csv(pd.DataFrame(spread), spread_csv)
    ranges = pd.DataFrame(reconstruction_ranges(records, rows, delta=ADMISSIBLE_DELTA_AICC))
    if ranges_csv:
        io.write_csv(ranges, ranges_csv)
    proposal = propose(records, rows, opts.proposal, sigma_model_rel=me.sigma_model_rel,
                       sigma_shape_rel=me.shape.sigma_model_rel if me.shape is not None else 0.0)
    if next_csv:
        io.write_csv(proposal[0], next_csv)
    best = proposal[1]["best"]
    if best is not None:
        t = proposal[1]["target"]
        log(f"next measurement: {best['measurement']} — {t} x{proposal[1]['before']:.2f} -> "
            f"x{best[t + '_ratio_after']:.2f}, {best['expected_hypotheses_left']:.1f} hypotheses left")
    io.write_text(out_md, ranking_markdown(ranking, pd.DataFrame(spread), records, linked, me, ranges,
                                           proposal=proposal, opts=opts.proposal))
    if linked_json:
        io.write_json(linked_json, linked)
    return ranking


def linked_summary(opts: RankingOptions, rec: dict, log=print_log) -> dict:
    """The best hypothesis's linked fit per state: joint stiffness per area and the lateral, normal
    and feed rigidity of one carriage on its rail (:class:`jointid.response.carriage.BlockTest`),
    with the lateral/normal ratio and whether it lies in :data:`CREDIBLE_RATIO`."""
    from jointid.response.carriage import BlockTest

    name = rec["hypothesis"]
    test = BlockTest(*opts.carriage_tests[name])
    states = {}
    for s in rec["states"]:
        res = test.rigidity(s["joints_N_per_m3"], parts=False)  # the assembly's only: one factorisation per state
        a = {d: res.assembly_N_per_m[d] * 1e-6 for d in res.assembly_N_per_m}
        ratio = a["lateral"] / a["normal"]
        states[s["state"]] = {"joints_N_per_m3": s["joints_N_per_m3"], "assembly_N_per_um": a,
                              "lateral_over_normal": ratio,
                              "credible": bool(CREDIBLE_RATIO[0] <= ratio <= CREDIBLE_RATIO[1]),
                              "max_abs_error_pct": s["max_abs_error_pct"],
                              "n_unpaired_visible": s["n_unpaired_visible"]}
        log(f"linked fit [{s['state']}]: carriage lateral {a['lateral']:,.0f}, normal {a['normal']:,.0f} N/um, "
            f"ratio {ratio:.2f}")
    params = {p["parameter"]: p for p in rec["parameters"]}
    return {"hypothesis": name, "description": rec.get("description", ""), "preload_N": rec.get("preload_N"),
            "preload_profile": rec.get("preload_profile", []), "parameters": params,
            "interval_scale": rec["interval_scale"], "credible_ratio": list(CREDIBLE_RATIO), "states": states,
            "all_parameters_inside_bounds": not any(p.get("at_bound") for p in rec["parameters"])}


def ranking_markdown(ranking: pd.DataFrame, spread: pd.DataFrame, records: dict, linked: dict | None = None,
                     me: ModelError | None = None, ranges: pd.DataFrame | None = None, *,
                     proposal: tuple | None = None, opts: ProposalOptions | None = None) -> str:
    """The ranking as a short Markdown page (report and README); with ``proposal`` (:func:`propose`'s
    table and summary) the section on the measurement that would narrow the reconstruction."""
    me = me or NO_MODEL_ERROR
    lines = ["# Reconstruction hypotheses ranked by QAICc", "", me.sentence(), "",
             "Each hypothesis is fitted to both states at once under the linked contact law "
             "(docs/reconstruction.md, \"Hypotheses\"); unpaired, clearly visible model modes count as "
             "misfits in chi-square and in the errors. QAICc is AICc at the stated noise plus that model error "
             f"(c_hat = {me.c_hat:.1f}, held fixed for all); weights are Akaike weights of QAICc.", "",
             "| rank | hypothesis | ΔQAICc | weight | χ² | max error per state (%) | unpaired visible | β | P (N) |",
             "|---:|---|---:|---:|---:|---|---|---:|---:|"]
    apart = []
    for _, r in ranking.iterrows():
        rec = records[r["hypothesis"]]
        errs = " / ".join(f"{s['max_abs_error_pct']:.2f}" for s in rec["states"])
        if r.get("listed_apart"):
            apart.append(f"| {r['hypothesis']} | {errs} | {r['listed_apart']} |")
            continue
        mis = " / ".join(str(s["n_unpaired_visible"]) for s in rec["states"])
        beta = r.get("em_preload.beta", np.nan)
        pre = "—" if rec.get("preload_N") is None else f"{rec['preload_N']:g}"
        lines.append(f"| {r['rank']} | {r['hypothesis']} | {r['delta_qaicc']:.1f} | {r['weight']:.2f} | "
                     f"{r['chi2']:.1f} | {errs} | {mis} | {beta:.3f} | {pre} |")
    unchecked = [r["hypothesis"] for _, r in ranking.iterrows() if not r.get("certified", True)]
    if unchecked:
        lines += ["", "Not Sturm-counted (outside the admissible set, so no answer rests on them; every solve of "
                  "their fits was checked in the full space by its residuals): " + ", ".join(unchecked) + "."]
    if apart:
        lines += ["", "Listed apart (a broken reading, not a competitor; no QAICc is given):", "",
                  "| hypothesis | max error per state (%) | reason |", "|---|---|---|"] + apart
    lines += ["", f"Joint parameters over the admissible hypotheses (within ΔQAICc < {ADMISSIBLE_DELTA_AICC:g}, or in the "
              "95 % confidence set of models: the reconstruction range; intervals scaled by max(1, √(χ²/dof))):", "",
              "| parameter | hypotheses | value range | weighted value | combined 95 % interval |",
              "|---|---:|---|---:|---|"]
    for _, s in spread.iterrows():
        lines.append(f"| {s['parameter']} | {s['n_hypotheses']} | {s['value_min']:.4g} … {s['value_max']:.4g} | "
                     f"{s['value_weighted']:.4g} | {s['combined_ci95_low']:.4g} … {s['combined_ci95_high']:.4g} |")
    if ranges is not None and len(ranges):
        top = ranges[ranges["mode"] == 0]
        lines += ["", "The answers over the same admissible reconstructions (reconstruction.csv; Table 1 by modal "
                  "superposition of each fit's modes at the nominal damping):", "",
                  "| quantity | state | unit | range | weighted | hypotheses |", "|---|---|---|---|---:|---:|"]
        for _, r in top.iterrows():
            lines.append(f"| {r['quantity']} | {r['state']} | {r['unit']} | {r['value_min']:.4g} … "
                         f"{r['value_max']:.4g} | {r['value_weighted']:.4g} | {r['n_hypotheses']} |")
    if linked:
        lines += ["", f"The linked fit of the best hypothesis ({linked['hypothesis']}): a carriage on its rail under "
                  "its joints (rule carriage_rigidity's test):", "",
                  "| state | max error (%) | unpaired visible | lateral (N/µm) | normal (N/µm) | lateral/normal | "
                  f"credible ({linked['credible_ratio'][0]:g}–{linked['credible_ratio'][1]:g}) |",
                  "|---|---:|---:|---:|---:|---:|---|"]
        for st, v in linked["states"].items():
            a = v["assembly_N_per_um"]
            lines.append(f"| {st} | {v['max_abs_error_pct']:.2f} | {v['n_unpaired_visible']} | {a['lateral']:,.0f} | "
                         f"{a['normal']:,.0f} | {v['lateral_over_normal']:.2f} | {'yes' if v['credible'] else 'no'} |")
    if proposal is not None:
        lines += next_measurement_markdown(proposal[0], proposal[1], opts)
    return "\n".join(lines) + "\n"


def fit_path(results: str, name: str) -> str:
    """Where hypothesis ``name``'s record goes."""
    return os.path.join(results, "hypotheses", name, "fit.json")
