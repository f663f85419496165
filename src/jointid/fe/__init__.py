"""jointid.fe."""
