"""Converters from measuring instruments' exports to raw campaign folders (data-contract.md)."""
