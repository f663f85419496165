"""jointid.reporting."""
