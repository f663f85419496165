"""The self-contained HTML report of a run: one page, figures embedded as base64 PNG.

Tables 1-3 beside the paper, FRFs, errors, identified parameters, surface diagnostics, mode shapes,
configuration and provenance.  The page is rendered from the jinja2 templates in ``templates/``
(``page.html.j2``: the frame, summary and sections; ``page.css``), its tables by pandas' Styler
(:func:`html_table`); the key box's numbers come from :func:`jointid.reporting.summary.key_numbers`.
The workflow stage that reads the inputs and writes the page is
:func:`jointid.stages.report.run_report`.
"""

from __future__ import annotations

import base64
import html
import math
from functools import lru_cache

import pandas as pd
from markupsafe import Markup

from jointid.reporting.summary import key_numbers

__all__ = ["build_html", "html_table", "report_figures"]


@lru_cache(maxsize=1)
def _env():
    import jinja2

    return jinja2.Environment(loader=jinja2.PackageLoader("jointid.reporting", "templates"), autoescape=True,
                              keep_trailing_newline=False)


def _esc(x) -> str:
    return html.escape(str(x))


def _fmt(v, spec: str) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)) or (not isinstance(v, str) and pd.isna(v)):
        return "–"
    return format(v, spec) if spec else str(v)


_TABLE_IDS = [0]  # tables on the page so far: each gets its own id (Styler's uuid)


def html_table(df: pd.DataFrame, formats: dict[str, str] | None = None, headers: dict[str, str] | None = None,
               text_cols=()) -> str:
    """``df`` as an HTML table (pandas Styler): cells formatted by ``formats`` (format specs; missing
    and non-finite values as "–"), columns renamed by ``headers``, ``text_cols`` left-aligned."""
    formats, headers = formats or {}, headers or {}
    cells = df.rename(columns=headers)
    names = [headers.get(c, c) for c in df.columns]
    text = [headers.get(c, c) for c in df.columns if c in text_cols]
    fm = {headers.get(c, c): (lambda v, spec=formats.get(c, ""): _esc(_fmt(v, spec))) for c in df.columns}
    classes = pd.DataFrame([["t" if c in text else "" for c in names]] * len(cells), columns=names,
                           index=cells.index)
    uid = f"t{_TABLE_IDS[0]}"
    _TABLE_IDS[0] += 1
    st = (cells.style.format(fm).format_index(escape="html", axis=1).hide(axis="index").set_uuid(uid)
          .set_td_classes(classes)
          .set_table_styles({c: [{"selector": "th", "props": "text-align:left"}] for c in text}, overwrite=False))
    return st.to_html()


def _img(png: bytes, alt: str) -> str:
    return f"<img alt='{_esc(alt)}' src='data:image/png;base64,{base64.b64encode(png).decode()}'>"


def _mode_pictures(data: dict) -> dict[str, list[dict]]:
    pts = data["points"]
    out = {}
    for state, ver in data["verify"].items():
        z = data["modes"].get(state)
        if z is None:
            continue
        labels = [str(s) for s in z["labels"]]
        rows = [labels.index(f"{p}:{d}") for p in pts["point"] for d in "xyz"]
        pics = []
        for _, r in ver.iterrows():
            j = int(r["fe_mode"]) - 1
            if j < 0 or j >= z["shapes"].shape[1]:
                continue
            u = z["shapes"][rows, j].reshape(-1, 3)
            pics.append({"title": f"mode {int(r['order'])}: {r['experimental_Hz']:.0f} Hz test / "
                                  f"{r['simulation_Hz']:.0f} Hz FE\n{r['description']}", "u": u})
        out[state] = pics
    return out


