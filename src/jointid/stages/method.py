"""The paper's method in one process, without files: the rules ``mesh`` -> ``doe`` -> ``modal`` ->
``gather_modal`` -> ``fit_surface`` (with ``doe.zoom``: -> ``scout`` -> ``doe_zoom`` -> ``modal_zoom`` ->
``gather_zoom`` -> ``fit_zoom``) -> ``identify`` -> ``verify`` -> ``tables``, as the Snakefile chains them.

Each step calls the stage function its rule calls (:func:`jointid.stages.doe.doe_sheet`,
:func:`jointid.stages.modal.doe_modes`, :func:`jointid.stages.surface.surfaces`,
:func:`jointid.stages.identify.identify`, :func:`jointid.stages.verify.verify`,
:func:`jointid.stages.tables.state_table` ...) with the options its rule builds (the same config keys,
:meth:`jointid.config.study.StudySettings.options`), and hands the next one what the rule's file would
hand it: a table as its CSV holds it (:func:`jointid.io.through_csv`, 10 significant digits), a document
as its JSON holds it (:func:`jointid.io.through_json`), the model as its ``matrices.npz`` holds it
(:func:`jointid.fe.model.stored_model`).  So its numbers are the workflow's, to the last digit.  The API
runs it (:meth:`jointid.Study.run_method`).  ``solver.method: rom`` is the workflow's alone.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING

from jointid import io
from jointid.config import rule_keys as keys
from jointid.stages import doe, identify, modal, surface, tables, verify
from jointid.stages.model import mesh_model, model_summary, points_table

if TYPE_CHECKING:
    import pandas as pd

    from jointid.config.options import DoeOptions, IdentifyOptions, SurfaceOptions
    from jointid.config.study import StudySettings
    from jointid.config.typed import ModelSpec
    from jointid.identification.record import IdentificationRecord

__all__ = ["MethodOptions", "MethodRun", "run_method"]


@dataclass(frozen=True)
class MethodOptions:
    """The options of every rule of the method, each built from its rule's config keys (:meth:`of`):
    the states, the models of rules ``mesh``, ``modal`` and ``verify``, the DOE (rule ``doe_zoom``'s: rule
    ``doe``'s and ``doe.zoom``), the surfaces, each state's ``scout`` and ``identify`` and the paper's values
    of Tables 2-3 (None on other data)."""

    states: tuple[str, ...]
    mesh: ModelSpec
    modal: ModelSpec
    doe: DoeOptions
    surface: SurfaceOptions
    scout: Mapping[str, IdentifyOptions]
    identify: Mapping[str, IdentifyOptions]
    verify: ModelSpec
    paper_tables: str | None

    @classmethod
    def of(cls, settings: StudySettings) -> MethodOptions:
        """The options the Snakefile's rules get for the configuration of ``settings``."""
        from jointid.config.options import DoeOptions, IdentifyOptions, SurfaceOptions
        from jointid.config.snakefile import mesh_keys, modal_keys
        from jointid.config.typed import ModelSpec

        states = settings.states
        per_state = {s: partial(IdentifyOptions.from_config, states=[s, *states]) for s in states}
        return cls(states, settings.options(ModelSpec.from_config, mesh_keys),
                   settings.options(ModelSpec.from_config, modal_keys),
                   settings.options(DoeOptions.from_config, keys.DOE_ZOOM),  # rule doe's keys and doe.zoom
                   settings.options(SurfaceOptions.from_config, keys.SURFACE),
                   {s: settings.options(per_state[s], keys.scout(list(states))) for s in states},
                   {s: settings.options(per_state[s], keys.identify(s, list(states))) for s in states},
                   settings.options(ModelSpec.from_config, keys.VERIFY), settings.paper_input(tables.PAPER_TABLES))


@dataclass(frozen=True, eq=False)
class MethodRun:
    """What the method found: the surface model the states were identified on (``surface``), each state's
    identification (``params.json``), its FE verification (:class:`jointid.stages.verify.Verified`) and its
    table of natural frequencies (Tables 2-3: ``tables/table2_power_off.csv`` ...)."""

    surface: dict
    identifications: Mapping[str, IdentificationRecord]
    verified: Mapping[str, verify.Verified]
    tables: Mapping[str, pd.DataFrame]


def run_method(opts: MethodOptions, model=None) -> MethodRun:
    """Run the method (see the module's text) on ``model`` (rule ``mesh``'s model as its file holds it,
    :func:`jointid.fe.model.stored_model`; None: built here).  Progress goes to standard output, as in the rules' logs."""
    from jointid.errors import ConfigError
    from jointid.fe.model import stored_model
    from jointid.identification.record import IdentificationRecord

    if opts.modal.solver.method == "rom":
        raise ConfigError("solver.method: rom runs in the workflow only (snakemake -j2) — use reduced or full here")
    model = stored_model(mesh_model(opts.mesh)) if model is None else model
    pts = io.through_csv(points_table(model))
    areas = io.through_json(model_summary(model))["contact_area_per_carriage_m2"]
    sheet = doe.doe_sheet(opts.doe)
    # rule modal with solver.method full gets each point's parameters from the Snakefile's own sheet, not its file
    doc = _surfaces(opts, model, io.through_csv(sheet), sheet if opts.modal.solver.method == "full" else None)
    if opts.doe.zoom_enabled:
        scout = {s: identify.identify(opts.scout[s], s, doc, pts, areas, states=list(opts.states))
                 for s in opts.states}
        optima = {s: io.through_json(r.to_json())["surface_optimum"] for s, r in scout.items()}
        sheet, box = doe.zoom_sheet(opts.doe, optima)
        doc = _surfaces(opts, model, io.through_csv(sheet), box=io.through_json(box))
    found, checked = {}, {}
    for s in opts.states:
        rec = identify.identify(opts.identify[s], s, doc, pts, areas, model, states=list(opts.states))
        found[s] = IdentificationRecord.from_json(io.through_json(rec.to_json()))
        checked[s] = verify.verify(opts.verify, s, found[s], doc, model)
    paper = tables.read_paper(opts.paper_tables, tables.PAPER_TABLES_COLUMNS)
    out = {s: tables.state_table(s, io.through_csv(v.table), paper, io.through_csv(v.unpaired))
           for s, v in checked.items()}
    return MethodRun(doc, found, checked, out)


def _surfaces(opts: MethodOptions, model, sheet, solve_sheet=None, box: dict | None = None) -> dict:
    """Rules ``modal``, ``gather`` and ``fit_surface`` (or their zoomed twins, ``box``) on one sample sheet (as
    its file holds it; ``solve_sheet``: the one the points are solved at where that is another): the surface
    model as its ``model.json`` holds it."""
    points = [arrays for _, arrays in modal.doe_modes(opts.modal, model, sheet if solve_sheet is None else solve_sheet)]
    _, arrays = modal.gathered(sheet, points)
    doc, diag = surface.surfaces(opts.surface, sheet, arrays, box)
    surface.check_surfaces(opts.surface, doc, diag)
    return io.through_json(doc)
