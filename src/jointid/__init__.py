"""jointid: joint-surface stiffness and damping identification by FE model updating.

Python API
----------
``from jointid import Study``; runnable examples in ``docs/examples/`` (docs/architecture.md, "Python API").

Study
    One validated configuration and the engineer's procedure on it:

    * ``Study.from_config(["config.yaml", ...], overrides=None)`` - load, merge and validate;
      ``Study.default(overrides=None)`` - the shipped defaults (the paper's rig and data), no file;
    * ``.model()`` - the FE model of the rig (built once);
    * ``.modes(theta, n, state)`` - natural frequencies (Hz) and shapes at the measuring points
      at joint parameters ``theta`` (N/m^3) -> :class:`ModalResult`;
    * ``.compare(dataset, theta, state)`` - measured vs model Hz, error %, MAC (pandas table);
    * ``.identify(dataset, state)`` - the joint parameters fitted to one state's modes (the
      workflow's FE polish, a local search) -> :class:`Identification`;
    * ``.run_method()`` - the whole method on the configured states (DOE, response surfaces, multistart,
      FE polish, verification), through the workflow's stage functions: Tables 2-3 -> :class:`MethodResult`;
    * ``.diagnose(dataset)`` - which physical effect the model lacks -> :class:`DiagnosisResult`;
    * ``.dataset(path)`` - a measured dataset folder or UFF file; ``.synthetic_dataset(truth, folder)``.
ModalResult, Identification, MethodResult, DiagnosisResult
    The typed (frozen) results.
load_dataset
    A measured dataset for a study.

The whole workflow (DOE, response surfaces, identification, verification, report) runs with
``snakemake -j2``; see README.md and docs/workflow.md.

Conventions (used throughout the package)
-----------------------------------------
* SI units inside the code: N, m, kg, s, Hz.  Column names and config keys carry the unit.
* Global axes: X lateral (across the rails), Y vertical (normal to the rail top), Z feed (along the rails).
* Mode shapes are arrays shaped ``(n_dofs_or_locations, n_modes)``, mass-normalised where they come
  from the FE model; frequencies in Hz; damping as ratios of critical.
* DOF numbering of the FE model is scikit-fem's for a vector ``ElementVector``: interleaved
  ``(ux, uy, uz)`` per node, i.e. dof = 3 * node + component.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__all__ = ["DiagnosisResult", "Identification", "MethodResult", "ModalResult", "Study", "__version__", "load_dataset"]

_API = ("DiagnosisResult", "Identification", "MethodResult", "ModalResult", "Study", "load_dataset")

if TYPE_CHECKING:
    from jointid.api import DiagnosisResult, Identification, MethodResult, ModalResult, Study, load_dataset  # noqa: F401


def __getattr__(name: str):
    """The API names, imported on first use (PEP 562): ``import jointid.<module>`` in a workflow job
    stays as light as before, and the package's modules do not import the API through it."""
    if name in _API or name == "__version__":
        value = getattr(importlib.import_module("jointid.version" if name == "__version__" else "jointid.api"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'jointid' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_API, "__version__"})
