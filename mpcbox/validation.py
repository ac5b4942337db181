"""Argument checks shared by the public API; messages always name the argument.

A value of the wrong type raises :class:`~mpcbox.errors.InvalidTypeError` (also a
:class:`TypeError`), a value of the right type outside its range
:class:`~mpcbox.errors.InvalidArgumentError` (also a :class:`ValueError`).
"""

from __future__ import annotations

import functools
import inspect
import numbers
import re
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TypeVar

import numpy as np

from mpcbox.errors import InvalidArgumentError, InvalidTypeError, ShapeError, UnknownOptionError

F = TypeVar("F", bound=Callable[..., Any])


def as_array(name: str, value: object, shape: Sequence[int | None]) -> np.ndarray:
    """Convert ``value`` to a float64 array and check its shape.

    Args:
        name: Argument name used in error messages.
        value: Array-like input.
        shape: Expected shape; ``None`` entries match any size.

    Returns:
        A float64 array (a copy only when conversion needs one).

    Raises:
        ShapeError: If the number of dimensions or a fixed dimension differs.
        InvalidTypeError: If ``value`` is not numeric (a string, a mapping, ``None``, ...) or
            complex.
    """
    if value is None or isinstance(value, (str, bytes, Mapping)):
        raise InvalidTypeError(f"{name} must be a numeric array, got {type(value).__name__}")
    if np.iscomplexobj(value):  # float64 would drop the imaginary part with only a warning
        raise InvalidTypeError(f"{name} must be a real array, got complex values")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidTypeError(
            f"{name} must be a numeric array, got {type(value).__name__}: {exc}"
        ) from exc
    want = tuple("*" if s is None else s for s in shape)
    if arr.ndim != len(shape) or any(s is not None and a != s for a, s in zip(arr.shape, shape)):
        raise ShapeError(f"{name} must have shape {want}, got {arr.shape}")
    return arr


def finite_array(name: str, value: object, shape: Sequence[int | None]) -> np.ndarray:
    """:func:`as_array`, and every entry finite (no NaN or infinity)."""
    arr = as_array(name, value, shape)
    if not np.all(np.isfinite(arr)):
        raise InvalidArgumentError(f"{name} must be finite, got {arr.tolist()}")
    return arr


def as_weights(name: str, value: object, size: int) -> np.ndarray:
    """A non-negative, finite weight vector of length ``size`` from a scalar or array."""
    if value is None or isinstance(value, (str, bytes, Mapping, bool)):
        raise InvalidTypeError(f"{name} must be a number or an array, got {type(value).__name__}")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidTypeError(f"{name} must be a number or an array: {exc}") from exc
    if arr.ndim == 0:
        arr = np.full(size, float(arr))
    arr = finite_array(name, arr, (size,))
    if np.any(arr < 0):
        raise InvalidArgumentError(f"{name} must be non-negative, got {arr}")
    return arr


def number(name: str, value: object) -> float:
    """``value`` as a float; it must be a real number (not a bool, a string or an array).

    Raises:
        InvalidTypeError: If it is not a real number.
    """
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise InvalidTypeError(f"{name} must be a number, got {type(value).__name__} {value!r}")
    return float(value)


def finite(name: str, value: object) -> float:
    """Check that ``value`` is a finite number and return it as float."""
    val = number(name, value)
    if not np.isfinite(val):
        raise InvalidArgumentError(f"{name} must be a finite number, got {value!r}")
    return val


def positive(name: str, value: object) -> float:
    """Check ``0 < value < inf`` and return it as float."""
    val = number(name, value)
    if not np.isfinite(val) or val <= 0:
        raise InvalidArgumentError(f"{name} must be a positive finite number, got {value!r}")
    return val


def optional_positive(name: str, value: object) -> float | None:
    """``None`` for ``None``, else :func:`positive`."""
    return None if value is None else positive(name, value)


def non_negative(name: str, value: object) -> float:
    """Check ``0 <= value < inf`` and return it as float."""
    val = number(name, value)
    if not np.isfinite(val) or val < 0:
        raise InvalidArgumentError(f"{name} must be a finite number >= 0, got {value!r}")
    return val


def non_negative_weights(**weights: object) -> dict[str, float]:
    """Check every weight with :func:`non_negative`, named by its keyword.

    Returns:
        The weights as floats, keyed by the keyword without a ``_cost`` or ``_scale``
        suffix (``height_cost=1`` gives ``{"height": 1.0}``).
    """
    return {
        re.sub(r"_(cost|scale)$", "", name): non_negative(name, value)
        for name, value in weights.items()
    }


def in_range(
    name: str, value: object, low: float, high: float, *, low_open: bool, high_open: bool
) -> float:
    """Check that ``value`` lies in the interval from ``low`` to ``high`` (ends open or closed)."""
    val = number(name, value)
    above = val > low if low_open else val >= low
    below = val < high if high_open else val <= high
    if not (above and below):
        interval = f"{'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
        raise InvalidArgumentError(f"{name} must be in {interval}, got {value!r}")
    return val


#: Largest seed numpy's legacy generator takes (``RandomState``): seeds are 32-bit.
SEED_MAX = 2**32 - 1


def integer(name: str, value: object, minimum: int = 0, maximum: int | None = None) -> int:
    """Check that ``value`` is an integer (not a bool) ``>= minimum`` (and ``<= maximum``
    when given) and return it."""
    bounds = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise InvalidTypeError(
            f"{name} must be an integer {bounds}, got {type(value).__name__} {value!r}"
        )
    if value < minimum or (maximum is not None and value > maximum):
        raise InvalidArgumentError(f"{name} must be an integer {bounds}, got {value!r}")
    return int(value)


