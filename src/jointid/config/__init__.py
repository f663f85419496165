"""jointid.config.core."""
