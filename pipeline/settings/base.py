"""The base of every settings model, its loader and the wording of what is wrong.

A section of ``params.yaml`` is read (:func:`pipeline.config.load_section`) and checked against
its model by :func:`load_settings` at the start of a stage. Whatever is wrong -- a key the model
does not have (a misspelt one), a value of the wrong type or out of range, a required key left
out -- stops the stage with one :class:`~pipeline.errors.ParamsError` that names, per problem,
the file and the full key path (``params.yaml: select.methdos``,
``params.yaml: evaluate.candidates.mlr[1]``), what is wrong and, for an unknown key, the keys
allowed at that level and the closest of them. The raw files checked on models of their own
(``campaign.yaml``, the importer's mapping file) word their problems from :func:`problems`.
"""

from __future__ import annotations

import difflib
import inspect
import types
import typing
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ConfigDict, ValidationError
from pydantic.fields import FieldInfo

from pipeline.config import DEFAULT_PARAMS, load_section
from pipeline.errors import ParamsError

UNKNOWN, MISSING, INVALID = "unknown", "missing", "invalid"
"""The kinds of :class:`Problem`."""

MAX_VALUE_TEXT = 60
"""Characters of a wrong value quoted in a message; longer ones are cut."""


class Settings(BaseModel):
    """Base of the settings models: an unknown key is an error, numbers are finite, frozen."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


SettingsModel = TypeVar("SettingsModel", bound=BaseModel)


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a settings file.

    Attributes
    ----------
    path : tuple of str or int
        Keys from the top of the checked mapping down to the wrong one; an int is a position in
        a list.
    kind : str
        :data:`UNKNOWN` (a key the model does not have), :data:`MISSING` (a required key left
        out) or :data:`INVALID` (a value of the wrong type or out of range).
    text : str
        What is wrong: for an unknown key the keys allowed at its level (and the closest one),
        for a wrong value what it should be.
    value : object
        The value found (None for a missing key).
    code : str
        pydantic's error type (``literal_error``, ``greater_than_equal``, ...), for a caller
        that words the problem itself.
    context : dict
        pydantic's error context (the bound of a range: ``ge``, ``gt``, ...).
    """

    path: tuple[str | int, ...]
    kind: str
    text: str
    value: Any = None
    code: str = ""
    context: Mapping[str, Any] = field(default_factory=dict)

    def where(self, root: str = "") -> str:
        """Return the key path, e.g. ``evaluate.candidates.mlr[1]`` for ``root`` "evaluate"."""
        return key_path(self.path, root)

    def line(self, root: str = "") -> str:
        """Return the problem in one line: key path, the value for a wrong one, what is wrong."""
        if self.kind == INVALID:
            return f"{self.where(root)} = {quote(self.value)}; {self.text}"
        return f"{self.where(root)}: {self.text}"


def key_path(parts: Iterable[str | int], root: str = "") -> str:
    """Return ``root.a.b[2].c`` for the parts ``("a", "b", 2, "c")``."""
    text = root
    for part in parts:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += f".{part}" if text else str(part)
    return text


def quote(value: Any) -> str:
    """Return ``repr(value)``, cut to :data:`MAX_VALUE_TEXT` characters."""
    text = repr(value)
    return text if len(text) <= MAX_VALUE_TEXT else text[: MAX_VALUE_TEXT - 3] + "..."


def unknown_key_text(
    key: object, allowed: Iterable[str], noun: str = "key", what: str = "allowed here"
) -> str:
    """Return "unknown key (did you mean 'x'?); allowed here: a, b, x" for a key not allowed.

    Parameters
    ----------
    key : object
        The key (or name) found.
    allowed : iterable of str
        The keys allowed at its level.
    noun : str
        What was found, e.g. ``key`` or ``model``.
    what : str
        What the allowed keys are, e.g. ``allowed here`` or ``registered models``.
    """
    allowed = list(allowed)
    close = closest(str(key), allowed)
    hint = f" (did you mean '{close}'?)" if close else ""
    return f"unknown {noun}{hint}; {what}: {', '.join(allowed) if allowed else 'none'}"


def closest(
    key: str, allowed: Iterable[str], cutoff: float = 0.6, shortening: bool = True
) -> str | None:
    """Return the allowed key ``key`` is most likely a misspelling or a shortening of, if any.

    Parameters
    ----------
    key : str
    allowed : iterable of str
    cutoff : float
        Least similarity (:class:`difflib.SequenceMatcher` ratio, 0 to 1) of a misspelling.
    shortening : bool
        Also take ``key`` for the one allowed key that starts with it (``buffer`` for
        ``buffer_campaigns``).
    """
    allowed = list(allowed)
    close = difflib.get_close_matches(key, allowed, n=1, cutoff=cutoff)
    if close:
        return close[0]
    longer = [name for name in allowed if shortening and key and name.startswith(key)]
    return longer[0] if len(longer) == 1 else None


