"""Experimental modal analysis: modal parameters from measured FRFs.

``frfs`` reads FRFs (frf.csv, UFF 58, a dataset folder) into :class:`~jointid.ema.frfs.FrfSet`;
``timedata`` makes H1 FRFs from hammer time histories; ``poles`` runs LSCF over model orders
(sdypy-EMA); ``stability`` selects the physical poles by their stability across orders;
``shapes`` fits the residues (LSFD) and makes real shapes; ``uncertainty`` bootstraps over
response rows; ``extract`` puts them together and writes a dataset folder; ``figures`` draws the
stabilisation chart and the synthesised FRFs.  See docs/measurement-format.md, "From FRFs: EMA".
"""
