"""Helpers shared by the tests: real server processes on 127.0.0.1 (:mod:`.processes`), the
repository's params.yaml sections (:mod:`.repo_params`)."""
