"""FRFs of a known modal model, with noise: the known truth of the EMA's tests and examples.

``H_ij(w) = sum_r phi_ir phi_jr / (w_r^2 - w^2 + 2 i zeta_r w_r w)`` (receptance, m/N, mass-normalised
shapes), with complex Gaussian noise of ``noise_pct`` percent of ``|H|`` on every line (seeded).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from jointid.ema.frfs import FrfSet

__all__ = ["modal_frfs", "frf_table"]


def modal_frfs(freq_Hz, freqs_Hz, zetas, phi, dofs, refs, *, noise_pct: float = 0.0, seed: int = 0,
               state: str = "measured") -> FrfSet:
    # many parameters: the grid, the modal model (f, zeta, shapes, DOFs), the references, noise, seed, state
    """FRFs of every DOF of ``dofs`` for each reference in ``refs``.

    Parameters
    ----------
    freq_Hz : array_like, shape (n_f,)
    freqs_Hz, zetas : array_like, shape (n_modes,)
        Undamped natural frequencies (Hz) and viscous damping ratios.
    phi : array_like, shape (n_dofs, n_modes)
        Mass-normalised shapes (m/sqrt(kg)) at ``dofs``.
    dofs : sequence of (point, direction)
    refs : sequence of int
        Indices into ``dofs`` of the hammer DOFs.
    noise_pct : float
        1-sigma of the complex noise on each line, percent of ``|H|`` there.
    """
    f = np.asarray(freq_Hz, float)
    w = 2 * np.pi * f[:, None]
    wr = 2 * np.pi * np.asarray(freqs_Hz, float)[None, :]
    inv = 1 / (wr**2 - w**2 + 2j * np.asarray(zetas, float)[None, :] * wr * w)
    phi = np.asarray(phi, float)
    H = np.vstack([(inv @ (phi[r][:, None] * phi.T)).T for r in refs])
    rng = np.random.default_rng(seed)
    noise = (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)
    H = H * (1 + noise_pct / 100 * noise)
    rows = pd.DataFrame([(p, d, dofs[r][0], dofs[r][1]) for r in refs for p, d in dofs],
                        columns=["point", "direction", "ref_point", "ref_direction"])
    return FrfSet(state=state, freq_Hz=f, H=H, rows=rows, source="synthetic modal model")


def frf_table(fs: FrfSet) -> pd.DataFrame:
    """The FRFs as frf.csv rows with a ``reference`` column (``state, point, direction, reference,
    freq_Hz, re, im``)."""
    n_f = fs.freq_Hz.size
    r = fs.rows
    return pd.DataFrame({
        "state": fs.state,
        "point": np.repeat(r["point"].to_numpy(), n_f),
        "direction": np.repeat(r["direction"].to_numpy(), n_f),
        "reference": np.repeat((r["ref_point"] + ":" + r["ref_direction"]).to_numpy(), n_f),
        "freq_Hz": np.tile(fs.freq_Hz, len(r)),
        "re": fs.H.real.ravel(), "im": fs.H.imag.ravel()})
