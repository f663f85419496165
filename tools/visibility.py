"""Which model modes would a given hammer test see?  Run in a finished run's folder:

    python tools/visibility.py results/identify/power_off/params.json --tap T05:y --tap T01:y

Solves the cached model (``results/model/matrices.npz``) at the identified parameters and prints,
for each tap (one or more ``<point>:<direction>`` joined by ``+``, e.g. ``T05:x+T05:y+T05:z``) and a
roving 3-axis sensor at every measuring point, the visibility of every mode in ``harmonic.band_Hz``
relative to the most visible one (:mod:`jointid.correlate.observability`).
"""
import argparse

import pandas as pd

from jointid.config import load_config
from jointid.config.typed import ModelSpec
from jointid.correlate.observability import MeasurementSetup, visibility
from jointid.fe.model import load_model
from jointid.geometry.points import dof_labels
from jointid.identification.polish import solve_point
from jointid.identification.record import IdentificationRecord


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("params", help="results/identify/<state>/params.json")
    ap.add_argument("--tap", action="append", default=None, help="hammer DOFs, e.g. T05:y or T05:x+T05:y")
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--matrices", default="results/model/matrices.npz")
    args = ap.parse_args()
    cfg = load_config(args.config)
    model = load_model(args.matrices)
    theta = IdentificationRecord.read(args.params).theta
    freqs, shapes, desc, _ = solve_point(ModelSpec.from_config(cfg), model, theta)
    labels = dof_labels(pd.DataFrame(model.meta["points"]))
    lo, hi = cfg["harmonic"]["band_Hz"]
    band = [i for i, f in enumerate(freqs) if lo <= f <= hi]
    table = {"freq_Hz": [round(float(freqs[i]), 1) for i in band],
             "description": [desc["description"][i] for i in band]}
    for tap in args.tap or ["T05:y"]:
        vis = visibility(shapes, freqs, labels, MeasurementSetup(tuple(tap.split("+")), tuple(labels)))
        top = max(vis[i] for i in band)
        table[tap] = [round(float(vis[i] / top), 3) for i in band]
    print(pd.DataFrame(table).to_string(index=False))


if __name__ == "__main__":
    main()
