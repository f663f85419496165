"""Which physical effect does the model lack?  The diagnosis (docs/effects.md).

Modules
-------
effects
    The library of candidate effects and the affine system of model terms they act on.
variants
    Measured states (:class:`StateData`, :func:`dataset_states`) and model variants.
fitting
    Evaluating and fitting variants with the reduced solver (:class:`Diagnoser`, :class:`Fit`, refits).
statistics
    Score tests, between-state contrasts, identifiability, AICc.
tables
    Result tables: ladder rows, ranking, parameters, comparison, drift.
loop
    The driver :func:`diagnose` and its steps; the result :class:`Diagnosis`.
__main__
    The command line ``python -m jointid.diagnosis``.

Elsewhere: the diagnosis's page, result files and run history are in :mod:`jointid.reporting`
(``diagnosis_page``, ``diagnosis_outputs``, ``diagnosis_history``); the reconstruction hypotheses in
:mod:`jointid.reconstruction`; synthetic datasets with hidden effects in :mod:`jointid.synthetic`.
"""

import importlib

_EXPORTS = {"Diagnosis": "loop", "diagnose": "loop", "StateData": "variants", "dataset_states": "variants"}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    """The package's exports, imported when first asked for: importing one submodule (as the
    Snakefile's rules do) does not import the whole diagnosis and SciPy's statistics with it."""
    if name in _EXPORTS:
        return getattr(importlib.import_module(f"jointid.diagnosis.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module 'jointid.diagnosis' has no attribute {name!r}")
