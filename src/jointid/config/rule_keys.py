"""The config keys each rule hashes (``params: cfg=``): a change outside them does not rerun the rule.

One place for every rule's keys, and nothing here imports more than the standard library: the
Snakefile reads them at every Snakemake call (the loop of docs/effects.md included), so naming a
rule's keys must not load the numerical code that runs it.  The API's method
(:mod:`jointid.stages.method`) reads the same tuples.  Keys that depend on the configuration itself (the
modal rules', the mesh's) are in :mod:`jointid.config.snakefile`.
"""

from __future__ import annotations

__all__ = ["BASIS", "CARRIAGE", "DOE", "DOE_ZOOM", "EMA", "HYPOTHESIS", "MESH_CHECK", "RANKING", "ROM", "ROM_KEYS",
           "SOLVE_KEYS", "SURFACE", "TIE_DAMPING_KEYS", "VERIFY", "harmonic", "identify", "scout"]

SOLVE_KEYS = ("solver.n_modes", "solver.shift_Hz", "solver.backend", "solver.min_freq_Hz")
"""The ``solver`` keys of one eigen-solve (not the DOE's reduced-basis method)."""
TIE_DAMPING_KEYS = tuple(f"harmonic.damping.{k}" for k in ("model", "damping_ratio", "alpha_per_s", "beta_s"))
"""The damping keys the resolvability rule among tied pairings reads
(:func:`jointid.stages.identify.tie_damping`), not the range."""
ROM_KEYS = ("method", "rom_tolerance")
"""``solver`` keys of the reduced-order model only."""

DOE = ("joints", "doe.design", "doe.n_center", "doe.n_samples", "doe.seed", "doe.n_verification")
"""Rule ``doe`` (not ``doe.zoom``: that is the second DOE's only)."""
DOE_ZOOM = ("joints", "doe")
"""Rule ``doe_zoom``."""
ROM = ("materials", "rig", "model", "joints", "solver")
"""Rule ``rom``."""
SURFACE = ("joints", "surface", "solver.min_freq_Hz", "harmonic.band_Hz")
"""Rules ``fit_surface`` and ``fit_zoom``."""
VERIFY = ("materials", "rig", "model", "joints", "mesh.extrapolate_edges", *SOLVE_KEYS)
"""Rule ``verify`` (``mesh.extrapolate_edges``: its frequencies are scaled by the identification's
mesh-extrapolation factors)."""
MESH_CHECK = ("materials", "rig", "model", "mesh", "mesh_check", "joints", "identify.weights", *SOLVE_KEYS)
"""Rule ``mesh_check``."""
CARRIAGE = ("materials", "rig", "joints", "mesh.element", "solver.backend", "carriage_rigidity", "catalogue")
"""Rule ``carriage_rigidity``."""
EMA = ("ema",)
"""Rule ``ema`` (its sources: :func:`jointid.config.snakefile.ema_sources`)."""
BASIS = ("materials", "rig", "model", "joints", "states", "measurements", "solver", "identify", "harmonic")
"""Rule ``diagnosis_basis`` (plus ``datasets`` when a state names one).  Not ``effects``: the basis starts at the
baseline, and enabling an effect (the loop of docs/effects.md) must not build it again."""
HYPOTHESIS = ("materials", "rig", "model", "mesh", "joints", "states", "measurements", "datasets", "solver", "identify",
              "harmonic", "effects", "linked", "hypotheses")
"""The sections a hypothesis reads (its own entry of ``hypotheses`` only, see the rule)."""
RANKING = ("materials", "rig", "model", "joints", "mesh.element", "solver.backend", "carriage_rigidity", "hypotheses",
           "next_measurement")
"""Rule ``hypotheses`` (the best hypothesis's joints in the catalogue-style block test)."""


def identify(state: str, states: list[str]) -> tuple[str, ...]:
    """Rule ``identify``: the shared sections, this state's settings and the other states' datasets (the
    measured modes of frequency-only states are paired alike in all states)."""
    return ("materials", "rig", "model", "joints", "identify", "mesh", *SOLVE_KEYS, "measurements",
            "harmonic.band_Hz", "harmonic.drive_point", *TIE_DAMPING_KEYS, f"states.{state}",
            *(f"states.{s}.dataset" for s in states))


def scout(states: list[str]) -> tuple[str, ...]:
    """Rule ``scout``: what the surface-only identification reads (not the FE solve, not the motor force)."""
    return ("joints", "identify.n_starts", "identify.seed", "identify.frequency_uncertainty_pct",
            "identify.weights", "identify.pairing", "identify.visible_threshold", "solver.min_freq_Hz",
            "harmonic.band_Hz", "harmonic.drive_point", *TIE_DAMPING_KEYS, "measurements",
            *(f"states.{s}.dataset" for s in states))


def harmonic(state: str) -> tuple[str, ...]:
    """Rule ``harmonic``: the shared sections and this state's settings only."""
    return ("materials", "rig", "model", "joints", "solver", "harmonic", "measurements", "datasets", f"states.{state}")
