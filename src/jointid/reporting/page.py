"""The self-contained HTML report of a run: one page, figures embedded as base64 PNG.

A summary card first (:func:`jointid.reporting.summary.card_items`: one sentence each, and the
parameters figure), then Tables 1-3 beside the paper, the identified parameters, FRFs, mode shapes,
the hypotheses, surface diagnostics, configuration and provenance.  The page is rendered from the
jinja2 templates in ``templates/`` (``page.html.j2``: the frame, card and sections; ``page.css``),
its tables by pandas' Styler (:func:`jointid.reporting.htmltable.html_table`, at most eight columns
wide, long text in notes under them).  The workflow stage that reads the inputs and writes the page
is :func:`jointid.stages.report.run_report`.
"""

from __future__ import annotations

import base64
from functools import lru_cache
from typing import TYPE_CHECKING

import pandas as pd
from markupsafe import Markup

from jointid.identification.record import SurfaceStage
from jointid.reporting.htmltable import esc as _esc
from jointid.reporting.htmltable import html_table, notes, reset_ids
from jointid.reporting.more_data import more_data_html
from jointid.reporting.summary import card_items, key_numbers
from jointid.reporting.damping_section import damping_section_html, shown as damping_shown
from jointid.reporting.table_sections import freq_tables_html, table1_html

if TYPE_CHECKING:
    from jointid.config.options import ReportOptions

__all__ = ["build_html", "html_table", "report_figures"]


@lru_cache(maxsize=1)
def _env():
    import jinja2

    return jinja2.Environment(loader=jinja2.PackageLoader("jointid.reporting", "templates"), autoescape=True,
                              keep_trailing_newline=False)


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


def report_figures(opts: ReportOptions, data: dict) -> dict[str, bytes]:
    """The report's figures as PNG bytes: ``frf, errors, parameters, surface, doe, mode_shapes`` and, when
    the carriage rigidity has a catalogue comparison, ``catalogue`` (embedded only; ``opts``: the parameters'
    bounds and the surfaces' verification limit)."""
    from jointid.reporting import figures as fg

    paper1 = data["paper_table1"].set_index("state")["paper_dynamic_stiffness_N_per_mm"].to_dict()
    sigma = {s: float(_or(p.frequency_uncertainty_pct, 1.0)) for s, p in data["params"].items()}
    bounds, limit = dict(opts.bounds_N_per_m3), opts.max_verification_error_pct
    return {
        "frf": fg.png_bytes(fg.frf_overlay(data["frf"], data["stiffness"], paper1,
                                           {s: list(p.f_meas_Hz) for s, p in data["params"].items()})),
        "errors": fg.png_bytes(fg.frequency_errors(data["tables"], sigma)),
        "parameters": fg.png_bytes(fg.parameter_intervals(data["params"], bounds)),
        "surface": fg.png_bytes(fg.surface_diagnostics(data["diagnostics"], limit)),
        "doe": fg.png_bytes(fg.doe_points(data["sheet"], {s: list(p.x_coded) for s, p in data["params"].items()})),
        "mode_shapes": fg.png_bytes(fg.mode_shapes(data["points"], _mode_pictures(data)), dpi=90),
        **({"catalogue": fg.png_bytes(fg.catalogue_rigidity(comps))} if (comps := _catalogue_comparisons(data)) else {}),
    }


def _or(value, default):
    """``value``, or ``default`` where the record has none (None)."""
    return default if value is None else value


