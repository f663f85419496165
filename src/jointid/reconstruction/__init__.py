"""Reconstruction hypotheses of the test rig: each fitted to the measured states, ranked by QAICc,
with the measurement that would best narrow them (docs/reconstruction.md, "Hypotheses")."""
