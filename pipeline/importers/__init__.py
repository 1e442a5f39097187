"""Converters from instrument and logger exports to the raw campaign contract."""
