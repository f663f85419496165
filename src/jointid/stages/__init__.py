"""Workflow stages: one module per rule family (read inputs, call the package, write outputs);
:mod:`jointid.stages.runner` is the glue to the Snakemake scripts."""
