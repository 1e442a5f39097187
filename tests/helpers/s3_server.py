"""Start a real S3-compatible server (``moto_server``) on 127.0.0.1 for tests, and always stop it.

Usage (in a test marked ``@pytest.mark.slow``)::

    from tests.helpers.s3_server import running_s3_server

    with running_s3_server(tmp_path, bucket="campaigns") as endpoint:  # "http://127.0.0.1:<port>"
        env = {**os.environ, **S3_CREDENTIALS}
        ...

The server is moto's standalone server (``moto[server]``), a separate process speaking the S3
HTTP API; it keeps its objects in memory. Its output goes to ``<tmp_path>/s3-server/s3.log``;
its process group is stopped as the MLflow server's is (:func:`stop_group`).
"""

from __future__ import annotations

import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import boto3
from botocore.client import BaseClient

from tests.helpers.processes import free_port, stop_group

S3_CREDENTIALS = {
    "AWS_ACCESS_KEY_ID": "testing",
    "AWS_SECRET_ACCESS_KEY": "testing",
    "AWS_DEFAULT_REGION": "us-east-1",
}
"""What a client sends the local server (moto accepts any key)."""


def s3_client(endpoint: str) -> BaseClient:
    """Return a boto3 S3 client of the local server at ``endpoint`` (:data:`S3_CREDENTIALS`)."""
    return boto3.client(
        "s3",
        endpoint_url=endpoint,
        aws_access_key_id=S3_CREDENTIALS["AWS_ACCESS_KEY_ID"],
        aws_secret_access_key=S3_CREDENTIALS["AWS_SECRET_ACCESS_KEY"],
        region_name=S3_CREDENTIALS["AWS_DEFAULT_REGION"],
    )


@contextmanager
def running_s3_server(tmp_path: Path, bucket: str, timeout_s: float = 60.0) -> Iterator[str]:
    """Run ``moto_server`` until the ``with`` block ends, with ``bucket`` created; yield its URL.

    Raises
    ------
    RuntimeError
        If the server exits or does not answer in time, with the end of its log.
    """
    folder = Path(tmp_path) / "s3-server"
    folder.mkdir(parents=True, exist_ok=True)
    port = free_port()
    endpoint = f"http://127.0.0.1:{port}"
    log = folder / "s3.log"
    command = [str(Path(sys.executable).parent / "moto_server"), "-H", "127.0.0.1", "-p", str(port)]
    with log.open("wb") as output:
        process = subprocess.Popen(  # noqa: S603
            command,
            cwd=folder,
            stdout=output,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
    try:
        _wait(endpoint, process, log, timeout_s)
        client = s3_client(endpoint)
        client.create_bucket(Bucket=bucket)
        yield endpoint
    finally:
        stop_group(process)


def _wait(endpoint: str, process: subprocess.Popen, log: Path, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise RuntimeError(f"moto_server exited: {log.read_text(errors='replace')[-2000:]}")
        try:
            urllib.request.urlopen(endpoint, timeout=2).close()  # noqa: S310 (127.0.0.1)
            return
        except (urllib.error.URLError, ConnectionError, TimeoutError):
            time.sleep(0.2)
    raise RuntimeError(f"moto_server not answering at {endpoint}: {log.read_text()[-2000:]}")
