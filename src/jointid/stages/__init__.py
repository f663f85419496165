"""Workflow stages: one module per rule family (read inputs, call the package, write outputs); runner: the Snakemake glue."""
