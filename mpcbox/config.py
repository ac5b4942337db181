"""Keyword-only configuration objects: building them from options, describing their fields.

Every controller takes a frozen, keyword-only dataclass (``LQRConfig``, ``ILQRConfig``,
``QPMPCConfig``, ``SamplingConfig`` and its subclasses). Keyword options passed to a
controller are applied on top of its config with :func:`resolve_config`, which rejects
unknown names and lists the valid ones.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from typing import Any, NamedTuple, TypeVar

from mpcbox.errors import InvalidTypeError, UnknownOptionError

C = TypeVar("C")


class OptionInfo(NamedTuple):
    """One field of a config class, as :func:`describe_config` lists it.

    Attributes:
        name: Field name (the keyword option).
        default: Default value (``dataclasses.MISSING`` when the field has none).
        type: The annotation, as written.
    """

    name: str
    default: Any
    type: str


def check_option_names(config_class: type, options: Iterable[str], owner: str) -> None:
    """Raise :class:`UnknownOptionError` (listing the valid fields) for an option that is not
    a field of ``config_class``.

    Args:
        config_class: A config dataclass.
        options: Option names.
        owner: Name used in the message (``"ILQR"``, ``"--set ilqr"``).
    """
    valid = {f.name for f in dataclasses.fields(config_class)}
    unknown = set(options) - valid
    if unknown:
        raise UnknownOptionError(owner, unknown, valid)


def resolve_config(
    config_class: type[C], config: C | None, options: Mapping[str, Any], owner: str
) -> C:
    """The config to use: ``config`` (or the class's defaults) with ``options`` applied.

    Args:
        config_class: The expected dataclass type.
        config: A ``config_class`` instance, or ``None`` for its defaults.
        options: Keyword options that replace fields of ``config``.
        owner: Name used in error messages (for example ``"ILQR"``).

    Returns:
        A new frozen config instance.

    Raises:
        InvalidTypeError: If ``config`` is not a ``config_class``.
        UnknownOptionError: If an option is not a field of ``config_class``; the message
            lists the valid fields.
    """
    if config is None:
        config = config_class()
    elif not isinstance(config, config_class):
        raise InvalidTypeError(
            f"config of {owner} must be a {config_class.__name__}, got {type(config).__name__}"
        )
    check_option_names(config_class, options, owner)
    return dataclasses.replace(config, **options) if options else config  # type: ignore[type-var]


def describe_config(config_class: type) -> list[OptionInfo]:
    """The fields of a config dataclass with their defaults, in declaration order."""
    out = []
    for field in dataclasses.fields(config_class):
        if field.default is not dataclasses.MISSING:
            default = field.default
        elif field.default_factory is not dataclasses.MISSING:
            default = field.default_factory()
        else:
            default = dataclasses.MISSING
        out.append(OptionInfo(field.name, default, str(field.type)))
    return out


def config_options(config: Any) -> dict[str, Any]:
    """The fields of a config object as keyword options (a shallow copy: nested configs stay
    objects), e.g. to pass a task's tuned config on with a few changes."""
    if not dataclasses.is_dataclass(config) or isinstance(config, type):
        raise InvalidTypeError(f"config must be a config dataclass instance, got {config!r}")
    return {f.name: getattr(config, f.name) for f in dataclasses.fields(config)}