def report_figures(cfg: dict, data: dict) -> dict[str, bytes]:
    """The report's figures as PNG bytes: ``frf, errors, parameters, surface, doe, mode_shapes`` and, when
    the carriage rigidity has a catalogue comparison, ``catalogue`` (embedded only)."""
    from jointid.reporting import figures as fg

    paper1 = data["paper_table1"].set_index("state")["paper_dynamic_stiffness_N_per_mm"].to_dict()
    sigma = {s: float(p.get("frequency_uncertainty_pct", 1.0)) for s, p in data["params"].items()}
    bounds = {n: (s["lower"], s["upper"]) for n, s in cfg.get("joints", {}).get("parameters", {}).items()}
    limit = cfg.get("surface", {}).get("max_verification_error_pct")
    return {
        "frf": fg.png_bytes(fg.frf_overlay(data["frf"], data["stiffness"], paper1,
                                           {s: p.get("f_meas_Hz", []) for s, p in data["params"].items()})),
        "errors": fg.png_bytes(fg.frequency_errors(data["tables"], sigma)),
        "parameters": fg.png_bytes(fg.parameter_intervals(data["params"], bounds)),
        "surface": fg.png_bytes(fg.surface_diagnostics(data["diagnostics"], limit)),
        "doe": fg.png_bytes(fg.doe_points(data["sheet"], {s: p["x_coded"] for s, p in data["params"].items()})),
        "mode_shapes": fg.png_bytes(fg.mode_shapes(data["points"], _mode_pictures(data)), dpi=90),
        **({"catalogue": fg.png_bytes(fg.catalogue_rigidity(comps))} if (comps := _catalogue_comparisons(data)) else {}),
    }


def _table1_html(data: dict) -> str:
    t = data["table1"].copy()
    order = lambda v: "" if pd.isna(v) else f" (measured mode {int(v)})"  # noqa: E731
    t["ratio_to_paper"] = t.dynamic_stiffness_N_per_mm / t.paper_dynamic_stiffness_N_per_mm
    t["governing"] = [f"FE mode {r.governing_mode}: {r.governing_description}, {r.governing_freq_Hz:.0f} Hz"
                      + order(r.governing_measured_order) for _, r in t.iterrows()]
    t["paired_governing"] = ["–" if pd.isna(r.paired_governing_mode) else
                             f"FE mode {r.paired_governing_mode}: {r.paired_governing_description}, "
                             f"{r.paired_governing_freq_Hz:.0f} Hz" + order(r.paired_governing_measured_order)
                             for _, r in t.iterrows()]
    cols = ["state", "status", "dynamic_stiffness_N_per_mm", "not_identified_dynamic_stiffness_N_per_mm",
            "paper_dynamic_stiffness_N_per_mm", "ratio_to_paper", "increase_pct", "paper_increase_pct", "f_at_min_Hz",
            "governing", "paired_dynamic_stiffness_N_per_mm", "paired_increase_pct", "paired_governing",
            "damping_ratio_governing", "static_stiffness_N_per_mm"]
    heads = {"dynamic_stiffness_N_per_mm": "K_dyn,min identified (N/mm)",
             "not_identified_dynamic_stiffness_N_per_mm": "K_dyn,min not identified (N/mm)",
             "paper_dynamic_stiffness_N_per_mm": "paper (N/mm)", "ratio_to_paper": "ratio to paper",
             "increase_pct": "increase (%)", "paper_increase_pct": "paper increase (%)",
             "f_at_min_Hz": "minimum at (Hz)", "governing": "governing mode",
             "paired_dynamic_stiffness_N_per_mm": "lowest peak of a paired mode (N/mm)",
             "paired_increase_pct": "its increase (%)", "paired_governing": "that paired mode",
             "damping_ratio_governing": "ζ of the governing mode", "static_stiffness_N_per_mm": "static 1/H(0) (N/mm)"}
    fm = {c: ",.0f" for c in cols if c.endswith("_N_per_mm")}
    fm.update({"ratio_to_paper": ".2f", "increase_pct": "+.1f", "paper_increase_pct": "+.1f", "paired_increase_pct": "+.1f",
               "f_at_min_Hz": ".1f", "damping_ratio_governing": ".3g"})
    out = html_table(t[cols], fm, heads, text_cols=("state", "status", "governing", "paired_governing"))
    rng = data.get("table1_ranges")
    if rng is not None and len(rng):
        r = rng.copy()
        r["paper_inside"] = r["paper_inside"].map(lambda v: "yes" if v in (True, "True") else "no")
        ref = r["reference_state"].iloc[0]
        rc = ["state", "basis", "over", "n_cases", "reference_k_min_low_N_per_mm", "reference_k_min_high_N_per_mm",
              "k_min_low_N_per_mm", "k_min_high_N_per_mm", "increase_low_pct", "increase_high_pct", "paper_inside"]
        rh = {"basis": "K_min of", "n_cases": "cases", "reference_k_min_low_N_per_mm": f"{ref} lowest (N/mm)",
              "reference_k_min_high_N_per_mm": f"{ref} highest (N/mm)", "k_min_low_N_per_mm": "lowest (N/mm)",
              "k_min_high_N_per_mm": "highest (N/mm)", "increase_low_pct": "increase from (%)",
              "increase_high_pct": "increase to (%)", "paper_inside": "paper +42.1 % inside"}
        rf = {c: ",.0f" for c in rc if c.endswith("_N_per_mm")}
        rf.update({"increase_low_pct": "+.1f", "increase_high_pct": "+.1f"})
        out += ("<h3>Ranges over the 18 table points and three damping laws</h3>"
                + html_table(r[rc], rf, rh, text_cols=("state", "basis", "over", "paper_inside"))
                + "<p class='note'>Each case: drive and response at one table point (T01…T18) in the drive direction, "
                  "over a hammer-tip patch; damping laws: constant modal ζ; joint dashpots c = η·k_joint (ζ_r = η ω_r e_r / 2, "
                  "e_r the mode's strain-energy share in the joints); a constant joint loss factor k_joint(1 + iγ) "
                  "(ζ_r ≈ γ e_r / 2). The laws are calibrated so that the reference state's governing paired mode at "
                  "the drive point has the configured ratio, so they differ only in how the damping changes between the "
                  "states. The increase is taken case by case. 'Paired modes': the lowest resonance peak of a mode "
                  "paired with a measured one; 'all modes': the band minimum, whichever mode sets it.</p>")
    return out


