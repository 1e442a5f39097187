"""Thermal-error pipeline for CNC machine tools.

Raw campaign logs (``data/raw/<campaign>/``, see ``docs/data-contract.md``) are ingested, validated,
separated into geometric and thermal error, modelled and scored across seasons. Each DVC stage
is one module of this package with a ``main(argv)`` entry point, dispatched by :mod:`pipeline.cli`.
"""

__version__ = "0.1.0"
