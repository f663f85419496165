"""Rule ``joint_damping_states``: does the attraction change the joint loss factor?

Reads every state's ``params.json`` and writes ``results/tables/joint_damping_states.json``
(:func:`jointid.identification.damping_law.states_comparison`): each state's identified structural ratio and
joint loss factors with their 95 % intervals, and each state against the reference state (power_off): the
difference, its combined 95 % interval and whether it excludes 0.  Frequency-only data (the paper's) give
``{"available": false, ...}`` saying why.
"""

from __future__ import annotations

from jointid import io
from jointid.identification.damping_law import states_comparison
from jointid.identification.record import by_state
from jointid.reporting.tables import reference_state
from jointid.stages.runner import log

__all__ = ["run_damping_states"]


def run_damping_states(params_jsons, out_json: str) -> dict:
    """Compare the states' identified joint damping (``params_jsons``: one ``params.json`` per state, the
    state being its folder's name) and write ``out_json``; returns its content."""
    records = {s: rec.joint_damping for s, rec in by_state(params_jsons).items()}
    doc = states_comparison(records, reference_state(list(records)))
    io.write_json(out_json, doc)
    log(f"joint damping states: {doc['note']}")
    return doc