def problems(error: ValidationError, model: type[BaseModel]) -> list[Problem]:
    """Return what a validation error of ``model`` says, one :class:`Problem` per wrong key."""
    found = []
    for item in error.errors(include_url=False):
        path, code, context = tuple(item["loc"]), item["type"], item.get("ctx") or {}
        if code == "extra_forbidden":
            allowed = allowed_keys(model, path[:-1])
            text = unknown_key_text(path[-1], allowed)
            found.append(Problem(path, UNKNOWN, text, item.get("input"), code, context))
        elif code == "missing":
            found.append(Problem(path, MISSING, "missing; add it", None, code, context))
        else:
            found.append(Problem(path, INVALID, _reason(item), item.get("input"), code, context))
    return found


def _reason(item: Mapping[str, Any]) -> str:
    """Return a validation error's message, the text of a validator's own ValueError as is."""
    if item["type"] == "value_error":
        return str(item["ctx"]["error"])
    message = str(item["msg"])
    return message[:1].lower() + message[1:]


def allowed_keys(model: type[BaseModel], path: tuple[str | int, ...]) -> list[str]:
    """Return the keys the model allows in the mapping at ``path`` (empty if not a model)."""
    node: Any = model
    for part in path:
        node = _child(node, part)
    found = _model_in(node)
    return [] if found is None else list(found.model_fields)


def choices(model: type[BaseModel], path: tuple[str | int, ...]) -> tuple[Any, ...]:
    """Return the values a ``Literal`` at ``path`` allows (empty if it is not one)."""
    node: Any = model
    for part in path:
        node = _child(node, part)
    for member in _members(node):
        if typing.get_origin(member) is typing.Literal:
            return typing.get_args(member)
    return ()


def described(model: type[BaseModel], path: tuple[str | int, ...]) -> str | None:
    """Return the description of the value at ``path``: its field's, or its ``Annotated`` one's."""
    parent: Any = model
    for part in path[:-1]:
        parent = _child(parent, part)
    found = _model_in(parent)
    if found is not None:
        info = found.model_fields.get(path[-1]) if path and isinstance(path[-1], str) else None
        return None if info is None else info.description
    node = _child(parent, path[-1]) if path else None
    if typing.get_origin(node) is typing.Annotated:
        for meta in typing.get_args(node)[1:]:
            if isinstance(meta, FieldInfo) and meta.description:
                return meta.description
    return None


def _members(node: Any) -> list[Any]:
    """Return the types an annotation stands for: ``Annotated`` unwrapped, a union split."""
    origin = typing.get_origin(node)
    if origin is typing.Annotated:
        return _members(typing.get_args(node)[0])
    if origin in (typing.Union, types.UnionType):
        return [member for arg in typing.get_args(node) for member in _members(arg)]
    return [node]


def _model_in(node: Any) -> type[BaseModel] | None:
    for member in _members(node):
        if inspect.isclass(member) and issubclass(member, BaseModel):
            return member
    return None


def _child(node: Any, part: str | int) -> Any:
    """Return the annotation of the value at ``part`` below one annotated ``node`` (or None)."""
    model = _model_in(node)
    if model is not None:
        info = model.model_fields.get(part) if isinstance(part, str) else None
        return None if info is None else info.annotation
    for member in _members(node):
        origin, args = typing.get_origin(member), typing.get_args(member)
        if origin is dict and args:
            return args[1]
        if origin in (list, tuple) and args and isinstance(part, int):
            return args[0]
    return None


def parse_section(
    model: type[SettingsModel],
    section: str,
    content: Mapping[str, Any] | None,
    source: Path | str = DEFAULT_PARAMS,
) -> SettingsModel:
    """Check one section's mapping against its model.

    Parameters
    ----------
    model : type
        The section's settings model.
    section : str
        The section's key, the root of every key path in a message.
    content : mapping or None
        The section as read (None: empty).
    source : Path or str
        The file it was read from, for the message.

    Returns
    -------
    Settings
        The section, typed, with the model's defaults for the keys not given.

    Raises
    ------
    ParamsError
        One line per problem: ``<source>: <section>.<key path> ...`` (see :func:`problems`).
    """
    try:
        return model.model_validate(dict(content or {}))
    except ValidationError as error:
        lines = [f"{source}: {p.line(section)}" for p in problems(error, model)]
        raise ParamsError("\n".join(lines)) from None


def load_settings(
    model: type[SettingsModel], section: str, params_path: Path | str = DEFAULT_PARAMS
) -> SettingsModel:
    """Read ``section`` of the params file and check it against ``model``.

    Raises
    ------
    ParamsError
        If the file or the section is missing or unreadable (:func:`pipeline.config.load_section`)
        or anything in the section is wrong (:func:`parse_section`).
    """
    return parse_section(model, section, load_section(section, params_path), params_path)


def unknown_name_error(
    path: Iterable[str | int], name: object, allowed: Iterable[str], noun: str, what: str
) -> ParamsError:
    """Return the error of a name a registry of the library does not have.

    For the keys and values whose allowed names live in a registry (a model, a selection
    method, an effect), checked by the code that owns the registry.

    Parameters
    ----------
    path : iterable of str or int
        Key path of the name, from the section down (``("evaluate", "candidates", "mrl")``).
    name : object
        The name found.
    allowed : iterable of str
        The registry's names.
    noun, what : str
        What the name is (``model``) and what the registry's names are (``registered models``).
    """
    text = unknown_key_text(name, allowed, noun, what)
    return ParamsError(f"{DEFAULT_PARAMS}: {key_path(path)}: {text}")
