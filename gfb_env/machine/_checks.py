"""Validation helpers of the machine components (one clear ``ValueError`` naming the field).

They live here, not in :mod:`gfb_env.envs.config`, because the machine sits below the envs in the
layers (``integrator -> machine -> envs``) and must not import the env package."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T")


def is_number(v: Any) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating))


def nonnegative(name: str, v: Any, *, allow_inf: bool = False) -> float:
    """``v`` as a float >= 0 (``inf`` only when ``allow_inf``)."""
    ok = is_number(v) and not math.isnan(v) and v >= 0 and (allow_inf or math.isfinite(v))
    if not ok:
        what = "a non-negative number or inf" if allow_inf else "a finite non-negative number"
        raise ValueError(f"{name} must be {what}, got {v!r}")
    return float(v)


def positive(name: str, v: Any, *, allow_inf: bool = False) -> float:
    """``v`` as a float > 0 (``inf`` only when ``allow_inf``)."""
    ok = is_number(v) and not math.isnan(v) and v > 0 and (allow_inf or math.isfinite(v))
    if not ok:
        what = "a positive number or inf" if allow_inf else "a finite positive number"
        raise ValueError(f"{name} must be {what}, got {v!r}")
    return float(v)


def finite(name: str, v: Any) -> float:
    if not (is_number(v) and math.isfinite(v)):
        raise ValueError(f"{name} must be a finite number, got {v!r}")
    return float(v)


def finite_pair(name: str, r: Any, *, positive_values: bool = False) -> tuple[float, float]:
    """A pair ``(low, high)`` of finite numbers with ``low <= high`` (and ``low > 0`` if asked)."""
    try:
        lo, hi = r
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair (low, high), got {r!r}") from None
    if not (is_number(lo) and is_number(hi) and math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise ValueError(f"{name} must be a finite pair with low <= high, got {r!r}")
    if positive_values and lo <= 0:
        raise ValueError(f"{name} must be positive, got {r!r}")
    return float(lo), float(hi)


def component(name: str, cls: type[T], v: Any) -> T:
    """``v`` if it is a ``cls``, ``cls(**v)`` for a mapping (``gym.make`` keyword dicts), else an error."""
    if isinstance(v, cls):
        return v
    if isinstance(v, Mapping):
        try:
            return cls(**v)
        except TypeError as e:
            raise ValueError(f"{name}: {e}") from None
    raise ValueError(f"{name} must be a {cls.__name__} or a dict of its fields, got {type(v).__name__}")
