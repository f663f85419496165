"""Test/analysis correlation, pure modal maths: the MAC (:mod:`jointid.correlate.mac`) and the pairing
of modes and their comparison tables (:mod:`jointid.correlate.pairing`)."""
