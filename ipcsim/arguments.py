"""The checks of the arguments that the command line and the Python API share, written
once: ``ipcsim run --steps 1.5`` and ``ipcsim.run(spec, steps=1.5)`` are refused with the
same words, before anything is written. An :class:`ArgumentError` is an ``IpcsimError``
(exit status 2) and a ``ValueError``."""

from __future__ import annotations

import math
import numbers
import os

from .errors import ArgumentError, excerpt

__all__ = ["whole_number_at_least_1", "finite_number", "folder_path", "flag"]


def _shown(value) -> str:
    return f"'{excerpt(value)}'" if isinstance(value, str) else excerpt(repr(value))


def _number(value, kind: type, parse, expected: str):
    """``value`` read by ``parse``: a ``kind`` (not a bool), or its text as the command
    line gives it."""
    if isinstance(value, str):
        try:
            return parse(value)
        except ValueError:
            raise ArgumentError(f"expected {expected}, got {_shown(value)}") from None
    if isinstance(value, kind) and not isinstance(value, bool):
        return parse(value)
    raise ArgumentError(f"expected {expected}, got {_shown(value)}")


def whole_number_at_least_1(value) -> int:
    """A whole number >= 1: an int, or its text."""
    number = _number(value, numbers.Integral, int, "a whole number")
    if number < 1:
        raise ArgumentError(f"must be at least 1, got {number}")
    return number


def finite_number(value) -> float:
    """A finite number: a float or an int, or its text."""
    number = _number(value, numbers.Real, float, "a number")
    if not math.isfinite(number):
        raise ArgumentError(f"must be a finite number, got {value}")
    return number


def folder_path(value, name: str):
    """``value`` if it can name a folder (a str or an os.PathLike of one, not empty)."""
    if isinstance(value, os.PathLike):
        text = os.fspath(value)
    else:
        text = value
    if not isinstance(text, str) or not text:
        raise ArgumentError(f"{name} must be a folder path (a str or a pathlib.Path), got "
                            f"{_shown(value)}")
    return value


def flag(value, name: str) -> bool:
    if not isinstance(value, bool):
        raise ArgumentError(f"{name} must be True or False, got {_shown(value)}")
    return value
