"""The gates' report: :class:`GateReport`, its text form and its JSON file."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from mpcbox.errors import InvalidArgumentError
from mpcbox.gates.cpu_baseline import CpuBaseline
from mpcbox.sim.trajectory import jsonable

if TYPE_CHECKING:  # these import MJWarp
    from mpcbox.gates.capacity import Capacity
    from mpcbox.gates.parity import Parity
    from mpcbox.gates.scaling import Scaling
    from mpcbox.gates.throughput import Throughput

#: ``format`` entry of the JSON file.
FORMAT = "mpcbox-gates"


class GateReport(NamedTuple):
    """Everything :func:`~mpcbox.gates.validate_scene` found.

    A gate that did not run (MJWarp missing or unable to run the model, ``error`` says why)
    is ``None`` and counts as failed.

    Attributes:
        scene: The scene as given.
        source: Where the controls came from.
        notes: Remarks (pushes not replayed, a task's early stop, ...).
        model: Model sizes and options (``nq``, ``nv``, ``nu``, ``ngeom``, ``timestep``, ...).
        device: The machine (:func:`~mpcbox.gates.device.device_info`), or ``None``.
        config: The options used.
        cpu: Gate 1.
        parity: Gate 2.
        capacity: Gate 3.
        scaling: Gate 4.
        throughput: Gate 5.
        error: Why the MJWarp gates did not run, or ``None``.
        error_traceback: The full traceback behind ``error`` (kept in the JSON), or ``None``.
    """

    scene: str
    source: str
    notes: tuple[str, ...]
    model: dict[str, Any]
    device: dict[str, Any] | None
    config: dict[str, Any]
    cpu: CpuBaseline
    parity: Parity | None
    capacity: Capacity | None
    scaling: Scaling | None
    throughput: Throughput | None
    error: str | None = None
    error_traceback: str | None = None

    @property
    def gates(self) -> dict[str, Any]:
        """The five gates by name (``None`` where one did not run)."""
        return {
            "cpu_baseline": self.cpu,
            "parity": self.parity,
            "capacity": self.capacity,
            "scaling": self.scaling,
            "throughput": self.throughput,
        }

    @property
    def failed(self) -> list[str]:
        """Names of the gates that failed or did not run."""
        return [name for name, gate in self.gates.items() if gate is None or not gate.passed]

    @property
    def passed(self) -> bool:
        """Every gate ran and passed."""
        return not self.failed

    def to_dict(self) -> dict[str, Any]:
        """The JSON-ready report."""
        return jsonable(
            {
                "format": FORMAT,
                "version": 1,
                "scene": self.scene,
                "passed": self.passed,
                "failed": self.failed,
                "source": self.source,
                "notes": list(self.notes),
                "model": self.model,
                "device": self.device,
                "config": self.config,
                "error": self.error,
                "error_traceback": self.error_traceback,
                "gates": {
                    name: None if gate is None else gate.summary()
                    for name, gate in self.gates.items()
                },
            }
        )


def scene_slug(scene: str) -> str:
    """A file-name part for ``scene``: ``.../aloha_pot/scene.xml`` -> ``aloha_pot_scene``."""
    if scene.startswith(("task:", "menagerie:")):
        text = scene.split(":", 1)[1]
    else:
        path = Path(scene)
        text = f"{path.parent.name}_{path.stem}" if path.stem == "scene" else path.stem
    slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_.")
    return slug or "scene"


def write_report(report: GateReport, out: str | Path) -> Path:
    """Write ``out/gates_<scene>.json`` (folders created) and return its path.

    Raises:
        InvalidArgumentError: If ``out`` is not a folder that can be written.
    """
    if not isinstance(out, (str, Path)):
        raise InvalidArgumentError(f"out must be a folder path, got {type(out).__name__}")
    path = Path(out) / f"gates_{scene_slug(report.scene)}.json"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(report.to_dict(), indent=2) + "\n")
    except OSError as exc:
        raise InvalidArgumentError(f"out: cannot write {str(path)!r}: {exc}") from exc
    return path


def _mark(gate: Any) -> str:
    return "[ -- ]" if gate is None else "[PASS]" if gate.passed else "[FAIL]"


def _g(value: float | None, unit: str = "") -> str:
    return "-" if value is None else f"{value:.3g}{unit}"


def format_report(report: GateReport) -> str:
    """The report as readable text (what ``mpcbox validate`` prints)."""
    m = report.model
    cpu = report.cpu
    lines = [
        f"mpcbox validate: {report.scene}",
        f"  model: nq {m['nq']}, nv {m['nv']}, nu {m['nu']}, ngeom {m['ngeom']}, "
        f"timestep {m['timestep']:g} s",
        f"  controls: {report.source}; {len(cpu.ncon)} steps",
    ]
    lines += [f"  note: {n}" for n in report.notes]
    if report.device:
        d = report.device
        lines.append(
            f"  device: {d['device']} ({d['name']}), mujoco {d['mujoco']}, "
            f"mujoco-warp {d['mujoco_warp']}, warp {d['warp']}"
        )
    s = cpu.summary()
    lines.append(
        f"{_mark(cpu)} 1 CPU baseline: {s['steps']} steps, "
        f"{s['divergence'] or 'no divergence'}; most contacts {s['max_ncon']}, "
        f"most constraint rows {s['max_nefc']}"
    )
    if report.error:
        lines.append(f"  MJWarp gates did not run: {report.error}")
    p = report.parity
    if p is not None:
        ps = p.summary()
        beyond = ps["time_beyond_tolerance"]
        lines.append(
            f"{_mark(p)} 2 MJWarp parity (1 world): max |dqpos| {_g(ps['max_qpos_error'])}, "
            f"final {_g(ps['final_qpos_error'])}; tolerance {p.tolerance:g} within the first "
            f"{p.window:g} s; "
            + ("never beyond it" if beyond is None else f"beyond it from t = {beyond:.4g} s")
            + "".join(
                f", {s}x from {t:.4g} s"
                for s, t in ((10, p.first_time_beyond(10.0)), (100, p.first_time_beyond(100.0)))
                if t is not None
            )
            + (", DIVERGED" if p.diverged else "")
        )
        curve = ps["curve"]
        idx = sorted({int(i * (len(curve["time"]) - 1) / 4) for i in range(5)})
        points = ", ".join(f"{curve['time'][i]:.3g} s: {_g(curve['qpos_error'][i])}" for i in idx)
        lines.append(f"         |dqpos| over time: {points}")
    c = report.capacity
    if c is not None:
        z = c.sizing
        bad = [ch for ch in c.checks if not ch.passed]
        lines.append(
            f"{_mark(c)} 3 capacity: contacts seen CPU {z.cpu_max_ncon}, MJWarp "
            f"{z.warp_max_ncon} (broadphase {z.warp_max_ncollision}); rows CPU "
            f"{z.cpu_max_nefc}, MJWarp {z.warp_max_nefc}; suggested nconmax "
            f"{z.suggested_nconmax}, njmax {z.suggested_njmax} (headroom {z.headroom:g}); "
            f"used {z.nconmax}, {z.njmax}"
        )
        lines.append(
            f"         {len(c.checks)} runs checked: "
            + (
                "no overflow"
                if not bad
                else "; ".join(
                    f"{ch.run}: {ch.overflow['capacity_overflow_worlds']} worlds overflowed "
                    f"({', '.join(ch.overflow['capacity_flags'])})"
                    for ch in bad
                )
            )
        )
    sc = report.scaling
    if sc is not None:
        lines.append(
            f"{_mark(sc)} 4 N-world scaling: {sc.nworld} worlds x {sc.steps} steps, "
            f"{sc.diverged_worlds} diverged, {sc.host_reads} host read(s) (none per step), "
            f"final spread {_g(sc.final_spread)}, world 0 vs one world "
            f"{_g(sc.world0_vs_single)}, {sc.seconds:.3g} s"
        )
    t = report.throughput
    if t is not None:
        lines.append(
            f"{_mark(t)} 5 throughput on {t.device}: first call (compile or cache load) "
            f"{_g(t.first_call_seconds, ' s')}, blocks of {t.block_steps} steps"
        )
        lines.append("         nworld   cold s  capture s   warm s  world-steps/s  realtime x  ok")
        for r in t.rows:
            lines.append(
                f"         {r.nworld:>6}  {r.cold_seconds:7.3g}  {_g(r.capture_seconds):>9}"
                f"  {r.warm_seconds:7.3g}  {r.world_steps_per_second:13.4g}"
                f"  {r.realtime_factor:10.4g}  {'yes' if r.passed else 'NO'}"
            )
    verdict = "PASS" if report.passed else "FAIL (" + ", ".join(report.failed) + ")"
    lines.append(f"result: {verdict}")
    return "\n".join(lines)


__all__ = ["FORMAT", "GateReport", "format_report", "scene_slug", "write_report"]
