"""jointid.data."""
