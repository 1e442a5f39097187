"""The DVC stages, one module per ``dvc.yaml`` stage and with its name.

Each stage reads its inputs (paths from :mod:`pipeline.paths`, its ``params.yaml`` section),
calls the library packages and writes its outputs; ``thermal <stage>`` runs it. Library code
never imports a stage (``tests/test_architecture.py``).
"""
