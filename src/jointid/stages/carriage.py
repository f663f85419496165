"""Rule ``carriage_rigidity``: each state's identified joint springs in a catalogue-style test of one
carriage on its rail (:mod:`jointid.response.carriage`), the number to hold against a guide catalogue."""

from __future__ import annotations

from typing import TYPE_CHECKING

from jointid import io

if TYPE_CHECKING:
    from jointid.config.options import CarriageOptions



def run_carriage_rigidities(opts: CarriageOptions, states: list[str], params_jsons: list[str], out_jsons: list[str],
                            log=print) -> list[dict]:
    """Rule ``carriage_rigidity``: :func:`run_carriage_rigidity` of every state of ``states`` (the lists aligned
    with it) in one process, on one test model: its mesh is the same for every state, assembled once, and its
    first factorisation's ordering serves every later one (the same bits, :class:`BlockTest`)."""
    from jointid.response.carriage import BlockTest

    test = BlockTest(opts.model, opts.cell_size_m)
    return [run_carriage_rigidity(opts, s, p, o, log=log, test=test)
            for s, p, o in zip(states, params_jsons, out_jsons)]


def run_carriage_rigidity(opts: CarriageOptions, state: str, params_json: str, out_json: str, log=print,
                          test=None) -> dict:
    """Rule ``carriage_rigidity``: the identified joints of one state as a catalogue's block rigidity.

    Writes, per direction: the joint springs alone (parameter x contact area), the carriage and rail
    alone (stiff joints), the assembly (both in series, the catalogue's quantity) with every parameter
    at the low and at the high end of its 95 % interval (``assembly_ci95_low/high``: the rigidity grows
    with every spring, so this is an outer bound of its interval), and the joints' share of the
    assembly's compliance (1 - assembly / parts: the compliance they add over stiff joints).
    With a config section ``catalogue`` that has classes, ``catalogue`` holds the assembly against
    each of them (:func:`jointid.response.carriage.catalogue_comparison`); else it is null.  ``test``: the
    :class:`~jointid.response.carriage.BlockTest` of ``opts`` built before (:func:`run_carriage_rigidities`).
    """
    # the FE of the test (scikit-fem) is imported here, not with the rule's config keys (every Snakemake start)
    from jointid.identification.record import IdentificationRecord
    from jointid.response.carriage import DIRECTIONS, BlockTest, catalogue_comparison, catalogue_verdict

    par = IdentificationRecord.read(params_json)
    cell = opts.cell_size_m
    test = test if test is not None else BlockTest(opts.model, cell)
    res = test.rigidity(par.theta)
    low, high = test.rigidity(par.theta_low, False), test.rigidity(par.theta_high, False)
    springs = {d: 0.0 for d in DIRECTIONS}  # the identified parameters' per-carriage values, by direction
    along = {"x": "lateral", "y": "normal", "z": "feed"}
    for p in opts.model.joints.parameters:
        per = (par.per_carriage or {}).get(p.name.replace("_N_per_m3", "_per_carriage_N_per_um"))
        if per is not None:
            springs[along[p.direction]] += per.value
    rows = {}
    for d in DIRECTIONS:
        a = res.assembly_N_per_m[d] * 1e-6
        rows[d] = {"joint_springs_N_per_um": springs[d] or None, "parts_N_per_um": res.parts_N_per_m[d] * 1e-6,
                   "assembly_N_per_um": a, "assembly_ci95_low_N_per_um": low.assembly_N_per_m[d] * 1e-6,
                   "assembly_ci95_high_N_per_um": high.assembly_N_per_m[d] * 1e-6,
                   "joint_share_of_compliance": 1 - a / (res.parts_N_per_m[d] * 1e-6)}
        log(f"carriage_rigidity[{state}]: {d}: assembly {a:,.0f} N/um "
            f"[{rows[d]['assembly_ci95_low_N_per_um']:,.0f}, {rows[d]['assembly_ci95_high_N_per_um']:,.0f}]"
            + (f", joint springs alone {springs[d]:,.0f}" if springs[d] else "")
            + f", carriage and rail alone {rows[d]['parts_N_per_um']:,.0f} N/um "
            f"(joints {100 * rows[d]['joint_share_of_compliance']:.0f} % of the compliance)")
    doc = {"state": state, "cell_size_m": cell, "n_dofs": res.n_dofs,
           "test": "one carriage on a rail segment (2 rail heights beyond either end), rail bottom clamped, "
                   "carriage top moved as a rigid plate; rigidity = reaction / displacement",
           "directions": rows}
    doc["catalogue"] = catalogue_comparison(rows, opts.catalogue)
    for d, c in (doc["catalogue"] or {}).get("directions", {}).items():
        log(f"carriage_rigidity[{state}]: against {doc['catalogue']['block'].split(' (')[0]}: {catalogue_verdict(d, c)}")
    io.write_json(out_json, doc)
    return doc
