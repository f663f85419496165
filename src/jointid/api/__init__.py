"""The public Python API of jointid: a :class:`Study` and its typed results.

``from jointid import Study`` (the names are re-exported by the package).

Study
    :meth:`Study.from_config` loads and validates a configuration; :meth:`Study.model` is its FE
    model; :meth:`Study.modes` solves it at joint parameters (:class:`ModalResult`);
    :meth:`Study.compare` tabulates it against a measured dataset (folder or UFF file);
    :meth:`Study.identify` fits the joint parameters to one state (:class:`Identification`, the FE polish
    alone); :meth:`Study.run_method` runs the whole method (DOE, surfaces, polish, verification: Tables 2-3,
    :class:`MethodResult`);
    :meth:`Study.diagnose` says which physical effect the model lacks (:class:`DiagnosisResult`).
load_dataset
    A measured dataset folder or UFF file, checked against a study's measuring points.

Modules: :mod:`jointid.api.study` (the class), :mod:`jointid.api.results` (the frozen dataclasses),
:mod:`jointid.api.measured` (datasets and result records).  Runnable examples: ``docs/examples/``.
"""

from __future__ import annotations

from jointid.api.results import DiagnosisResult, Identification, MethodResult, ModalResult
from jointid.api.study import Study

__all__ = ["DiagnosisResult", "Identification", "MethodResult", "ModalResult", "Study", "load_dataset"]


def load_dataset(source, study: Study, *, state: str = "power_off", em_force_N: float | None = None):
    """A measured dataset (:class:`jointid.data.dataset.Dataset`) from a folder or a ``.uff``/``.unv``
    file, checked against (folder) or mapped onto (UFF) ``study``'s measuring points; the same as
    ``study.dataset(source, state=state, em_force_N=em_force_N)``."""
    return study.dataset(source, state=state, em_force_N=em_force_N)
