"""All five gates on one scene: :func:`validate_scene`."""

from __future__ import annotations

import dataclasses
import traceback
from pathlib import Path

import mujoco

from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.gates.config import CPU_WORLDS, GPU_WORLDS, GatesConfig
from mpcbox.gates.controls import (
    GateInput,
    load_scene,
    scene_controls,
    task_controls,
    task_scene_controls,
    trajectory_controls,
)
from mpcbox.gates.cpu_baseline import run_cpu_baseline
from mpcbox.gates.report import GateReport
from mpcbox.validation import checked_keywords


def gate_input(
    scene: str | Path | mujoco.MjModel | None,
    config: GatesConfig,
    *,
    ctrl_trajectory: str | Path | None = None,
    task: str | None = None,
    controller: str | None = None,
) -> GateInput:
    """The model, start and controls the gates replay (see :mod:`mpcbox.gates.controls`).

    Raises:
        InvalidArgumentError: If both or neither of ``scene``/``task`` make a model, or a
            task's scene and ``scene`` differ in size.
    """
    if ctrl_trajectory is not None and task is not None:
        raise InvalidArgumentError("ctrl_trajectory and task both give controls: pass one of them")
    if controller is not None and task is None:
        raise InvalidArgumentError("controller needs a task to run (task=NAME)")
    if ctrl_trajectory is not None:
        return trajectory_controls(ctrl_trajectory, config, scene)
    if task is not None:
        found = task_controls(task, config, controller)
        if scene is None:
            return found
        model = load_scene(scene)
        for key in ("nq", "nv", "na", "nu"):
            if getattr(model, key) != getattr(found.model, key):
                raise InvalidArgumentError(
                    f"scene has {key}={getattr(model, key)}, but task {task!r} has "
                    f"{key}={getattr(found.model, key)}: its controls cannot be replayed there"
                )
        return found._replace(model=model, scene=str(scene))
    if scene is None:
        raise InvalidArgumentError(
            "scene is required (an MJCF path or 'menagerie:NAME') unless task or "
            "ctrl_trajectory gives the model"
        )
    if isinstance(scene, str) and scene.startswith("task:"):
        return task_scene_controls(scene[len("task:") :], config)
    name = str(scene) if isinstance(scene, (str, Path)) else "model"
    return scene_controls(load_scene(scene), config, name)


def _model_info(model: mujoco.MjModel) -> dict:
    return {
        "nq": model.nq,
        "nv": model.nv,
        "na": model.na,
        "nu": model.nu,
        "nbody": model.nbody,
        "ngeom": model.ngeom,
        "timestep": float(model.opt.timestep),
        "integrator": mujoco.mjtIntegrator(model.opt.integrator).name,
        "solver": mujoco.mjtSolver(model.opt.solver).name,
        "cone": mujoco.mjtCone(model.opt.cone).name,
        "iterations": int(model.opt.iterations),
    }


