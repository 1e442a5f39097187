"""Start a real PostgreSQL server in a temporary folder for tests, and always stop it.

Usage (in a test marked ``@pytest.mark.slow``)::

    from tests.helpers.postgres_server import running_postgres, unavailable_reason

    if unavailable_reason() is not None:
        pytest.skip(unavailable_reason())
    with running_postgres(database="mlflow") as url:  # "postgresql://mlflow@127.0.0.1:<port>/mlflow"
        ...

The cluster is made by ``initdb`` (trust authentication, on 127.0.0.1 only) in a new folder of
the system's temporary folder and served by ``pg_ctl start`` on a free port; ``pg_ctl stop``
and the folder's removal end it. PostgreSQL refuses to run as root: under root the server's
commands run as the ``postgres`` account (Debian's packages make it), which owns the folder.
"""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from tests.helpers.processes import ServerError, free_port, log_tail

ROLE = "mlflow"
"""The superuser ``initdb`` makes, and the owner of the test's database."""
SERVER_ACCOUNT = "postgres"
"""The system account the server's commands run as under root."""


def unavailable_reason() -> str | None:
    """Return why no PostgreSQL server can be started here, or None when one can."""
    if postgres_binaries() is None:
        return "PostgreSQL's initdb and pg_ctl are absent (Debian's package: postgresql)"
    if os.geteuid() == 0:
        try:
            pwd.getpwnam(SERVER_ACCOUNT)
        except KeyError:
            return f"PostgreSQL refuses root and there is no {SERVER_ACCOUNT!r} account to run as"
    return None


def postgres_binaries() -> Path | None:
    """Return the folder of ``initdb``, ``pg_ctl`` and ``createdb``, or None where absent.

    ``initdb`` on the ``PATH``, else the newest of Debian's ``/usr/lib/postgresql/*/bin``.
    """
    found = shutil.which("initdb")
    if found:
        return Path(os.path.realpath(found)).parent
    folders = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"))
    return Path(folders[-1]).parent if folders else None


@contextmanager
def running_postgres(database: str = "mlflow", timeout_s: float = 60.0) -> Iterator[str]:
    """Run a PostgreSQL server with an empty ``database`` until the ``with`` block ends.

    Yields
    ------
    str
        Its SQLAlchemy URL, ``postgresql://mlflow@127.0.0.1:<port>/<database>``.

    Raises
    ------
    ServerError
        If no server can be started here (:func:`unavailable_reason`), or a command fails (with
        the end of the server's log).
    """
    reason = unavailable_reason()
    if reason is not None:
        raise ServerError(reason)
    binaries = postgres_binaries()
    folder = Path(tempfile.mkdtemp(prefix="thermal-tests-postgres-"))
    user = SERVER_ACCOUNT if os.geteuid() == 0 else None
    if user:
        shutil.chown(folder, user=user, group=user)
    port = free_port()
    data, log = folder / "data", folder / "server.log"

    def run(command: list[str]) -> None:
        result = subprocess.run(  # noqa: S603
            command, user=user, cwd=folder, capture_output=True, text=True, timeout=timeout_s
        )
        if result.returncode != 0:
            raise ServerError(
                f"{' '.join(command)} failed ({result.returncode}):\n{result.stdout}"
                f"{result.stderr}\nthe server's log ends with:\n{log_tail(log)}"
            )

    options = f"-p {port} -h 127.0.0.1 -k {folder}"
    initdb, pg_ctl, createdb = (str(binaries / tool) for tool in ("initdb", "pg_ctl", "createdb"))
    try:
        run([initdb, "-D", str(data), "-U", ROLE, "--auth=trust", "-E", "UTF8"])
        run([pg_ctl, "-D", str(data), "-o", options, "-l", str(log), "-w", "start"])
        try:
            run([createdb, "-h", "127.0.0.1", "-p", str(port), "-U", ROLE, database])
            yield f"postgresql://{ROLE}@127.0.0.1:{port}/{database}"
        finally:
            run([pg_ctl, "-D", str(data), "-m", "fast", "-w", "stop"])
    finally:
        shutil.rmtree(folder, ignore_errors=True)
