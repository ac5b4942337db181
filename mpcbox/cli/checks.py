"""Checks of the command line's arguments, run before any simulation starts.

A bad value is an :class:`~mpcbox.errors.InvalidArgumentError` naming the flag and what it
expects; the command prints it and exits with status 2 (no traceback).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from mpcbox.config import check_option_names
from mpcbox.errors import InvalidArgumentError, MpcboxError

#: Smallest bisection tolerance of ``--push-tolerance`` (N): below it a bisection over forces
#: of hundreds of newtons would run into the float resolution.
MIN_PUSH_TOLERANCE = 1e-3


def _finite(flag: str, value: float, *, low: float | None = None, strict: bool = True) -> None:
    if not math.isfinite(value):
        raise InvalidArgumentError(f"{flag} must be a finite number, got {value!r}")
    if low is not None and (value <= low if strict else value < low):
        sign = ">" if strict else ">="
        raise InvalidArgumentError(f"{flag} must be {sign} {low:g}, got {value!r}")


def check_arguments(args: argparse.Namespace) -> None:
    """Check the numbers of ``mpcbox compare`` (seeds, duration, pushes, scales, ...), and
    read a bare Menagerie name in ``--model`` as one (:func:`resolve_model`).

    Raises:
        InvalidArgumentError: Naming the first flag with a bad value.
    """
    if args.seeds < 1:
        raise InvalidArgumentError(f"--seeds must be >= 1, got {args.seeds}")
    if args.seed < 0:
        raise InvalidArgumentError(f"--seed must be >= 0 (NumPy seeds), got {args.seed}")
    if args.workers < 0:
        raise InvalidArgumentError(f"--workers must be >= 0 (0: one per core), got {args.workers}")
    _finite("--duration", args.duration, low=0.0)
    _finite("--push", args.push, low=0.0, strict=False)
    _finite("--push-time", args.push_time, low=0.0, strict=False)
    _finite("--push-duration", args.push_duration, low=0.0)
    if args.push and args.push_time >= args.duration:
        raise InvalidArgumentError(
            f"--push-time ({args.push_time:g} s) must be before the end of the run "
            f"(--duration {args.duration:g} s): the push would never be applied"
        )
    _finite("--mass-scale", args.mass_scale, low=0.0)
    _finite("--friction-scale", args.friction_scale, low=0.0)
    _finite("--push-tolerance", args.push_tolerance, low=MIN_PUSH_TOLERANCE, strict=False)
    for flag in ("--push-rest-speed", "--push-scan-step"):
        value = getattr(args, flag[2:].replace("-", "_"), None)
        if value is not None:
            _finite(flag, value, low=0.0)
    lookahead = lookahead_option(getattr(args, "lookahead", None))
    if lookahead is not None and not args.realtime:
        raise InvalidArgumentError("--lookahead needs --realtime")
    delay = getattr(args, "delay", None)
    if delay is not None:
        if not args.realtime:
            raise InvalidArgumentError("--delay needs --realtime")
        _finite("--delay", delay, low=0.0, strict=False)
    speed = getattr(args, "speed", 1.0)
    _finite("--speed", speed, low=0.0)
    if speed != 1.0 and not getattr(args, "realtime", False):
        raise InvalidArgumentError("--speed needs --realtime (a lock-step run has no clock)")
    if speed != 1.0 and delay is not None:
        raise InvalidArgumentError(
            "--speed has no effect with --delay (the world waits for each tick): leave it at 1"
        )
    if getattr(args, "largest_push", False) and getattr(args, "realtime", False):
        raise InvalidArgumentError(
            "--largest-push searches in lock-step (the world waits for the controller), so "
            "it cannot be combined with --realtime: run it without --realtime, or give a "
            "fixed --push in real time"
        )
    message = f"--noise must be numbers separated by commas, got {args.noise!r}"
    if not str(args.noise).strip():
        raise InvalidArgumentError(message)
    for part in str(args.noise).split(","):
        if not part.strip():
            continue
        _finite("--noise", _to_float(part, message), low=0.0, strict=False)
    resolve_model(args)


def check_output_folder(folder: str | Path, flag: str = "--out") -> Path:
    """Create ``folder`` (the value of ``flag``, or the folder of its file) and check that
    a file can be written there, before anything runs.

    Raises:
        InvalidArgumentError: If the folder cannot be created or written, naming ``flag``.
    """
    path = Path(folder)
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path):
            pass
    except OSError as exc:
        raise InvalidArgumentError(
            f"{flag}: {str(path)!r} is not a writable folder: {exc}"
        ) from exc
    return path


def number_flag(flag: str, value: float, *, low: float | None = None, strict: bool = True) -> float:
    """``value`` of ``flag``, checked to be finite and above ``low`` (``>=`` with
    ``strict=False``).

    Raises:
        InvalidArgumentError: Naming the flag.
    """
    _finite(flag, value, low=low, strict=strict)
    return value


def check_push_flags(args: argparse.Namespace) -> None:
    """``--duration`` (> 0), ``--push`` (>= 0) and ``--push-scan-step`` (> 0 when given)
    of the legged-balance scripts (``problems/go2_stand.py``, ``problems/g1_balance.py``).

    Raises:
        InvalidArgumentError: Naming the first bad flag.
    """
    _finite("--duration", args.duration, low=0.0)
    _finite("--push", args.push, low=0.0, strict=False)
    if args.push_scan_step is not None:
        _finite("--push-scan-step", args.push_scan_step, low=0.0)


def check_save_name(flag: str, name: str | None) -> None:
    """Check before any run that ``flag``'s ``PATH`` (written as ``PATH.csv`` and
    ``PATH.json``) names a file in a folder that can be created and written.

    Raises:
        InvalidArgumentError: Naming the flag.
    """
    if name is None:
        return
    from mpcbox.sim.trajectory_files import trajectory_paths

    try:
        csv_path, _ = trajectory_paths(name)
    except InvalidArgumentError as exc:
        raise InvalidArgumentError(f"{flag}: {exc}") from None
    check_output_folder(csv_path.parent, flag)


def check_options(name: str, options: Mapping[str, Any], chosen: Iterable[str]) -> None:
    """Check a ``--set NAME.OPTION=VALUE`` group against the controller's config fields.

    Raises:
        UnknownNameError: If ``name`` is not one of the chosen controllers.
        UnknownOptionError: If an option is not a field of the controller's config.
    """
    from mpcbox.registry import controller_class

    chosen = list(chosen)
    if name not in chosen:
        raise InvalidArgumentError(
            f"--set {name}.OPTION=VALUE: {name!r} is not among the chosen controllers "
            f"({', '.join(chosen)}); add it to --controllers or drop the --set"
        )
    check_option_names(controller_class(name).config_class, options, f"--set {name}")


def resolve_model(args: argparse.Namespace) -> None:
    """Read a ``--model`` that is not a file as a Menagerie robot (a bare name becomes
    ``"menagerie:NAME"``), as ``problems/*.py`` and ``mpcbox inspect`` take it."""
    model = getattr(args, "model", None)
    if isinstance(model, str) and not os.path.exists(model):
        from mpcbox.core.menagerie import model_source

        args.model = model_source(model)


def script_main(run: Callable[[list[str] | None], int], argv: list[str] | None) -> int:
    """``run(argv)`` of a problem script; a bad argument (an :class:`MpcboxError`, which
    names it) prints ``error: ...`` to stderr and returns 2."""
    try:
        return run(argv)
    except MpcboxError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


def lookahead_option(text: str | None) -> float | str | None:
    """``--lookahead``'s value: ``None`` (not given, or ``"none"``), ``"auto"`` or seconds
    ``>= 0``.

    Raises:
        InvalidArgumentError: For anything else, naming the flag.
    """
    if text is None or text == "none":
        return None
    if text == "auto":
        return text
    seconds = _to_float(text, f"--lookahead must be 'auto', 'none' or seconds >= 0, got {text!r}")
    _finite("--lookahead", seconds, low=0.0, strict=False)
    return seconds


def _to_float(text: str, message: str) -> float:
    """``float(text)``, or :class:`InvalidArgumentError` with ``message``."""
    try:
        return float(text)
    except ValueError:
        raise InvalidArgumentError(message) from None
