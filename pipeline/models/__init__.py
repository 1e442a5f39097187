"""Candidate thermal-error models; :mod:`pipeline.models.registry` looks them up by name.

The package does not import the registry itself: a stage that needs one model (e.g. the linear
axes' composite) does not pay for importing every model's library.
"""
