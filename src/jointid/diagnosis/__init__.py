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
page, outputs, history
    The report page (figures, jinja2 template), the result files, the run history CSV.
synth
    Synthetic datasets with hidden effects (to prove the diagnosis).
__main__
    The command line ``python -m jointid.diagnosis``.
"""

from jointid.diagnosis.history import append_history, history_row
from jointid.diagnosis.loop import Diagnosis, diagnose
from jointid.diagnosis.outputs import write_outputs
from jointid.diagnosis.variants import StateData, dataset_states

__all__ = ["Diagnosis", "StateData", "append_history", "dataset_states", "diagnose", "history_row",
           "write_outputs"]
