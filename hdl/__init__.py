"""Amaranth gateware of the correlator (the HDL issue)."""
