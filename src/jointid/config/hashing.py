"""Stable short hash of a configuration, or of some of its sections (:func:`config_hash`).

The workflow's provenance sidecars and the report name a result's configuration by this hash.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from jointid.config.load import section
from jointid.errors import ConfigError

__all__ = ["ConfigStamp", "config_digest", "config_hash"]


def _canonical(value: Any) -> Any:
    """``value`` as plain JSON types; integral floats as ints so that ``1`` and ``1.0`` hash alike."""
    if isinstance(value, Mapping):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):
        return _canonical(value.tolist())
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, (int, float)):
        if isinstance(value, float):
            if not math.isfinite(value):
                raise ConfigError(f"config: {value} cannot be hashed — use finite numbers")
            if value.is_integer() and abs(value) < 2**53:
                return int(value)
        return value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise ConfigError(f"config: value of type {type(value).__name__} cannot be hashed — use YAML types only")


def mesh_digest(cfg: Mapping) -> str:
    """A short digest of the mesh settings of a configuration (its ``mesh`` section and model kind):
    two models with the same digest have the same discretisation (a synthetic dataset computed on the
    analysis's own mesh has no discretisation error against it, :mod:`jointid.diagnosis.mesh_error`)."""
    kind = (cfg.get("model") or {}).get("kind", "rig")
    return config_hash({"mesh": cfg.get("mesh"), "kind": kind})[:16]


def config_hash(cfg: Mapping, keys: str | Iterable[str] | None = None) -> str:
    """Stable short hash of a configuration or of some of its sections.

    The hash is the first 12 hex digits of the SHA-256 of canonical JSON (sorted keys, no
    whitespace, integral floats written as integers so ``1`` and ``1.0`` hash alike).

    Parameters
    ----------
    cfg : mapping
        Configuration (normally from :func:`load_config`).
    keys : str or iterable of str, optional
        Dotted keys of the sections to hash (e.g. ``["rig", "mesh", "joints.parameters"]``);
        default the whole configuration.

    Returns
    -------
    str
        12 lower-case hex digits.
    """
    if keys is None:
        return config_digest(cfg)[:12]
    keys = [keys] if isinstance(keys, str) else list(keys)
    return config_digest({k: section(cfg, k) for k in keys})[:12]


def config_digest(cfg: Mapping) -> str:
    """The whole SHA-256 (64 hex digits) of the canonical JSON of ``cfg`` that :func:`config_hash` cuts to 12."""
    text = json.dumps(_canonical(cfg), sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class ConfigStamp:
    """What a provenance record keeps of the configuration a result depends on: its hash
    (:func:`config_hash`, 12 hex digits) and its top-level sections, in the configuration's order."""

    hash: str
    sections: tuple[str, ...]

    @classmethod
    def of(cls, cfg: Mapping) -> ConfigStamp:
        """The stamp of a configuration (or of the sections of it a rule gets)."""
        return cls(config_hash(cfg), tuple(str(k) for k in cfg))
