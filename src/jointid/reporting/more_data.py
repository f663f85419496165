"""What more of the test would add: one line per kind of data the dataset lacks (mode shapes, damping
ratios, FRFs), with what it would change in this run's answer.

A hammer test measures shapes, damping and FRFs beside the natural frequencies.  A dataset that
carries frequencies only (the paper's) still gives every table; this section says, with this run's
numbers, what each missing kind would add.  It lists nothing when the dataset has all three.
"""

from __future__ import annotations

from html import escape


def _by_frequency(data: dict) -> bool:
    from jointid.correlate.pairing import PairedBy

    return any((p.paired_by or PairedBy.MAC).by_frequency for p in data["params"].values())


def _tied(data: dict) -> list[str]:
    return [s for s, p in data["params"].items() if p.tie_rule is not None and p.tie_rule.tied]


def _shapes_line(data: dict) -> str | None:
    if not _by_frequency(data):
        return None
    tied = _tied(data)
    why = (f"Here the pairing is tied in {', '.join(s.replace('_', '-') for s in tied)}: Table 1 rests on a "
           "tie rule that shapes would replace." if tied else
           "Here the frequencies alone pair the modes without a tie.")
    return ("<b>Mode shapes</b> would pair the model's modes with the measured ones by MAC instead of by "
            f"frequency, and can enter the diagnosis's fits (<code>diagnosis.shape_residuals</code>). {why}")


def _damping_line(data: dict) -> str | None:
    if any(p.joint_damping is not None for p in data["params"].values()):
        return None
    t1 = data["table1"]
    spans = []
    for _, row in t1.iterrows():
        lo, hi = row.get("k_dyn_min_low_N_per_mm"), row.get("k_dyn_min_high_N_per_mm")
        zl, zh = row.get("damping_ratio_low"), row.get("damping_ratio_high")
        if all(v == v and v is not None for v in (lo, hi, zl, zh)):
            spans.append(f"{str(row['state']).replace('_', '-')} {lo:,.0f}–{hi:,.0f} N/mm over ζ {zl:g}–{zh:g}")
    today = (" Today Table 1 takes an assumed damping ratio, and its minimum spans " + "; ".join(spans) + "."
             if spans else " Today Table 1 takes an assumed damping ratio.")
    return ("<b>Damping ratios</b>, one per measured mode, would identify a structural ζ0 and a loss factor per "
            "joint direction with intervals; Table 1 and the model FRFs would then use them." + today)


def _frf_line(data: dict) -> str | None:
    if data.get("frf_measured"):
        return None
    return ("<b>Measured FRFs</b> (<code>frf.csv</code> or UFF 58) would be overlaid with the model's, scored by "
            "FRAC and CSAC, and give a measured drive-point dynamic stiffness beside Table 1's model value.")


def more_data_lines(data: dict) -> list[str]:
    """HTML lines, one per kind of data the dataset lacks (``data`` as read by
    :func:`jointid.stages.report.load_inputs`); empty when it has shapes, damping ratios and FRFs."""
    return [line for line in (_shapes_line(data), _damping_line(data), _frf_line(data)) if line]


def more_data_html(data: dict) -> str:
    """The section's HTML, or "" when nothing is missing."""
    lines = more_data_lines(data)
    if not lines:
        return ""
    return ("<p>This dataset carries natural frequencies" + ("" if len(lines) == 3 else " and more")
            + ". What the rest of a modal test would add:</p><ul>"
            + "".join(f"<li>{line}</li>" for line in lines) + "</ul>"
            + "<p class='note'>The keys are described in docs/measurement-format.md; <code>"
            + escape("jointid data check <folder>") + "</code> validates a dataset.</p>")