def _params_html(data: dict) -> str:
    rows = []
    for state, p in data["params"].items():
        for name, v in p.parameters.items():
            rows.append({"state": state, "parameter": name, "value": v.value, "ci95_low": v.ci95_low,
                         "ci95_high": v.ci95_high, "on bound": "yes" if name in p.on_bound else ""})
        for name, v in (p.per_carriage or {}).items():
            rows.append({"state": state, "parameter": name, "value": v.value, "ci95_low": v.ci95_low,
                         "ci95_high": v.ci95_high, "on bound": ""})
    df = pd.DataFrame(rows)
    fm = {"value": ".4g", "ci95_low": ".4g", "ci95_high": ".4g"}
    extra = []
    for state, p in data["params"].items():
        w = p.warnings
        info = (f"{state}: paired by {'?' if p.paired_by is None else p.paired_by.value}, "
                f"cost {_or(p.cost, float('nan')):.3g}, condition number {_or(p.condition_number, float('nan')):.3g}, "
                f"{_or(p.n_starts_agreeing, '?')} starts agree"
                + (f", weak combination: {p.weak_combination}" if p.weak_combination else ""))
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
    df, text = pd.DataFrame(rows), ("state", "direction", "nearest", "beyond")
    classes = [c for n in names for c in (f"{n}_value", f"{n}_ratio")]
    return (f"<h3>Against the catalogue: {_esc(first['block'].split(' (')[0])}</h3>"
            + html_table(df[["state", "direction", "identified", "low", "high", "nearest", "beyond"]], fm, heads,
                         text_cols=text)
            + html_table(df[["state", "direction", *classes]], fm, heads, text_cols=text, keys=2)
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
    par = next(iter(data["params"].values()), None)
    box = (par and par.surface_box) or {}
    if par is not None and par.surface_stage is SurfaceStage.ZOOM and box:
        head = ("<p class='note'>Surfaces of the zoomed second DOE, in the box around the first-stage optima of "
                "all states: " + "; ".join(f"{_esc(n)} {a:.3g} .. {b:.3g} N/m³" for n, (a, b) in box.items())
                + " (the first DOE's surfaces over the whole bounds: results/surface/diagnostics.csv).</p>")
    else:
        head = "<p class='note'>Surfaces over the whole bounds of joints.parameters.</p>"
    shapes = ("Tracked modes: " + "; ".join(f"{r.tracked_mode} {r.description}" for r in d.itertuples()) + "."
              if {"tracked_mode", "description"} <= set(d.columns) else "")
    return head + html_table(d.drop(columns="description", errors="ignore") if shapes else d, fm,
                             {"verify_max_error_pct": "verification max error (%)"},
                             text_cols=("description",)) + notes([shapes])


def _hypotheses_html(data: dict) -> str:
    from jointid.reporting.hypotheses import hypotheses_html

    h = data["hypotheses"]
    return hypotheses_html(h["ranking"], h["records"], h["spread"], html_table, data["tables"], h.get("ranges"),
                           h.get("next"))


def _provenance_html(opts: ReportOptions, prov: dict) -> str:
    rows = [("workflow commit", prov["workflow_commit"]), ("jointid package commit", prov["package_commit"]),
            ("config hash (jointid.config.config_hash)", prov["config_hash"]),
            ("Python", f"{prov['python']} on {prov['platform']}")]
    rows += [(k, v) for k, v in prov["versions"].items()]
    table = html_table(pd.DataFrame(rows, columns=["item", "value"]), text_cols=("item", "value"))
    return _env().get_template("provenance.html.j2").render(table=Markup(table), config_text=opts.config_yaml)


def _short(commit: str) -> str:
    sha = commit.split(" ")[0]
    return sha[:12] + commit[len(sha):] if len(sha) == 40 else commit


def _table1_section(data: dict) -> str:
    d0 = next(iter(data["stiffness"].values()))
    pt = data["points"].set_index("point").loc[d0["drive_point"]]
    return (table1_html(data)
            + f"<p class='note'>Drive point {d0['drive_point']} ({pt['part']} top at x = {pt['x_m']:.3f} m, "
              f"z = {pt['z_m']:.3f} m). Force and response in {d0['direction'].upper()}, spread and averaged over a "
              f"{1e3 * d0.get('patch_diameter_m', 0.0):g} mm hammer-tip patch. The minimum of |F/X| over the "
              "band sits at a resonance, K_min ≈ 2 ζ_r k_r. So its absolute value follows the "
              + ("damping ratio (its source in the notes above) " if "damping_source" in data["table1"] else
                 "assumed damping ratio (the paper gives none) ")
              + "and which modes the drive point excites: the absolute numbers are not "
              "expected to match the paper's ANSYS model. A state is <i>identified</i> only when the mode that sets "
              "the minimum is paired with a measured mode (verify stage). Otherwise the model's minimum is shown "
              "apart, as not identified, beside the lowest resonance peak of a paired mode.</p>")


def _frf_measured_html(data: dict) -> str:
    from jointid.reporting.frf_section import frf_section_html

    return frf_section_html(*data["frf_measured"], html_table=html_table)


def _sections(opts: ReportOptions, data: dict, figs: dict[str, bytes], prov: dict) -> list[tuple[str, str, str]]:
    """The sections below the summary card: (anchor, title, HTML)."""
    return [
        ("table1", "Table 1 — dynamic stiffness", _table1_section(data)),
        ("freq", "Tables 2 and 3 — natural frequencies",
         freq_tables_html(data) + _img(figs["errors"], "per-mode errors")
         + "<p class='note'>Bars: simulation − test in % of the test frequency. Error bars and the grey band: "
           "±2σ of the assumed measurement uncertainty.</p>"),
        ("params", "Identified joint parameters",
         "<p class='note'>The figure of the summary shows these values and intervals.</p>"
         + _params_html(data) + _rigidity_html(data, figs) + _mesh_check_html(data)),
        *([("damping", "Identified joint damping", damping_section_html(data["joint_damping_states"]))]
          if damping_shown(data.get("joint_damping_states")) else []),
        ("frf", "Frequency response, power-off vs power-on",
         _img(figs["frf"], "FRF overlay") + _harmonic_notes(data)),
        *([("frf_measured", "Measured FRFs against the model's", _frf_measured_html(data))]
          if data.get("frf_measured") else []),
        *([("more_data", "What more of the test would add", more_data_html(data))]
          if more_data_html(data) else []),
        ("shapes", "Mode shapes of the paired modes", _img(figs["mode_shapes"], "mode shapes")
         + "<p class='note'>FE modes paired with the measured modes (verify stage), drawn at the 36 measuring "
           "points: table 3×6 grid on top, base lines below. The scale is arbitrary.</p>"),
        *([("hypotheses", "Reconstruction hypotheses — the linked two-state fit", _hypotheses_html(data))]
          if data.get("hypotheses") else []),
        ("surface", "DOE and response-surface diagnostics", _img(figs["doe"], "DOE")
         + _img(figs["surface"], "surface diagnostics") + _diag_html(data)),
        ("prov", "Configuration and provenance", _provenance_html(opts, prov)),
    ]


def build_html(opts: ReportOptions, data: dict, figs: dict[str, bytes], prov: dict) -> str:
    """The report page (one string, figures embedded): the summary card (:func:`card_items`, with the
    parameters figure), then the sections. ``data`` as read by :func:`jointid.stages.report.load_inputs`,
    ``prov`` by :func:`jointid.reporting.provenance.run_record`."""
    reset_ids()
    d0 = next(iter(data["stiffness"].values()))
    sections = _sections(opts, data, figs, prov)
    band = f"{d0['band_Hz'][0]:g}–{d0['band_Hz'][1]:g} Hz"
    return _env().get_template("page.html.j2").render(
        prov=prov, short_commit=_short(prov["package_commit"]), d0=d0, band=band, summary=key_numbers(data),
        card=card_items(data), card_figure=Markup(_img(figs["parameters"], "identified joint stiffness, 95 % intervals")),
        sections=[{"key": k, "title": t, "html": Markup(c)} for k, t, c in sections])
