"""Experimental modal analysis: modal parameters from measured FRFs, each with a measured uncertainty.

- ``frfs``: FRFs (frf.csv, UFF 58, a dataset folder) as :class:`~jointid.ema.frfs.FrfSet`.
- ``timedata``: H1 FRFs from hammer time histories; ``sources``: picks the reader.
- ``poles``: LSCF over model orders (sdypy-EMA) and LSFD.
- ``stability``: the physical poles, stable across orders.
- ``refine``: each pole refitted locally, with its covariance.
- ``shapes``: real shapes from the residues; ``uncertainty``: the bootstrap over response rows.
- ``extract``: one state's EMA and the dataset tables; ``run``: writes the dataset folder and the report.
- ``figures``: the stabilisation chart and the synthesised FRFs; ``synthetic``: FRFs of a known modal model.

See docs/measurement-format.md, "From FRFs: EMA".
"""
