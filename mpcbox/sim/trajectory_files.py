"""Trajectory files: ``NAME.csv`` (one row per step) beside ``NAME.json`` (the metadata).

:func:`save_trajectory` writes them (see :mod:`mpcbox.sim.trajectory` for the columns);
:func:`load_trajectory` reads them back and refuses a file that was truncated or edited (a
missing or renamed column, a row of another length, a cell that is no number, NaN in the
time, state or controls, time that does not increase, another format or version), naming
the file and the row.
"""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

import numpy as np

from mpcbox.errors import InvalidArgumentError, InvalidTypeError, MpcboxError
from mpcbox.sim.disturbances import ActuatorNoise, ModelMismatch, Push
from mpcbox.sim.trajectory import Trajectory, disturbance_record, jsonable
from mpcbox.validation import checked_keywords

#: ``format`` entry of the JSON sidecar.
FORMAT = "mpcbox-trajectory"
#: Version of the file layout.
VERSION = 1


def trajectory_paths(path: str | Path) -> tuple[Path, Path]:
    """The CSV and JSON paths of a trajectory named ``path`` (with or without a suffix)."""
    if not isinstance(path, (str, Path)):
        raise InvalidTypeError(f"path must be a file path, got {type(path).__name__}")
    if str(path).endswith(("/", os.sep)) or Path(path).is_dir():
        raise InvalidArgumentError(
            f"path must name a file (PATH.csv and PATH.json are written), got the folder "
            f"{str(path)!r}: add a name, such as {str(Path(path) / 'run')!r}"
        )
    path = Path(path)
    if path.suffix.lower() in (".csv", ".json"):
        path = path.with_suffix("")
    return path.with_name(path.name + ".csv"), path.with_name(path.name + ".json")


def _columns(traj: Trajectory) -> list[str]:
    nq, nv = int(traj.metadata["nq"]), int(traj.metadata["nv"])
    na, nu = int(traj.metadata["na"]), traj.ctrls.shape[1]
    cols = ["time"]
    cols += [f"qpos_{i}" for i in range(nq)] + [f"qvel_{i}" for i in range(nv)]
    cols += [f"act_{i}" for i in range(na)] + [f"ctrl_{i}" for i in range(nu)]
    cols += [f"measure_{name}" for name in traj.series]
    for name in traj.sites:
        cols += [f"site_{name}_{axis}" for axis in "xyz"]
    return cols


@checked_keywords
def save_trajectory(traj: Trajectory, path: str | Path) -> tuple[Path, Path]:
    """Write ``traj`` as ``PATH.csv`` and ``PATH.json`` (a ``.csv``/``.json`` suffix is dropped).

    Args:
        traj: The trajectory.
        path: File name without suffix; folders are created.

    Returns:
        The CSV and JSON paths.

    Raises:
        InvalidArgumentError: If ``traj`` is not a Trajectory or the files cannot be written.
    """
    if not isinstance(traj, Trajectory):
        raise InvalidArgumentError(f"traj must be an mpcbox Trajectory, got {type(traj).__name__}")
    csv_path, json_path = trajectory_paths(path)
    blocks = [traj.time[:, None], traj.states, traj.ctrls]
    blocks += [v[:, None] for v in traj.series.values()]
    blocks += list(traj.sites.values())
    table = np.hstack(blocks)
    meta = {
        "format": FORMAT,
        "version": VERSION,
        "csv": csv_path.name,
        "problem": traj.problem,
        "controller": traj.controller,
        "failure": traj.failure,
        "steps": len(traj.time),
        "final_time": float(traj.time[-1]),
        "initial_state": jsonable(traj.initial_state),
        "measures": list(traj.series),
        "sites": list(traj.sites),
        **disturbance_record(traj),
        **{k: jsonable(v) for k, v in traj.metadata.items()},
    }
    try:
        csv_path.parent.mkdir(parents=True, exist_ok=True)
        with csv_path.open("w", newline="") as f:
            csv.writer(f, lineterminator="\n").writerow(_columns(traj))
            np.savetxt(f, table, fmt="%.17g", delimiter=",")
        json_path.write_text(json.dumps(meta, indent=2, allow_nan=True) + "\n")
    except OSError as exc:
        raise InvalidArgumentError(f"cannot write the trajectory {str(path)!r}: {exc}") from exc
    return csv_path, json_path


_SHARED = {"format", "version", "csv", "problem", "controller", "failure", "steps", "final_time"}
_SHARED |= {"initial_state", "measures", "sites", "seed", "pushes", "noise", "mismatch"}


