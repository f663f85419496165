"""What the API's :class:`jointid.Study` reads of its configuration, typed once (:class:`StudySettings`)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import TypeVar

from jointid.config.hashing import config_hash
from jointid.config.typed import Settings
from jointid.config.typed_diagnosis import DiagnosisSettings

__all__ = ["StudySettings"]

T = TypeVar("T")


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

    @property
    def states(self) -> tuple[str, ...]:
        """The configured states (``states``), in order: the workflow's ``STATES``."""
        return tuple(self.config["states"])

    def options(self, build: Callable[[Mapping], T], keys: Iterable[str] | Callable[[Mapping], Iterable[str]]) -> T:
        """What a workflow rule gets: ``build`` (an options class's ``from_config``) of the configuration's parts
        ``keys`` (:func:`jointid.config.snakefile.sections`; the rule's ``params: cfg=``), or of the keys that
        ``keys`` gives for the configuration (:func:`jointid.config.snakefile.mesh_keys` ...)."""
        from jointid.config.snakefile import sections

        return build(sections(self.config, *(keys(self.config) if callable(keys) else keys)))

    def paper_input(self, path: str) -> str | None:
        """``path`` (a file of the paper's values) when the measured dataset is the paper's, else None
        (:func:`jointid.config.snakefile.paper_input`: the tables' paper columns stay empty)."""
        from jointid.config.snakefile import paper_input

        return paper_input(self.config, path) or None
