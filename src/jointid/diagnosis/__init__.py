"""jointid.diagnosis."""
