"""jointid.correlate.pairing."""