def _freq_tables_html(data: dict) -> str:
    out = []
    titles = {"power_off": "Table 2 — power-off", "power_on": "Table 3 — power-on"}
    for state, tab in data["tables"].items():
        t = tab.copy()
        ver = data["verify"].get(state)
        if ver is not None:
            t = t.merge(ver[["order", "fe_mode", "mac_to_tracked", "description"]], on="order", how="left")
        heads = {"order": "order", "experimental_Hz": "test (Hz)", "simulation_Hz": "this model (Hz)",
                 "relative_error_pct": "error (%)", "paper_simulation_Hz": "paper ANSYS (Hz)",
                 "paper_relative_error_pct": "paper error (%)", "fe_mode": "FE mode", "mac_to_tracked": "MAC to tracked",
                 "description": "FE mode shape"}
        fm = {"experimental_Hz": ".1f", "simulation_Hz": ".1f", "relative_error_pct": "+.2f",
              "paper_simulation_Hz": ".1f", "paper_relative_error_pct": "+.2f", "mac_to_tracked": ".3f"}
        out.append(f"<div><h3>{titles.get(state, state)}</h3>{html_table(t, fm, heads, text_cols=('description',))}</div>")
    return "<div class='row'>" + "".join(out) + "</div>"


def _params_html(data: dict) -> str:
    rows = []
    for state, p in data["params"].items():
        for name, v in p["parameters"].items():
            rows.append({"state": state, "parameter": name, "value": v["value"], "ci95_low": v["ci95_low"],
                         "ci95_high": v["ci95_high"], "on bound": "yes" if name in p.get("on_bound", []) else ""})
        for name, v in p.get("per_carriage", {}).items():
            rows.append({"state": state, "parameter": name, "value": v["value"], "ci95_low": v["ci95_low"],
                         "ci95_high": v["ci95_high"], "on bound": ""})
    df = pd.DataFrame(rows)
    fm = {"value": ".4g", "ci95_low": ".4g", "ci95_high": ".4g"}
    extra = []
    for state, p in data["params"].items():
        w = p.get("warnings") or []
        info = (f"{state}: paired by {p.get('paired_by', '?')}, cost {p.get('cost', float('nan')):.3g}, "
                f"condition number {p.get('condition_number', float('nan')):.3g}, "
                f"{p.get('n_starts_agreeing', '?')} starts agree"
                + (f", weak combination: {p['weak_combination']}" if p.get("weak_combination") else ""))
        extra.append(f"<li>{_esc(info)}" + "".join(f"<br><span class='warn'>warning: {_esc(x)}</span>" for x in w)
                     + "</li>")
    return (html_table(df, fm, {"ci95_low": "95 % low", "ci95_high": "95 % high"}, text_cols=("state", "parameter",
                                                                                              "on bound"))
            + f"<ul class='note'>{''.join(extra)}</ul>")


