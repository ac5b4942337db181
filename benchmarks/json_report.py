"""How the legged-balance benchmarks end: stamp the run, print its JSON, write it if asked."""

from __future__ import annotations

import json
import platform
import sys
import time
from pathlib import Path

from mpcbox.cli.checks import check_output_folder, number_flag
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import integer, positive_int

#: The machine these benchmarks' JSON names by default.
SANDBOX = "2-core sandbox CPU, shared"


def finish(out: dict, path: str, *, started: float, machine: str | None = SANDBOX) -> int:
    """Add ``wall_time_s`` (since ``started``, a :func:`time.perf_counter` reading) and, unless
    ``machine`` is None, ``machine`` and ``platform`` to ``out``; print it as JSON and write
    it to ``path`` when that is not empty. Returns 0, the script's exit status."""
    out["wall_time_s"] = round(time.perf_counter() - started, 1)
    if machine is not None:
        out["machine"] = machine
        out["platform"] = f"{platform.machine()}, Python {sys.version.split()[0]}"
    text = json.dumps(out, indent=2)
    print(text)
    if path:
        Path(path).write_text(text + "\n")
    return 0


def json_option(flag: str, text: str) -> dict:
    """``flag``'s value, a JSON object (a named :class:`InvalidArgumentError` otherwise)."""
    try:
        value = json.loads(text)
    except ValueError as exc:
        raise InvalidArgumentError(f"{flag} must be a JSON object, got {text!r}: {exc}") from None
    if not isinstance(value, dict):
        raise InvalidArgumentError(f"{flag} must be a JSON object, got {text!r}")
    return value


def check_balance_args(args, first_seed: str) -> None:
    """The shared flags of the legged-balance benchmarks, before any run: ``--seeds``, the
    first seed (flag ``first_seed``), ``--duration``, ``--push-tolerance``, ``--workers``
    (0: one per core), ``--controller-options`` and ``--json``'s folder.

    Raises:
        InvalidArgumentError: Naming the first bad flag.
    """
    positive_int("--seeds", args.seeds)
    integer(first_seed, getattr(args, first_seed[2:].replace("-", "_")), minimum=0)
    number_flag("--duration", args.duration, low=0.0)
    number_flag("--push-tolerance", args.push_tolerance, low=0.0)
    integer("--workers", args.workers, minimum=0)
    json_option("--controller-options", args.controller_options)
    if args.json:
        check_output_folder(Path(args.json).parent, "--json")
