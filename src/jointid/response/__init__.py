"""jointid.response."""