@checked_keywords
def load_trajectory(path: str | Path) -> Trajectory:
    """Read a trajectory written by :func:`save_trajectory`.

    Args:
        path: ``NAME.csv``, ``NAME.json`` or ``NAME``.

    Raises:
        InvalidArgumentError: If a file is missing, unreadable or not a whole mpcbox trajectory.
    """
    csv_path, json_path = trajectory_paths(path)
    try:
        meta = json.loads(json_path.read_text())
        header, table = _read_table(csv_path)
    except (OSError, ValueError) as exc:
        raise InvalidArgumentError(
            f"path: cannot read the trajectory {str(path)!r} ({csv_path.name} + {json_path.name}): "
            f"{exc or type(exc).__name__}"
        ) from exc
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        found = meta.get("format") if isinstance(meta, dict) else None
        raise InvalidArgumentError(
            f"{str(json_path)!r} is not an mpcbox trajectory (format {found!r}, expected "
            f"{FORMAT!r})"
        )
    for key, kind in (("task", str), ("task_options", dict)):
        if meta.get(key) is not None and not isinstance(meta[key], kind):
            raise InvalidArgumentError(
                f"{str(json_path)!r}: {key} must be a {'string' if kind is str else 'JSON object'}"
                f", got {type(meta[key]).__name__} (an edited file?)"
            )
    if meta.get("version") != VERSION:
        raise InvalidArgumentError(
            f"{str(json_path)!r} is version {meta.get('version')!r} of the trajectory format; "
            f"this mpcbox reads version {VERSION}"
        )
    try:
        nq, nv, na, nu = (int(meta[k]) for k in ("nq", "nv", "na", "nu"))
        measures, sites = list(meta["measures"]), list(meta["sites"])
        width = 1 + nq + nv + na + nu + len(measures) + 3 * len(sites)
        rows, steps = len(table), int(meta.get("steps", len(table)))
        if len(header) != width or (table.size and table.shape[1] != width) or rows != steps:
            raise InvalidArgumentError(
                f"{csv_path.name} has {len(header)} columns and {rows} rows; its JSON describes "
                f"{width} columns and {steps} rows (a truncated or edited file?)"
            )
        expected = ["time"] + [f"qpos_{i}" for i in range(nq)] + [f"qvel_{i}" for i in range(nv)]
        expected += [f"act_{i}" for i in range(na)] + [f"ctrl_{i}" for i in range(nu)]
        if header[: len(expected)] != expected:
            bad = next(i for i, (a, b) in enumerate(zip(header, expected, strict=False)) if a != b)
            raise InvalidArgumentError(
                f"{csv_path.name}: column {bad + 1} is {header[bad]!r}, expected "
                f"{expected[bad]!r} (an edited file?)"
            )
        if not np.all(np.isfinite(table[:, : len(expected)])):
            row = int(np.flatnonzero(~np.isfinite(table[:, : len(expected)]).all(axis=1))[0])
            raise InvalidArgumentError(
                f"{csv_path.name}: data row {row + 1} holds NaN or infinity in its time, state "
                "or controls"
            )
        if np.any(np.diff(table[:, 0]) <= 0.0):
            row = int(np.flatnonzero(np.diff(table[:, 0]) <= 0.0)[0])
            raise InvalidArgumentError(
                f"{csv_path.name}: time does not increase at data row {row + 2} "
                f"({table[row, 0]!r} then {table[row + 1, 0]!r})"
            )
        cols = np.cumsum([1, nq + nv + na, nu, len(measures)])
        noise = meta["noise"]
        mismatch = meta["mismatch"]
        return Trajectory(
            problem=str(meta["problem"]),
            controller=str(meta["controller"]),
            time=table[:, 0].copy(),
            states=table[:, 1 : cols[1]].copy(),
            ctrls=table[:, cols[1] : cols[2]].copy(),
            series={m: table[:, cols[2] + i].copy() for i, m in enumerate(measures)},
            sites={
                s: table[:, cols[3] + 3 * i : cols[3] + 3 * i + 3].copy()
                for i, s in enumerate(sites)
            },
            failure=meta["failure"],
            initial_state=np.asarray(meta["initial_state"], dtype=np.float64),
            pushes=tuple(
                Push(
                    force=tuple(p["force"]),
                    torque=tuple(p["torque"]),
                    start=float(p["start"]),
                    duration=float(p["duration"]),
                    body=str(p["body"]),
                )
                for p in meta["pushes"]
            ),
            mismatch=None if mismatch is None else ModelMismatch(**mismatch),
            noise=None if noise is None else ActuatorNoise(**noise),
            seed=int(meta["seed"]),
            metadata={k: v for k, v in meta.items() if k not in _SHARED},
        )
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, MpcboxError):
            raise
        raise InvalidArgumentError(
            f"{str(json_path)!r} is not a complete mpcbox trajectory: {exc!r}"
        ) from exc


def _read_table(csv_path: Path) -> tuple[list[str], np.ndarray]:
    """The header and the numbers ``(rows, columns)`` of a trajectory CSV.

    Raises:
        ValueError: For an empty file, a row of another length or a cell that is no number,
            each named by its data row.
    """
    with csv_path.open(newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if not header:
            raise ValueError(f"{csv_path.name} is empty (no header row)")
        rows = []
        for number, cells in enumerate(reader, start=1):
            if len(cells) != len(header):
                raise ValueError(
                    f"data row {number} has {len(cells)} cells, the header {len(header)} (a "
                    "truncated or edited file?)"
                )
            try:
                rows.append([float(c) for c in cells])
            except ValueError:
                raise ValueError(f"data row {number} holds a cell that is not a number") from None
    return header, np.array(rows, dtype=np.float64).reshape(len(rows), len(header))
