"""Helpers shared by the tests (and the benchmarks that run the pipeline in a copy).

- :mod:`.repository`: a throw-away copy of the repository as a git repository;
- :mod:`.processes`, :mod:`.mlflow_server`, :mod:`.s3_server`, :mod:`.opcua_controller`: real
  servers on 127.0.0.1, started and always stopped;
- :mod:`.raw_builders`, :mod:`.raw_edits`: raw campaign folders written or damaged on purpose;
- :mod:`.repo_params`: the repository's ``params.yaml`` sections;
- :mod:`.score_rows`: rows of the cross-season score table;
- :mod:`.twin_measured`, :mod:`.twin_cases`: twin campaigns as measurements, calibrated twins;
- :mod:`.compensation_bundle`: a small compensation bundle for the runtime tests.
"""
