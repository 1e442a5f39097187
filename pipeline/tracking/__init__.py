"""Library code of the ``track`` stage: run identity, run records and the MLflow writer.

- :mod:`pipeline.tracking.identity` hashes code, params, raw data and evaluate outputs into the
  run identity and collects the provenance tags (git commit, ``dvc.lock`` hashes, synthetic flag).
- :mod:`pipeline.tracking.records` turns the evaluate outputs into one parent and one child
  :class:`~pipeline.tracking.records.RunRecord` per (model, selection, train campaign); pure.
- :mod:`pipeline.tracking.store` writes records to MLflow in batches (the only module that
  imports :mod:`mlflow`).
"""
