"""Candidate thermal-error models, looked up by name from ``params.yaml``."""

from pipeline.models.registry import MODELS, make_model

__all__ = ["MODELS", "make_model"]
