"""Plain-language mode descriptions from energy shares.

For each mode: the share of kinetic energy in each part, the share of strain energy stored in each
stiffness term (joints, mounts), and for table modes the dominant rigid-body motion of the table
(sway X, bounce Y, feed Z, pitch about X, yaw about Y, roll about Z) from a least-squares rigid-body fit.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from jointid.fe.fem import Model
from jointid.geometry.rig import PART_IDS

RIGID_NAMES = ["sway", "bounce", "feed", "pitch", "yaw", "roll"]


def energy_shares(model: Model, phi: np.ndarray, kc: dict[str, float], mc: dict[str, float]) -> pd.DataFrame:
    """Kinetic energy share per part and strain energy share per stiffness term, one row per mode."""
    M = model.M(mc)
    K = model.K(kc)
    Mphi = M @ phi
    kin_total = np.einsum("ij,ij->j", phi, Mphi)
    out = {}
    dof_part = np.repeat(model.dof_part, 3)
    for name, pid in PART_IDS.items():
        if pid < 0:
            continue
        sel = dof_part == pid
        out[f"kinetic_{name}"] = np.einsum("ij,ij->j", phi[sel], Mphi[sel]) / kin_total
    strain_total = np.einsum("ij,ij->j", phi, K @ phi)
    for name, c in kc.items():
        if c != 0.0:
            out[f"strain_{name}"] = c * np.einsum("ij,ij->j", phi, model.stiffness[name] @ phi) / strain_total
    return pd.DataFrame(out)


def table_rigid_motion(model: Model, phi: np.ndarray) -> np.ndarray:
    """Rigid-body fit of the table's motion: ``(n_modes, 6)`` amplitudes (m and rad*r_g in m).

    Rotations are scaled by the table's radius of gyration so translations and rotations compare.
    """
    sel = np.flatnonzero(model.dof_part == PART_IDS["table"])
    xyz = model.doflocs[:, sel].T
    c = xyz.mean(axis=0)
    r = xyz - c
    rg = np.sqrt((r ** 2).sum(axis=1).mean())
    n = len(sel)
    A = np.zeros((3 * n, 6))
    for d in range(3):
        A[d::3, d] = 1.0
    # u = t + w x r  ->  ux = wy rz - wz ry ; uy = wz rx - wx rz ; uz = wx ry - wy rx
    A[0::3, 4], A[0::3, 5] = r[:, 2], -r[:, 1]
    A[1::3, 5], A[1::3, 3] = r[:, 0], -r[:, 2]
    A[2::3, 3], A[2::3, 4] = r[:, 1], -r[:, 0]
    rows = (3 * sel[:, None] + np.arange(3)).ravel()
    coef, *_ = np.linalg.lstsq(A, phi[rows], rcond=None)
    coef[3:] *= rg
    return coef.T


def describe_modes(model: Model, phi: np.ndarray, kc: dict[str, float], mc: dict[str, float]) -> pd.DataFrame:
    """Energy shares plus a short description per mode (e.g. ``table bounce``, ``base bending``; on a
    mesh file the bodies that move most, e.g. ``block 71% + table 22%, joints 64%``)."""
    if model.meta.get("kind") == "mesh":
        return _describe_mesh_modes(model, phi, kc, mc)
    df = energy_shares(model, phi, kc, mc)
    rigid = table_rigid_motion(model, phi)
    joint_cols = [c for c in df.columns if c.startswith("strain_K_top") or c.startswith("strain_K_flank")]
    df["strain_joints"] = df[joint_cols].sum(axis=1) if joint_cols else 0.0
    names = []
    pts = model.meta["points"]
    base_rows = [i for i, p in enumerate(pts["point"]) if str(p).startswith("B")]
    for j in range(phi.shape[1]):
        kin_table = df.loc[j, ["kinetic_table", "kinetic_carriage"]].sum()
        kin_base = df.loc[j, ["kinetic_base", "kinetic_rail"]].sum()
        if kin_table >= kin_base:
            amp = np.abs(rigid[j])
            k = int(np.argmax(amp))
            second = np.argsort(amp)[-2]
            label = f"table {RIGID_NAMES[k]}"
            if amp[second] > 0.5 * amp[k]:
                label += f"+{RIGID_NAMES[second]}"
            if df.loc[j, "strain_joints"] < 0.3:
                label += " (table flexible)"
        else:
            label = _base_label(model, phi[:, j], base_rows, pts)
            if "strain_K_mount" in df and df.loc[j, "strain_K_mount"] > 0.5:
                label = "rig on mounts: " + label.replace("base ", "")
        names.append(label)
    df.insert(0, "description", names)
    return df


def _describe_mesh_modes(model: Model, phi: np.ndarray, kc: dict, mc: dict) -> pd.DataFrame:
    """Kinetic energy share per body of a mesh-file model, strain share per term and per joint
    layers; the description names the bodies with the largest kinetic shares."""
    from jointid.fe.model import joint_layer_terms

    Mphi = model.M(mc) @ phi
    kin_total = np.einsum("ij,ij->j", phi, Mphi)
    dof_body = np.repeat(model.dof_part, 3)
    out = {}
    for k, name in enumerate(model.meta["bodies"]):
        sel = dof_body == k
        out[f"kinetic_{name}"] = np.einsum("ij,ij->j", phi[sel], Mphi[sel]) / kin_total
    strain_total = np.einsum("ij,ij->j", phi, model.K(kc) @ phi)
    for name, c in kc.items():
        if c != 0.0:
            out[f"strain_{name}"] = c * np.einsum("ij,ij->j", phi, model.stiffness[name] @ phi) / strain_total
    df = pd.DataFrame(out)
    cols = [f"strain_{t}" for t in sorted(joint_layer_terms(model)) if f"strain_{t}" in df]
    df["strain_joints"] = df[cols].sum(axis=1) if cols else 0.0
    names = []
    kin_cols = [f"kinetic_{b}" for b in model.meta["bodies"]]
    for j in range(phi.shape[1]):
        shares = df.loc[j, kin_cols].sort_values(ascending=False)
        top = [f"{c[len('kinetic_'):]} {v:.0%}" for c, v in shares.items() if v >= 0.2][:2] or \
              [f"{shares.index[0][len('kinetic_'):]} {shares.iloc[0]:.0%}"]
        names.append(" + ".join(top) + f", joints {df.loc[j, 'strain_joints']:.0%}")
    df.insert(0, "description", names)
    return df


def _base_label(model: Model, phi_j: np.ndarray, base_rows: list[int], pts: dict) -> str:
    u = (model.probe @ phi_j).reshape(-1, 3)[base_rows]
    x = np.asarray(pts["x_m"])[base_rows]
    z = np.asarray(pts["z_m"])[base_rows]
    comp = int(np.argmax(np.abs(u).sum(axis=0)))
    if comp != 1:
        return f"base {'lateral' if comp == 0 else 'axial'}"
    uy = u[:, 1]
    left, right = uy[x < 0], uy[x > 0]
    order_l, order_r = np.argsort(z[x < 0]), np.argsort(z[x > 0])
    sym = np.abs(left[order_l] + right[order_r]).sum()
    anti = np.abs(left[order_l] - right[order_r]).sum()
    line = (left[order_l] + right[order_r]) if sym >= anti else (left[order_l] - right[order_r])
    s = np.sign(line[np.abs(line) > 0.05 * np.abs(line).max()])
    crossings = int(np.sum(s[1:] != s[:-1]))
    kind = "bending" if sym >= anti else "torsion"
    return f"base {kind} ({crossings} nodal lines)"
