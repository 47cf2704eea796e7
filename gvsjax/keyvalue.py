"""The one ``key=value`` parser of the command lines and of ``PPOConfig`` overrides."""

from __future__ import annotations

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
