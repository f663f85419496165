"""Each joint direction's share of a mode's strain energy, from a modal result's energy table.

The joint damping laws (:mod:`jointid.identification.joint_damping`) need, per paired mode r and joint
parameter (direction) j, ``e_rj = phi_r^T (sum_t c_t K_t) phi_r / w_r^2`` over the joint-layer terms t of
parameter j (:func:`jointid.fe.model.joint_terms`: ``k_normal_N_per_m3`` -> ``K_top_y`` on the rig,
``k_feed_N_per_m3`` -> ``K_top_z`` and ``K_flank_z`` ...).  The energy table of a modal solve
(:func:`jointid.fe.describe.energy_shares`, ``ModalResult.energy`` of :meth:`jointid.Study.modes`) holds
each stiffness term's share ``strain_<term>``; this module sums them per direction.  Terms split per
carriage (``K_top_y@2``) count towards their layer's parameter; a term the table lacks (coefficient 0)
stores no energy.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from jointid.config.typed import ModelSpec
from jointid.errors import ModelError
from jointid.fe.model import joint_terms

__all__ = ["direction_shares", "model_direction_shares"]


def direction_shares(energy: pd.DataFrame, terms: Mapping[str, Sequence[str]], names: Sequence[str]) -> np.ndarray:
    """Strain-energy share of each joint parameter's layers in each mode.

    Parameters
    ----------
    energy : DataFrame
        One row per mode with ``strain_<term>`` columns (shares of the mode's strain energy, 0..1).
    terms : mapping of str -> sequence of str
        Joint parameter -> its layer terms (:func:`jointid.fe.model.joint_terms`).
    names : sequence of str
        The parameters of the columns, in order.

    Returns
    -------
    ndarray, shape (n_modes, len(names))
        ``e_rj`` (dimensionless, 0..1).

    Raises
    ------
    jointid.errors.ModelError
        If a name has no layer terms.
    """
    out = np.zeros((len(energy), len(names)))
    for j, name in enumerate(names):
        layers = set(terms.get(name, ()))
        if not layers:
            raise ModelError(f"{name}: no joint-layer terms — use one of {', '.join(terms)}")
        cols = [c for c in energy.columns if c.startswith("strain_") and c[len("strain_"):].split("@")[0] in layers]
        if cols:
            out[:, j] = energy[cols].to_numpy(float).sum(axis=1)
    return out


def model_direction_shares(energy: pd.DataFrame, spec: ModelSpec, names: Sequence[str] | None = None) -> np.ndarray:
    """:func:`direction_shares` with the layer terms of the model ``spec`` (rig or mesh file); ``names``:
    default the identified joint parameters (``joints.parameters``), in config order."""
    terms = joint_terms(spec.joints, spec.mesh_file)
    return direction_shares(energy, terms, spec.joints.names if names is None else list(names))
