"""jointid.geometry."""