def _rigidity_html(data: dict, figs: dict | None = None) -> str:
    """The identified joints as a catalogue's carriage rigidity (rule carriage_rigidity), and against the
    guide's catalogue when the run has one (figure ``catalogue`` of ``figs``)."""
    if not data.get("rigidity"):
        return ""
    rows = []
    for state, d in data["rigidity"].items():
        for direction, r in d["directions"].items():
            rows.append({"state": state, "direction": direction, "springs": r["joint_springs_N_per_um"],
                         "parts": r["parts_N_per_um"], "assembly": r["assembly_N_per_um"],
                         "low": r["assembly_ci95_low_N_per_um"], "high": r["assembly_ci95_high_N_per_um"],
                         "share": 100 * r["joint_share_of_compliance"]})
    heads = {"springs": "joint springs alone (N/µm)", "parts": "carriage and rail alone (N/µm)",
             "assembly": "carriage on its rail (N/µm)", "low": "all parameters at 95 % low",
             "high": "all parameters at 95 % high",
             "share": "joints' share of the compliance (%)"}
    fm = {k: ",.0f" for k in ("springs", "parts", "assembly", "low", "high")} | {"share": ".0f"}
    return ("<h3>Carriage rigidity, as a guide catalogue states it</h3>"
            "<p class='note'>One carriage on a rail segment, rail bottom clamped, carriage top moved as a "
            "rigid plate (results/identify/&lt;state&gt;/carriage_rigidity.json). Compare the assembly's "
            "rigidity with the catalogue of the guide: the joint springs act in series with the carriage's "
            "and rail's own deformation.</p>"
            + html_table(pd.DataFrame(rows), fm, heads, text_cols=("state", "direction"))
            + _catalogue_html(data, figs))


def _catalogue_comparisons(data: dict) -> dict[str, dict]:
    """``{state: catalogue comparison}`` of the states whose carriage_rigidity.json has one."""
    return {s: d["catalogue"] for s, d in (data.get("rigidity") or {}).items() if d.get("catalogue")}


def _catalogue_html(data: dict, figs: dict | None = None) -> str:
    """The carriage on its rail beside each preload class of the guide's catalogue (config ``catalogue``)."""
    from jointid.response.carriage import catalogue_verdict

    comps = _catalogue_comparisons(data)
    if not comps:
        return ""
    first = next(iter(comps.values()))
    names = list(next(iter(first["directions"].values()))["classes"])
    rows, fm, heads, lines, fallback = [], {"identified": ",.0f", "low": ",.0f", "high": ",.0f"}, {}, [], False
    for state, comp in comps.items():
        for d, doc in sorted(comp["directions"].items(), key=lambda kv: kv[0] != "normal"):
            row = {"state": state, "direction": d, "identified": doc["identified_N_per_um"],
                   "low": doc.get("identified_ci95_low_N_per_um"), "high": doc.get("identified_ci95_high_N_per_um")}
            for n in names:
                c = doc["classes"][n]
                row[f"{n}_value"], row[f"{n}_ratio"] = c["catalogue_N_per_um"], c["ratio"]
                fallback |= d == "lateral" and c["catalogue_key"] != "lateral_N_per_um"
            row["nearest"] = doc["nearest_class"]
            row["beyond"] = ("above the stiffest" if doc["exceeds_stiffest"] else
                             "below the softest" if doc["below_softest"] else "")
            rows.append(row)
            lines.append(f"{state}: {catalogue_verdict(d, doc)}".replace("N/um", "N/µm"))
        if "lateral_to_normal" in comp:
            cat = ", ".join(f"{n} {v:.2f}" for n, v in comp["lateral_to_normal"]["catalogue"].items())
            lines.append(f"{state}: lateral / normal {comp['lateral_to_normal']['identified']:.2f} (catalogue {cat})")
    for n in names:
        fm[f"{n}_value"], fm[f"{n}_ratio"] = ",.0f", ".2f"
        heads[f"{n}_value"], heads[f"{n}_ratio"] = f"{n} (N/µm)", f"ratio to {n}"
    heads |= {"identified": "identified (N/µm)", "low": "95 % low", "high": "95 % high", "nearest": "nearest class",
              "beyond": "beyond the classes"}
    img = _img(figs["catalogue"], "identified rigidity vs catalogue classes") if figs and figs.get("catalogue") else ""
    return (f"<h3>Against the catalogue: {_esc(first['block'].split(' (')[0])}</h3>"
            + html_table(pd.DataFrame(rows), fm, heads, text_cols=("state", "direction", "nearest", "beyond"))
            + img
            + f"<ul class='note'>{''.join(f'<li>{_esc(x)}</li>' for x in lines)}</ul>"
            + "<p class='note'>Identified: the carriage on its rail (springs and parts in series), one block; "
              "ratio = identified / catalogue; nearest = the class the identified value is the smallest factor from"
            + (". The catalogue states one rigidity per class, used for the lateral direction as well" if fallback
               else "")
            + f". Block: {_esc(first['block'])}. Source: {_esc(first['source'])} (config section "
              "<code>catalogue</code>).</p>")


