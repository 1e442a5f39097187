"""Typed ``params.yaml``: one pydantic model per section, checked at the start of a stage.

:mod:`~pipeline.settings.base` holds the loader (:func:`~pipeline.settings.base.load_settings`)
and the wording of what is wrong; each section's model is a module of its own (``ingest``,
``validate``, ``separate``, ``protocol``, ``select``, ``model_axis``, ``evaluate``,
``compensation``, ``discrepancy``, ``tracking``, ``track``), so that a stage depends on the models
of the sections it reads only.
"""
