"""What the API's :class:`jointid.Study` reads of its configuration, typed once (:class:`StudySettings`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from jointid.config.hashing import config_hash
from jointid.config.typed import Settings
from jointid.config.typed_diagnosis import DiagnosisSettings

__all__ = ["StudySettings"]


@dataclass(frozen=True)
class StudySettings:
    """A study's configuration as the API reads it: the validated configuration itself (``config``: what
    :attr:`jointid.Study.config` shows, and what a truth's overrides are merged into), its typed objects
    (``settings``), the diagnosis's view of it (``diagnosis``; the same :class:`~jointid.config.typed.ModelSpec`),
    the modes' weights (``identify.weights``; None: ones) and the configuration's hash."""

    config: Mapping
    settings: Settings
    diagnosis: DiagnosisSettings
    weights: tuple[float, ...] | None
    config_hash: str

    @classmethod
    def from_config(cls, cfg: Mapping) -> StudySettings:
        """The settings of a validated configuration (:func:`jointid.config.load_config`)."""
        diag = DiagnosisSettings.from_config(cfg)
        weights = (cfg.get("identify") or {}).get("weights")
        return cls(cfg, Settings(model=diag.model, test_setup=diag.test_setup), diag,
                   tuple(weights) if weights else None, config_hash(cfg))
