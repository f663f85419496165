"""jointid.identification."""
