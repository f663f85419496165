"""The EMA's criteria as one typed object, with defaults from the config schema (``ema:``)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields, replace

from jointid.config.schema import load_schema
from jointid.errors import ConfigError

__all__ = ["EmaOptions"]


@dataclass(frozen=True)
class EmaOptions:
    """How the EMA selects poles and measures their uncertainty (schema section ``ema``).

    Attributes
    ----------
    band_Hz : tuple of float or None
        Analysis band (Hz); None: the FRFs' band, 2 % in from each end.
    max_order : int
        Highest LSCF model order (poles per order, conjugates included).
    freq_tol_pct, damping_tol_pct : float
        Stability of a pole against the closest pole of the next lower order (percent).
    mac_min : float
        Stability in shape: MAC with that pole's shape.
    min_stable_orders : int
        Orders at which a cluster must be stable to count as a physical pole.
    max_damping_ratio : float
        Poles with a damping ratio outside (0, this) are not physical.
    n_bootstrap : int
        Bootstrap replicates over response rows (0: none).
    seed : int
        Seed of the bootstrap.
    coherence_min, max_low_coherence_fraction : float
        Time data: lines below ``coherence_min`` are flagged; more than this fraction is an error.
    """

    band_Hz: tuple[float, float] | None = None
    max_order: int = 60
    freq_tol_pct: float = 1.0
    damping_tol_pct: float = 10.0
    mac_min: float = 0.95
    min_stable_orders: int = 6
    max_damping_ratio: float = 0.2
    n_bootstrap: int = 40
    seed: int = 52
    coherence_min: float = 0.9
    max_low_coherence_fraction: float = 0.2

    @classmethod
    def from_section(cls, section: Mapping | None = None, **overrides) -> EmaOptions:
        """Options from the config section ``ema`` (None: the schema's defaults), then ``overrides``."""
        props = load_schema()["properties"]["ema"]["properties"]
        values = {f.name: props[f.name]["default"] for f in fields(cls)}
        for key, value in dict(section or {}).items():
            if key == "sources":
                continue
            if key not in values:
                raise ConfigError(f"ema.{key}: unknown key — use one of {', '.join(values)}")
            values[key] = value
        values.update(overrides)
        if values["band_Hz"] is not None:
            lo, hi = map(float, values["band_Hz"])
            if not 0 <= lo < hi:
                raise ConfigError(f"ema.band_Hz = {values['band_Hz']!r} is not [low, high] with 0 <= low < high — "
                                  "give the analysis band in Hz, e.g. [100, 3500]")
            values["band_Hz"] = (lo, hi)
        if int(values["max_order"]) < 4:
            raise ConfigError(f"ema.max_order = {values['max_order']} is below 4 — give 20 to 100")
        return replace(cls(), **values)
