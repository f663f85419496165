"""Synthetic datasets with a known truth: the FE model with chosen effects, solved and written in
the measurement format (docs/measurement-format.md), for known-truth tests and the coverage study."""
