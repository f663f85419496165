"""The files of a dataset folder (docs/measurement-format.md), in a module of its own: light (no pandas), for
the readers (:mod:`jointid.data.dataset`) and for a Snakemake start's check of a folder (:mod:`jointid.data.checked`)."""

DATASET_FILES = ("modes.csv", "shapes.csv", "frf.csv", "conditions.yaml", "README.md")
"""What a dataset folder holds; the readers read the first four."""
