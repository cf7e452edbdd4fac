"""Checks of arguments shared across the package: each names the argument
and what was expected, as every public function's errors do."""

from __future__ import annotations

from typing import Any, Tuple

import numpy as np

__all__ = ["option_error", "check_int", "check_seed", "float_tuple", "int_triple", "is_number"]


def option_error(option: str, detail: str, kind: type = ValueError) -> Exception:
    """An exception of ``kind`` whose message is ``"option: detail"``, that
    carries ``option`` and ``detail`` as attributes: so that a caller (the
    command line) can name the option its own way without reading the
    message."""
    error = kind(f"{option}: {detail}")
    error.option, error.detail = option, detail
    return error


def is_number(value: Any) -> bool:
    """A real number (int or float, numpy's included), not a bool or a string."""
    return not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating))


def check_int(name: str, value: Any) -> int:
    """``value`` as an int; TypeError naming ``name`` if it is not an integer (a bool is not)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name}: expected an int, got {type(value).__name__}")
    return int(value)


def check_seed(name: str, value: Any) -> int:
    """A seed: an integer in [0, 2**64)."""
    value = check_int(name, value)
    if not 0 <= value < 2**64:
        raise ValueError(f"{name}: expected an integer in [0, 2**64), got {value}")
    return value


def float_tuple(name: str, value: Any, length: int) -> tuple:
    """``value``, a sequence of ``length`` numbers, as a tuple of floats."""
    try:
        items = tuple(value)
    except TypeError:
        raise TypeError(f"{name}: expected a sequence of {length} numbers, got {type(value).__name__}") from None
    if len(items) != length:
        raise ValueError(f"{name}: expected {length} numbers, got {len(items)}")
    out = []
    for v in items:
        if not is_number(v):
            raise TypeError(f"{name}: expected numbers, got {type(v).__name__}")
        out.append(float(v))
    return tuple(out)


def int_triple(name: str, value: Any) -> Tuple[int, int, int]:
    """``value``, three integers (frames, rows, columns), as a tuple of ints."""
    try:
        items = tuple(value)
    except TypeError:
        raise TypeError(f"{name}: expected three integers, got {type(value).__name__}") from None
    if len(items) != 3 or any(isinstance(v, bool) or not isinstance(v, (int, np.integer)) for v in items):
        raise ValueError(f"{name}: expected three integers, got {value!r}")
    return tuple(int(v) for v in items)  # type: ignore[return-value]
