"""Rule ema: a named FRF source (``ema.sources.<name>``) -> the dataset folder ``results/ema/<name>/dataset``
and the EMA's report (poles.csv, stabilisation chart, synthesised FRFs) in ``results/ema/<name>/report``.

Not in the paper's chain: the rule runs only for the sources named in the config.  Its dataset is read by
the rest of the chain like any other (``measurements.dataset: results/ema/<name>/dataset`` in a second
run, or ``jointid data ema`` beforehand: the datasets are checked when the Snakefile is parsed).
"""

from __future__ import annotations

from pathlib import Path

from typing import TYPE_CHECKING

from jointid.ema.run import run_ema
from jointid.progress import stamp

if TYPE_CHECKING:
    from jointid.ema.options import EmaOptions



def run_ema_stage(options: EmaOptions, source, out_dataset, out_poles) -> None:
    """EMA of ``source`` with the criteria ``options`` (``EmaOptions.from_section(cfg.get("ema"))``): the dataset
    folder ``out_dataset``, and ``out_poles`` (poles.csv) with the figures beside it."""
    run_ema(source, out_dataset, report=Path(out_poles).parent, options=options,
            log=lambda m: print(stamp(m), flush=True))
