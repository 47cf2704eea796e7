"""The one ``key=value`` parser of the command lines and of the algorithms' config overrides, and
the typed-config pieces ``PPOConfig`` and ``SACConfig`` share."""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Callable, Iterable, Mapping
from typing import Any

_TRUE, _FALSE = ("1", "true", "yes", "on"), ("0", "false", "no", "off")


def parse_bool(text: str) -> bool:
    lowered = text.strip().lower()
    if lowered in _TRUE:
        return True
    if lowered in _FALSE:
        return False
    raise ValueError(text)


def parse_int(text: str) -> int:
    """An int; "1e5" is accepted when it is a whole number."""
    try:
        return int(text)
    except ValueError:
        as_float = float(text)
        if not as_float.is_integer():
            raise
        return int(as_float)


def typed(default: Any) -> Callable[[str], Any]:
    """A parser of text into the type of ``default`` (bool, int, float or str)."""
    if isinstance(default, bool):
        return parse_bool
    if isinstance(default, int):
        return parse_int
    if isinstance(default, float):
        return float
    return str


def parse(argv: Iterable[str], options: Mapping[str, Callable[[str], Any]]) -> dict[str, Any]:
    """``["key=value", ...]`` -> ``{key: options[key](value)}``.

    A word without ``=``, an unknown key or a value its parser rejects raises
    ``ValueError`` naming the word and the valid keys (or the expected type).
    """
    out: dict[str, Any] = {}
    for item in argv:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep:
            raise ValueError(f"argument {item!r} is not of the form key=value (see --help)")
        if key not in options:
            raise ValueError(f"unknown key {key!r}; valid keys: {sorted(options)}")
        try:
            out[key] = options[key](text.strip())
        except ValueError as e:
            detail = str(e)
            if detail.startswith(f"{key}="):  # the parser named the key itself
                raise
            kind = getattr(options[key], "__name__", "value").replace("parse_", "")
            raise ValueError(f"{key}={text!r} is invalid; expected {kind}") from None
    return out


# ----------------------------------------------------------------------------- typed configs
# The algorithms' configs (``PPOConfig``, ``SACConfig``) are frozen dataclasses of bool, int, float,
# str and tuple-of-int fields, each with a help text; these are their shared pieces.


def field(default: Any, help: str) -> Any:
    """A dataclass field with its one-line ``help`` (what ``--help`` prints)."""
    return dataclasses.field(default=default, metadata={"help": help})


def field_docs(cls: type) -> dict[str, str]:
    """Each field's help text, by name."""
    return {f.name: f.metadata["help"] for f in dataclasses.fields(cls)}


def type_name(typ: Any) -> str:
    return typ.__name__ if typ in (bool, int, float, str) else "tuple of int"


def coerce(name: str, typ: Any, value: Any) -> Any:
    """Check ``value`` has the field's type; widen int->float and list->tuple."""
    if typ is bool:
        ok = isinstance(value, bool)
    elif typ is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif typ is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        value = float(value) if ok else value
    elif typ is str:
        ok = isinstance(value, str)
    else:  # tuple[int, ...]
        ok = isinstance(value, (tuple, list))
        value = tuple(value) if ok else value
    if not ok:
        raise ValueError(f"{name}={value!r} is invalid; expected type {type_name(typ)}")
    return value


def validate(config: Any, checks: Mapping[str, tuple[Callable[[Any], bool], str]]) -> None:
    """Coerce every field of the frozen dataclass ``config`` in place, then apply ``checks``
    (field -> (predicate, allowed range)): a ValueError names the field, its value and the range."""
    hints = typing.get_type_hints(type(config))
    for f in dataclasses.fields(config):
        object.__setattr__(config, f.name, coerce(f.name, hints[f.name], getattr(config, f.name)))
    for name, (ok, allowed) in checks.items():
        value = getattr(config, name)
        if not ok(value):
            raise ValueError(f"{name}={value!r} is invalid; allowed: {allowed}")


def parse_field(cls: type, name: str, text: str) -> Any:
    """Parse ``text`` to the type of field ``name`` of ``cls`` (no range checks)."""
    typ = typing.get_type_hints(cls)[name]
    text = text.strip()
    try:
        if typ in (bool, int, float, str):
            return typed(typ())(text)
        return tuple(parse_int(t) for t in text.strip("()[]").split(",") if t.strip())
    except ValueError:
        raise ValueError(f"{name}={text!r} is invalid; expected {type_name(typ)}"
                         + (" (e.g. 128,32,16)" if typ not in (bool, int, float, str) else "")) from None


def describe_fields(config: Any) -> str:
    """One line per field, ``key=value  help``, for a command line's ``--help``."""
    lines = []
    for name, doc in field_docs(type(config)).items():
        value = getattr(config, name)
        shown = ",".join(map(str, value)) if isinstance(value, tuple) else value
        lines.append(f"  {name}={shown}".ljust(34) + f"  {doc}")
    return "\n".join(lines)
