"""An FRF source of any kind -> FRFs per state: :func:`load_frfs` picks the reader by what the path is."""

from __future__ import annotations

from pathlib import Path

from jointid.ema.frfs import FrfSet, read_frf_csv, read_frf_folder, read_frf_uff
from jointid.ema.timedata import h1_frfs, read_time_csv
from jointid.errors import DataError

__all__ = ["load_frfs"]


def load_frfs(source, *, state: str = "measured", coherence_min: float = 0.9, max_low_fraction: float = 0.2,
              measuring_points=None, log=print) -> tuple[dict[str, FrfSet], dict]:
    # many parameters: the source, a UFF file's state name, the time data's coherence rule, log
    """FRFs of ``source`` (a dataset folder, a frf.csv, a time-history CSV, or a .uff/.unv file) and the
    conditions it carries (a dataset folder's conditions.yaml, else empty).  A CSV with a ``time_s``
    column holds hammer time histories: they become H1 FRFs (:mod:`jointid.ema.timedata`).  A UFF file's
    nodes are mapped to ``measuring_points`` when given (:func:`jointid.ema.frfs.read_frf_uff`)."""
    source = Path(source)
    if source.is_dir():
        return read_frf_folder(source)
    if not source.exists():
        raise DataError(f"{source}: FRF source does not exist — give a frf.csv, a UFF file or a dataset folder")
    if source.suffix.lower() == ".csv":
        with open(source, encoding="utf-8-sig") as fh:
            header = fh.readline()
        if "time_s" in [c.strip() for c in header.split(",")]:
            fs = h1_frfs(read_time_csv(source), state=state, source=source.name, coherence_min=coherence_min,
                         max_low_fraction=max_low_fraction, log=log)
            return {state: fs}, {}
        return read_frf_csv(source), {}
    if source.suffix.lower() in (".uff", ".unv"):
        return (read_frf_uff(source, state=state, measuring_points=measuring_points),
                {"frequencies_in_Hz_confirmed": True})
    raise DataError(f"{source}: unknown FRF file type {source.suffix!r} — give a .csv, .uff or .unv file")