def _mesh_check_html(data: dict) -> str:
    """The mesh check (rule mesh_check, opt-in): the parameters' first-order change on a refined mesh."""
    if not data.get("mesh_check"):
        return ""
    rows, notes = [], []
    for state, d in data["mesh_check"].items():
        for name, p in d["parameters"].items():
            rows.append({"state": state, "parameter": name, "value": p["value"],
                         "refined": p["value_refined_first_order"], "change_pct": p["change_pct"],
                         "ci95_half_width_pct": p["ci95_half_width_pct"]})
        notes.append(f"<li>{_esc(state)}: {d['n_dofs_default']:,} → {d['n_dofs_refined']:,} DOFs "
                     f"({_esc(', '.join(d['halved']))} cells halved), paired modes move by up to "
                     f"{d['max_paired_frequency_change_pct']:.2f} %"
                     + "".join(f"<br><span class='warn'>{_esc(w)}</span>" for w in d["warnings"]) + "</li>")
    fm = {"value": ".4g", "refined": ".4g", "change_pct": "+.2f", "ci95_half_width_pct": ".1f"}
    return ("<h3>Mesh check</h3><p class='note'>The identified parameters re-solved on a nested refinement of "
            "the mesh; 'refined' is where a re-identification there would move them, to first order "
            "(results/mesh_check/).</p>"
            + html_table(pd.DataFrame(rows), fm, {"refined": "refined mesh (first order)", "change_pct": "change (%)",
                                                   "ci95_half_width_pct": "95 % half-width (%)"},
                          text_cols=("state", "parameter"))
            + f"<ul class='note'>{''.join(notes)}</ul>")


def _harmonic_notes(data: dict) -> str:
    items = []
    for state, d in data["stiffness"].items():
        g = d["governing_mode"]
        items.append(
            f"<li><b>{_esc(state)}</b>: {d['modes']['n_modes']} modes up to {d['modes']['highest_Hz']:.0f} Hz "
            f"(target {d['modes']['target_Hz']:.0f} Hz); {_esc(d['residual']['note'])}. Governing FE mode "
            f"{g['fe_mode']} ({_esc(g['description'])}, {g['freq_Hz']:.0f} Hz, joint strain-energy share "
            f"{g['strain_joints']:.2f}): modal stiffness at the drive point k_r = {g['modal_stiffness_N_per_m'] * 1e-6:,.0f} "
            f"N/µm, 2ζk_r = {g['two_zeta_k_N_per_m'] * 1e-3:,.0f} N/mm. {_esc(d['damping']['measured'])}."
            + "".join(f"<br><span class='warn'>{_esc(w)}</span>" for w in d.get("warnings", [])) + "</li>")
    why = next(iter(data["stiffness"].values()))["damping"]["why"]
    return f"<ul class='note'>{''.join(items)}</ul><p class='note'>Damping: {_esc(why)}.</p>"


def _diag_html(data: dict) -> str:
    d = data["diagnostics"]
    fm = {"ref_freq_Hz": ".1f", "min_mac_in_doe": ".3f", "r2": ".5f", "r2_adj": ".5f", "r2_pred": ".5f",
          "rmse": ".3g", "verify_max_error_pct": ".2f"}
    par = next(iter(data["params"].values()), {})
    box = par.get("surface_box") or {}
    if par.get("surface_stage") == "zoom" and box:
        head = ("<p class='note'>Surfaces of the zoomed second DOE, in the box around the first-stage optima of "
                "all states: " + "; ".join(f"{_esc(n)} {a:.3g} .. {b:.3g} N/m³" for n, (a, b) in box.items())
                + " (the first DOE's surfaces over the whole bounds: results/surface/diagnostics.csv).</p>")
    else:
        head = "<p class='note'>Surfaces over the whole bounds of joints.parameters.</p>"
    return head + html_table(d, fm, {"verify_max_error_pct": "verification max error (%)"},
                              text_cols=("description",))