@checked_keywords
def validate_scene(
    scene: str | Path | mujoco.MjModel | None = None,
    *,
    ctrl_trajectory: str | Path | None = None,
    task: str | None = None,
    controller: str | None = None,
    config: GatesConfig | None = None,
) -> GateReport:
    """Run the five MuJoCo-to-MJWarp gates on a scene and report.

    1. CPU baseline (:mod:`mpcbox.gates.cpu_baseline`);
    2. one-world MJWarp parity over time (:mod:`mpcbox.gates.parity`);
    3. contact and constraint capacity sizing, overflows flagged (:mod:`mpcbox.gates.capacity`);
    4. N worlds without per-step host copies (:mod:`mpcbox.gates.scaling`);
    5. throughput against the number of worlds (:mod:`mpcbox.gates.throughput`).

    Gate 1 always runs. When MJWarp is missing or cannot run the model, gates 2-5 are
    ``None`` and ``error`` says why; any gate that fails or did not run makes
    :attr:`GateReport.passed` false.

    Args:
        scene: An MJCF path, ``"menagerie:NAME"``, ``"task:NAME"`` (a registered task's
            model from its initial state) or a ``mujoco.MjModel``; optional when
            ``task`` or a trajectory that names its task gives the model.
        ctrl_trajectory: A trajectory saved by :func:`mpcbox.sim.trajectory_files.save_trajectory`
            (``NAME.csv``/``NAME.json``) whose applied controls are replayed.
        task: A registered task run in closed loop to record the controls.
        controller: The task's controller (default: the first tuned one that runs here).
        config: Options (:class:`~mpcbox.gates.config.GatesConfig`).

    Returns:
        A :class:`~mpcbox.gates.report.GateReport`.

    Raises:
        InvalidArgumentError: For bad arguments (the message names the argument).
        BackendUnavailableError: If ``config.device`` asks for CUDA and none is available.
    """
    if config is None:
        config = GatesConfig()
    if not isinstance(config, GatesConfig):
        raise InvalidTypeError(f"config must be a GatesConfig, got {type(config).__name__}")
    for name, value in (("task", task), ("controller", controller)):
        if value is not None and not isinstance(value, str):
            raise InvalidTypeError(f"{name} must be a name (a string), got {value!r}")
    inputs = gate_input(
        scene, config, ctrl_trajectory=ctrl_trajectory, task=task, controller=controller
    )
    device = _device(config.device)
    cpu = run_cpu_baseline(inputs)
    report = GateReport(
        scene=inputs.scene,
        source=inputs.source,
        notes=inputs.notes,
        model=_model_info(inputs.model),
        device=None,
        config=dataclasses.asdict(config),
        cpu=cpu,
        parity=None,
        capacity=None,
        scaling=None,
        throughput=None,
        error=None,
    )
    if device is None:
        return report._replace(error="MuJoCo Warp is not installed (pip install mpcbox[gpu])")
    if cpu.steps == 0:
        return report._replace(error="the CPU baseline diverged on its first step")
    try:
        return _warp_gates(report, inputs, config, device)
    except Exception as exc:  # report what ran; the message says where MJWarp stopped
        detail = traceback.format_exception_only(type(exc), exc)[-1].strip()
        return report._replace(
            error=f"MJWarp gates stopped: {detail}", error_traceback=traceback.format_exc()
        )


def _device(device: str | None) -> str | None:
    try:
        import mujoco_warp  # noqa: F401
        import warp  # noqa: F401
    except ImportError:
        return None
    from mpcbox.controllers.sampling.backends.warp import resolve_device

    if device is None:
        import warp as wp

        return "cuda:0" if wp.is_cuda_available() else "cpu"
    return resolve_device(device)


def _warp_gates(
    report: GateReport, inputs: GateInput, config: GatesConfig, device: str
) -> GateReport:
    from mpcbox.gates.capacity import capacity_gate, check_run, size_capacity
    from mpcbox.gates.device import device_info
    from mpcbox.gates.parity import run_parity
    from mpcbox.gates.scaling import run_scaling, scaling_worlds
    from mpcbox.gates.throughput import measure_first_call, run_throughput
    from mpcbox.gates.warp_worlds import WarpScene

    report = report._replace(device=device_info(device))
    cpu = report.cpu
    scene = WarpScene(inputs.model, inputs.ctrls[: cpu.steps], device)
    generous = (max(64, 4 * int(cpu.ncon.max(initial=0))), max(256, 4 * int(cpu.nefc.max())))
    first_call = measure_first_call(scene, inputs, *generous)
    parity = run_parity(scene, inputs, cpu, config)
    sizing = size_capacity(cpu, parity, config)
    worlds = config.worlds or (GPU_WORLDS if device.startswith("cuda") else CPU_WORLDS)
    scaling = run_scaling(scene, inputs, parity, sizing, config, scaling_worlds(config, worlds))
    checks = [check_run(f"scaling N={scaling.nworld}", scaling.counts, sizing.nconmax,
                        sizing.njmax)]  # fmt: skip
    throughput = run_throughput(scene, inputs, sizing, config, worlds, first_call)
    checks += [
        check_run(f"throughput N={r.nworld}", r.counts, sizing.nconmax, sizing.njmax,
                  counted=False)
        for r in throughput.rows
    ]  # fmt: skip
    config_dict = {**report.config, "worlds": list(worlds), "device": device}
    return report._replace(
        config=config_dict,
        parity=parity,
        capacity=capacity_gate(sizing, checks),
        scaling=scaling,
        throughput=throughput,
    )


__all__ = ["gate_input", "validate_scene"]
