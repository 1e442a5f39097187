"""Errors the user fixes: the ``thermal`` command prints their message, without a traceback.

A stage raises one of these for a problem of its inputs -- data, ``params.yaml``, a stage not run
yet -- with a message that says what is wrong and what to do. Each also derives from the built-in
error it replaces, so callers that catch ``ValueError`` / ``FileNotFoundError`` / ``KeyError``
keep working. Any other exception is an internal error and keeps its traceback.
"""

from __future__ import annotations


class UserError(Exception):
    """A problem of the stage's inputs that the user fixes; the message says how."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class MissingInputError(UserError, FileNotFoundError):
    """An input file or folder is missing (e.g. the stage before was not run)."""


class InputDataError(UserError, ValueError):
    """The input data cannot be used as they are (e.g. no training campaign)."""


class ParamsError(UserError, KeyError, ValueError):
    """``params.yaml`` is missing, unreadable, or a section or value is wrong."""


class ClusterUnreachableError(UserError, ConnectionError):
    """The Dask scheduler the environment names does not answer."""