def seed(name: str, value: object) -> int:
    """Check that ``value`` is a random seed: an integer in ``[0, 2**32 - 1]``."""
    return integer(name, value, 0, SEED_MAX)


def seeds(name: str, values: object) -> list[int]:
    """A non-empty sequence of random seeds (each in ``[0, 2**32 - 1]``) as a list."""
    return integers(name, values, 0, SEED_MAX)


def positive_int(name: str, value: object) -> int:
    """Check that ``value`` is an integer >= 1 and return it."""
    return integer(name, value, 1)


def integers(name: str, values: object, minimum: int = 0, maximum: int | None = None) -> list[int]:
    """A non-empty sequence of integers ``>= minimum`` (seeds, for example) as a list."""
    if isinstance(values, (str, bytes, Mapping)) or not isinstance(values, Sequence | np.ndarray):
        raise InvalidTypeError(
            f"{name} must be a sequence of integers, got {type(values).__name__} {values!r}"
        )
    out = [integer(name, value, minimum, maximum) for value in values]
    if not out:
        raise InvalidArgumentError(f"{name} must hold at least one integer")
    return out


def boolean(name: str, value: object) -> bool:
    """Check that ``value`` is a bool (Python's or numpy's) and return it."""
    if not isinstance(value, (bool, np.bool_)):
        raise InvalidTypeError(
            f"{name} must be True or False, got {type(value).__name__} {value!r}"
        )
    return bool(value)


def string(name: str, value: object) -> str:
    """Check that ``value`` is a string and return it."""
    if not isinstance(value, str):
        raise InvalidTypeError(f"{name} must be a string, got {type(value).__name__} {value!r}")
    return value


def instance(name: str, value: object, cls: type, what: str | None = None) -> Any:
    """Check ``isinstance(value, cls)`` and return ``value``; ``what`` names ``cls``."""
    if not isinstance(value, cls):
        raise InvalidTypeError(
            f"{name} must be {what or 'a ' + cls.__name__}, got {type(value).__name__}"
        )
    return value


def one_of(name: str, value: str, choices: Sequence[str]) -> str:
    """Check that ``value`` is one of ``choices``; the error lists them."""
    listed = ", ".join(repr(c) for c in choices)
    if not isinstance(value, str):
        raise InvalidTypeError(f"{name} must be one of {listed}; got {type(value).__name__}")
    if value not in choices:
        raise InvalidArgumentError(f"{name} must be one of {listed}; got {value!r}")
    return value


def checked_options(init: F) -> F:
    """Decorate an ``__init__`` (or a class, e.g. a config dataclass, below ``@dataclass``)
    so that an unknown keyword argument raises :class:`~mpcbox.errors.UnknownOptionError`
    listing the valid ones (Python's own error is a bare :class:`TypeError`).

    The valid names are the keyword parameters of every ``__init__`` in the class hierarchy
    of the instance (so a subclass that forwards ``**kwargs`` to the decorated one is covered
    too), without ``*args``/``**kwargs`` themselves. More positional arguments than the
    ``__init__`` takes by position raise :class:`~mpcbox.errors.InvalidTypeError` naming
    those it takes (``Push([50, 0, 0])`` on a keyword-only dataclass, for one).
    """
    if isinstance(init, type):
        init.__init__ = checked_options(init.__init__)  # type: ignore[misc]
        return init

    params = list(inspect.signature(init).parameters.values())[1:]  # without self
    kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    positional = [p.name for p in params if p.kind in kinds]
    any_positional = any(p.kind is inspect.Parameter.VAR_POSITIONAL for p in params)

    @functools.wraps(init)
    def wrapper(self: Any, *args: Any, **kwargs: Any) -> Any:
        if len(args) > len(positional) and not any_positional:
            owner = type(self).__name__
            if positional:
                takes = f"only {', '.join(positional)} by position"
            else:
                first = params[0].name if params else "name"
                takes = f"keyword arguments only (e.g. {owner}({first}=...))"
            raise InvalidTypeError(f"{owner} takes {takes}, got {len(args)} positional argument(s)")
        check_class_options(type(self), kwargs, type(self).__name__)
        return init(self, *args, **kwargs)

    return wrapper  # type: ignore[return-value]


def check_class_options(cls: type, options: Mapping[str, Any], owner: str) -> None:
    """Raise :class:`~mpcbox.errors.UnknownOptionError` for a keyword in ``options`` that no
    ``__init__`` of ``cls`` or its bases takes (the message lists those that exist)."""
    valid: set[str] = set()
    for klass in cls.__mro__:
        method = klass.__dict__.get("__init__")
        if method is None or klass is object:
            continue
        for param in inspect.signature(inspect.unwrap(method)).parameters.values():
            if param.kind in (param.POSITIONAL_OR_KEYWORD, param.KEYWORD_ONLY):
                valid.add(param.name)
    valid.discard("self")
    unknown = set(options) - valid
    if unknown:
        raise UnknownOptionError(owner, unknown, valid)


def checked_keywords(function: F) -> F:
    """Decorate a function so that an unknown keyword argument raises
    :class:`~mpcbox.errors.UnknownOptionError` listing its keyword parameters (Python's own
    error is a bare :class:`TypeError`)."""
    params = inspect.signature(function).parameters.values()
    valid = {p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}

    @functools.wraps(function)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        unknown = set(kwargs) - valid
        if unknown:
            raise UnknownOptionError(function.__name__, unknown, valid)
        return function(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
