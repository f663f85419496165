"""The default mesh's modes at the identified parameters, as the mesh check needs them.

Rule ``verify`` solves the default mesh at each state's identified parameters (the tables' full solve).
The mesh check (:mod:`jointid.stages.meshcheck`) needs the same solve: the frequencies, the shapes at the
measuring points and ``d ln f / d log10 theta`` of every mode.  It used to load the model and solve it again
(about 5 s a state on the default mesh).  Now verify keeps what the check needs in a small file
(``results/identify/<state>/optimum_modes.npz``, 20 kB on the default mesh), and the check reads it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jointid import io
from jointid.errors import ModelError

__all__ = ["OptimumModes", "optimum_modes"]


@dataclass(frozen=True, eq=False)
class OptimumModes:
    """The modes of the default mesh at the joint parameters ``theta_N_per_m3`` (named ``names``)."""

    names: tuple[str, ...]
    theta_N_per_m3: np.ndarray  # (n_params,)
    freqs_Hz: np.ndarray  # (n_modes,)
    shapes: np.ndarray  # (n_labels, n_modes): at the measuring points
    dlnf_dlog10theta: np.ndarray  # (n_modes, n_params): exact modal sensitivities
    n_dofs: int

    def write(self, path) -> None:
        io.write_npz(path, names=np.array(self.names), theta_N_per_m3=self.theta_N_per_m3, freqs_Hz=self.freqs_Hz,
                     shapes=self.shapes, dlnf_dlog10theta=self.dlnf_dlog10theta, n_dofs=np.array(self.n_dofs))

    @classmethod
    def read(cls, path) -> "OptimumModes":
        z = io.load_npz(path)
        return cls(tuple(str(n) for n in z["names"]), z["theta_N_per_m3"], z["freqs_Hz"], z["shapes"],
                   z["dlnf_dlog10theta"], int(z["n_dofs"]))

    def check_parameters(self, names, theta, path) -> None:
        """Raise :class:`ModelError` unless these modes were solved at ``theta`` of ``names`` (the identified
        parameters the caller holds): a file left from another identification is not used."""
        same = tuple(names) == self.names and np.array_equal(np.asarray(theta, float), self.theta_N_per_m3)
        if not same:
            raise ModelError(f"{path}: the modes were solved at other joint parameters than those of "
                             "params.json — rebuild them (snakemake -R verify)")


def optimum_modes(spec, model, names, theta, freqs_Hz, shapes, phi, lam) -> OptimumModes:
    """:class:`OptimumModes` of a solve of ``model`` (``spec``: its :class:`~jointid.config.typed.ModelSpec`) at
    ``theta`` (N/m^3, in the order of ``names``): mass-normalised ``phi`` with eigenvalues ``lam``."""
    from jointid.fe.model import joint_terms
    from jointid.identification.polish import log_jacobian

    theta = np.asarray(theta, float)
    jt = joint_terms(spec.joints, spec.mesh_file)
    terms = [{t: 1.0 for t in jt[n]} for n in names]
    J = log_jacobian(model.stiffness, phi, lam, terms, theta)
    return OptimumModes(tuple(names), theta, np.asarray(freqs_Hz, float), np.asarray(shapes, float), J,
                        int(model.n_dofs))
