"""jointid.stages.core."""
