"""Command line of the EMA: ``jointid data ema FRF.uff|frf.csv|DATASET --out DATASET/``.

Reads measured FRFs (frf.csv with a reference per FRF, UFF 58, or a dataset folder with frf.csv), extracts
the modes (LSCF over orders, stable poles, refined poles, LSFD shapes, per-mode uncertainties) and writes a
dataset folder, with poles.csv and the stabilisation chart and FRF figures in ``--report`` (default
``<out>_ema``).  Progress goes to stdout; a problem is one line per cause on stderr, exit status 1, and
no dataset is written.
"""

from __future__ import annotations

import argparse
import sys

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 written, 1 problems, 2 usage)."""
    ap = argparse.ArgumentParser(prog="jointid data ema", description=__doc__.split("\n\n")[0])
    ap.add_argument("source", help="frf.csv (receptance, m/N, with a reference column), a UFF file with "
                    "dataset 58, or a dataset folder holding frf.csv")
    ap.add_argument("--out", required=True, help="dataset folder to write")
    ap.add_argument("--report", help="folder for poles.csv and the figures (default <out>_ema)")
    ap.add_argument("--state", default="measured", help="state name of a UFF file's FRFs (default measured)")
    ap.add_argument("--config", help="config.yaml whose ema: section sets the criteria (default: the schema's)")
    ap.add_argument("--band-Hz", nargs=2, type=float, metavar=("LOW", "HIGH"), help="analysis band in Hz")
    ap.add_argument("--max-order", type=int, help="highest LSCF model order")
    ap.add_argument("--bootstrap", type=int, help="bootstrap replicates over response rows")
    ap.add_argument("--points", help="measuring_points.csv of the model (checks point names; maps UFF nodes to points)")
    ap.add_argument("--em-force-N", type=float, help="motor attraction of every state (default 0 or the source's)")
    args = ap.parse_args(argv)
    from jointid.errors import JointidError  # noqa: PLC0415  (heavy imports after the arguments parse)
    from jointid.progress import stamp  # noqa: PLC0415

    try:
        import pandas as pd  # noqa: PLC0415

        from jointid.ema.options import EmaOptions  # noqa: PLC0415
        from jointid.ema.run import run_ema  # noqa: PLC0415

        section = None
        if args.config:
            from jointid.config import load_config  # noqa: PLC0415

            section = load_config(args.config).get("ema")
        overrides = {k: v for k, v in (("band_Hz", args.band_Hz), ("max_order", args.max_order),
                                       ("n_bootstrap", args.bootstrap)) if v is not None}
        options = EmaOptions.from_section(section, **overrides)
        points = pd.read_csv(args.points) if args.points else None
        run_ema(args.source, args.out, report=args.report, options=options, state=args.state,
                measuring_points=points, em_force_N=args.em_force_N, log=lambda m: print(stamp(m), flush=True))
    except JointidError as exc:
        print(str(exc), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