def _hypotheses_html(data: dict) -> str:
    from jointid.reporting.hypotheses import hypotheses_html

    h = data["hypotheses"]
    return hypotheses_html(h["ranking"], h["records"], h["spread"], html_table, data["tables"], h.get("ranges"))


def _provenance_html(cfg: dict, prov: dict) -> str:
    import yaml

    rows = [("workflow commit", prov["workflow_commit"]), ("jointid package commit", prov["package_commit"]),
            ("config hash (jointid.config.config_hash)", prov["config_hash"]),
            ("Python", f"{prov['python']} on {prov['platform']}")]
    rows += [(k, v) for k, v in prov["versions"].items()]
    table = html_table(pd.DataFrame(rows, columns=["item", "value"]), text_cols=("item", "value"))
    text = yaml.safe_dump(cfg, sort_keys=False, default_flow_style=None, width=110)
    return _env().get_template("provenance.html.j2").render(table=Markup(table), config_text=text)


def _short(commit: str) -> str:
    sha = commit.split(" ")[0]
    return sha[:12] + commit[len(sha):] if len(sha) == 40 else commit


def build_html(cfg: dict, data: dict, figs: dict[str, bytes], prov: dict) -> str:
    """The report page (one string, figures embedded); ``data`` as read by
    :func:`jointid.stages.report.load_inputs`, ``prov`` by :func:`jointid.reporting.provenance.run_record`."""
    _TABLE_IDS[0] = 0
    d0 = next(iter(data["stiffness"].values()))
    pt = data["points"].set_index("point").loc[d0["drive_point"]]
    sections = [
        ("table1", "Table 1 — dynamic stiffness",
         _table1_html(data)
         + f"<p class='note'>Drive point {d0['drive_point']} ({pt['part']} top at x = {pt['x_m']:.3f} m, "
           f"z = {pt['z_m']:.3f} m), force and response in {d0['direction'].upper()}, spread and averaged over a "
           f"{1e3 * d0.get('patch_diameter_m', 0.0):g} mm hammer-tip patch. The minimum of |F/X| over the "
           "band sits at a resonance, K_min ≈ 2 ζ_r k_r: its absolute value follows the assumed damping ratio "
           "(the paper gives none) and which modes the drive point excites, so the absolute numbers are not "
           "expected to match the paper's ANSYS model. A state is <i>identified</i> only when the mode that sets "
           "the minimum is paired with a measured mode (verify stage); otherwise the model's minimum is shown "
           "apart, as not identified, beside the lowest resonance peak of a paired mode.</p>"),
        ("frf", "Frequency response, power-off vs power-on",
         _img(figs["frf"], "FRF overlay") + _harmonic_notes(data)),
        ("freq", "Tables 2 and 3 — natural frequencies",
         _freq_tables_html(data) + _img(figs["errors"], "per-mode errors")
         + "<p class='note'>Bars: simulation − test in % of the test frequency; error bars and the grey band: "
           "±2σ of the assumed measurement uncertainty.</p>"),
        ("shapes", "Mode shapes of the paired modes", _img(figs["mode_shapes"], "mode shapes")
         + "<p class='note'>FE modes paired with the measured modes (verify stage), drawn at the 36 measuring "
           "points: table 3×6 grid on top, base lines below; the scale is arbitrary.</p>"),
        ("params", "Identified joint parameters", _img(figs["parameters"], "identified parameters")
         + _params_html(data) + _rigidity_html(data, figs) + _mesh_check_html(data)),
        *([("hypotheses", "Reconstruction hypotheses — the linked two-state fit", _hypotheses_html(data))]
          if data.get("hypotheses") else []),
        ("surface", "DOE and response-surface diagnostics", _img(figs["doe"], "DOE")
         + _img(figs["surface"], "surface diagnostics") + _diag_html(data)),
        ("prov", "Configuration and provenance", _provenance_html(cfg, prov)),
    ]
    band = f"{d0['band_Hz'][0]:g}–{d0['band_Hz'][1]:g} Hz"
    return _env().get_template("page.html.j2").render(
        prov=prov, short_commit=_short(prov["package_commit"]), d0=d0, band=band, summary=key_numbers(data),
        sections=[{"key": k, "title": t, "html": Markup(c)} for k, t, c in sections])
