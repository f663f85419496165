"""The configurations of synthetic cases: a truth model's (:func:`truth_config`) and the rig the synthetic
diagnosis cases are analysed on (:func:`identification_config`).

:mod:`jointid.synthetic.generate` takes their typed settings
(:class:`jointid.config.typed_diagnosis.DiagnosisSettings`), not the dicts.
"""

from __future__ import annotations

from collections.abc import Mapping

from jointid.config.load import load_config
from jointid.yamlio import deep_merge

__all__ = ["identification_config", "truth_config"]


def truth_config(truth: Mapping, base_cfg: Mapping) -> dict:
    """Validated configuration of the truth model (base config + the truth's overrides)."""
    cfg = deep_merge(base_cfg, truth.get("overrides") or {})
    return load_config(cfg)


def identification_config(cfg: Mapping) -> dict:
    """The validated configuration of the rig the synthetic diagnosis cases are analysed on, from a configuration
    dict (not yet validated): the normal and lateral joint stiffness identified (2e11..4e12 N/m^3), the feed
    stiffness fixed at 1e10 N/m^3 (so the feed effect is not absorbed by an identified parameter)."""
    cfg = dict(cfg)
    cfg["joints"] = {**cfg["joints"],
                     "parameters": {"k_normal_N_per_m3": {"direction": "y", "lower": 2.0e11, "upper": 4.0e12},
                                    "k_lateral_N_per_m3": {"direction": "x", "lower": 2.0e11, "upper": 4.0e12}},
                     "fixed": {"k_feed_N_per_m3": 1.0e10}}
    return load_config(cfg)
