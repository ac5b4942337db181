r"""What the gates replay: a model, its start state and a control sequence (:class:`GateInput`).

The controls come from one of three places:

* a trajectory saved by :func:`mpcbox.sim.trajectory_files.save_trajectory` (its applied controls
  ``ctrls[:-1]`` from its initial state; the model is the given scene, or the task the
  trajectory names);
* a registered task run in closed loop by one of its tuned controllers
  (:func:`mpcbox.simulate`), whose applied controls are then replayed open loop;
* a registered task's model (scene ``"task:NAME"``) from its initial state, with its
  reference control held;
* the scene alone: a held keyframe control, a walk through the keyframes' controls, or zeros
  (:data:`~mpcbox.gates.config.CONTROL_MODES`).

Open-loop replay of recorded controls is what makes the CPU and MJWarp runs comparable:
both get exactly the same :math:`u_k` at every step ``k``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.model import compile_spec, load_spec, object_id
from mpcbox.errors import (
    InvalidArgumentError,
    InvalidTypeError,
    ModelLoadError,
    ModelNotFoundError,
)
from mpcbox.gates.config import GatesConfig

#: Simulated seconds when neither ``duration`` nor a trajectory sets the length.
DEFAULT_DURATION = 2.0


class GateInput(NamedTuple):
    """A scene with the controls the gates replay on it (``T`` steps).

    Attributes:
        model: The MuJoCo model (float64 CPU reference).
        initial_state: Start state ``(nq + nv + na,)``, ``[qpos, qvel, act]``.
        ctrls: Controls ``(T, nu)``; step ``k`` applies ``ctrls[k]``.
        source: Where the controls came from, in words.
        scene: The scene's name as given (a path, ``menagerie:NAME`` or ``task:NAME``).
        notes: Remarks for the report (pushes that are not replayed, a task's failure, ...).
        mocap_pos: Mocap body positions ``(nmocap, 3)`` at the start (a keyframe's), or
            ``None`` for the model's.
        mocap_quat: Mocap body orientations ``(nmocap, 4)`` at the start, or ``None``.
    """

    model: mujoco.MjModel
    initial_state: np.ndarray
    ctrls: np.ndarray
    source: str
    scene: str
    notes: tuple[str, ...] = ()
    mocap_pos: np.ndarray | None = None
    mocap_quat: np.ndarray | None = None

    @property
    def steps(self) -> int:
        """Number of steps ``T``."""
        return int(self.ctrls.shape[0])


def load_scene(scene: str | Path | mujoco.MjModel) -> mujoco.MjModel:
    """The model of ``scene``: an MJCF path, ``"menagerie:NAME"`` or a compiled model.

    Raises:
        InvalidTypeError: If ``scene`` is none of these.
        ModelNotFoundError: If the file does not exist.
        ModelLoadError: If MuJoCo cannot load it.
    """
    if isinstance(scene, mujoco.MjModel):
        return scene
    if not isinstance(scene, (str, Path)):
        raise InvalidTypeError(
            f"scene must be an MJCF path, 'menagerie:NAME' or a mujoco.MjModel, got "
            f"{type(scene).__name__}"
        )
    try:
        return compile_spec(load_spec(scene))
    except (ModelNotFoundError, ModelLoadError) as exc:
        text = str(exc).removeprefix("model: ")
        raise type(exc)(f"scene: {text}") from exc


def _state(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    return np.concatenate([data.qpos, data.qvel, data.act]).astype(np.float64)


def _keyframe_id(model: mujoco.MjModel, keyframe: int | str | None) -> int | None:
    if keyframe is None:
        return 0 if model.nkey else None
    return object_id(model, "keyframe", keyframe, argument="keyframe")


def _steps(model: mujoco.MjModel, duration: float) -> int:
    return max(1, round(duration / model.opt.timestep))


def scene_controls(model: mujoco.MjModel, config: GatesConfig, scene: str = "scene") -> GateInput:
    """Controls from the scene alone (``config.controls``), from ``config.keyframe``."""
    data = mujoco.MjData(model)
    key = _keyframe_id(model, config.keyframe)
    if key is not None:
        mujoco.mj_resetDataKeyframe(model, data, key)
    steps = _steps(model, config.duration or DEFAULT_DURATION)
    start = f"keyframe {key}" if key is not None else "qpos0"
    if config.controls == "keyframes" and model.nkey < 2:
        raise InvalidArgumentError(
            f"controls='keyframes' walks through the keyframes' controls, and the model has "
            f"{model.nkey} keyframe(s): use 'hold' or 'zero'"
        )
    if config.controls == "zero" or model.nu == 0:
        ctrls = np.zeros((steps, model.nu))
        source = f"zero controls from {start}"
    elif config.controls == "hold" or model.nkey < 2:
        ctrls = np.repeat(data.ctrl[None, :].astype(np.float64), steps, axis=0)
        source = f"held ctrl of {start}" if key is not None else "zero controls from qpos0"
    else:
        # Piecewise-linear through the keyframes' ctrl, starting at the start keyframe's.
        order = [key or 0] + [k for k in range(model.nkey) if k != (key or 0)]
        knots = np.asarray([model.key_ctrl[k] for k in order], dtype=np.float64)
        times = np.linspace(0.0, 1.0, len(order))
        frac = np.arange(steps) / max(steps - 1, 1)
        ctrls = np.stack([np.interp(frac, times, knots[:, j]) for j in range(model.nu)], axis=1)
        source = f"linear walk through the ctrl of keyframes {order} from {start}"
    return GateInput(
        model,
        _state(model, data),
        ctrls,
        source,
        scene,
        mocap_pos=data.mocap_pos.copy() if model.nmocap else None,
        mocap_quat=data.mocap_quat.copy() if model.nmocap else None,
    )


def trajectory_controls(
    path: str | Path,
    config: GatesConfig,
    scene: str | Path | mujoco.MjModel | None = None,
) -> GateInput:
    """The applied controls of a saved trajectory, on ``scene`` or on the task it names.

    Raises:
        InvalidArgumentError: If the files cannot be read, the trajectory names no task and
            no scene is given, or the scene's sizes or timestep differ from the recorded ones.
    """
    from mpcbox.registry import TASKS, task_class
    from mpcbox.sim.trajectory_files import load_trajectory

    try:
        traj = load_trajectory(path)
    except InvalidArgumentError as exc:
        raise InvalidArgumentError(f"ctrl_trajectory: {exc}") from exc
    notes: list[str] = []
    named = isinstance(scene, str) and scene.startswith("task:")
    if scene is None or named:
        # The task named by the scene, else the one the trajectory ran (its task, or the
        # Problem's name when that is a registered task).
        task = scene[len("task:") :] if named else traj.metadata.get("task") or traj.problem
        if not task or task not in TASKS:
            raise InvalidArgumentError(
                f"ctrl_trajectory {str(path)!r} names no registered task: give the scene it ran on"
            )
        problem = task_class(task)(**dict(traj.metadata.get("task_options") or {}))
        model, name = problem.model, f"task:{task}"
    else:
        model = load_scene(scene)
        name = scene if isinstance(scene, (str, Path)) else "model"
    if traj.mismatch is not None:
        model = traj.mismatch.apply(model)
        notes.append("the trajectory's model mismatch is applied to the scene")
    sizes = {"nq": model.nq, "nv": model.nv, "na": model.na, "nu": model.nu}
    sizes["timestep"] = float(model.opt.timestep)
    for key, value in sizes.items():
        saved = traj.metadata.get(key)
        if saved is not None and not math.isclose(float(saved), float(value)):
            raise InvalidArgumentError(
                f"ctrl_trajectory was recorded with {key}={saved}, but the scene has "
                f"{key}={value}: give the scene it ran on"
            )
    ctrls = np.asarray(traj.ctrls[:-1], dtype=np.float64)
    if len(ctrls) == 0:
        raise InvalidArgumentError(f"ctrl_trajectory {str(path)!r} holds no applied control")
    if config.duration is not None:
        steps = _steps(model, config.duration)
        if steps > len(ctrls):
            notes.append(f"the last control is held for {steps - len(ctrls)} steps after the end")
            ctrls = np.vstack([ctrls, np.repeat(ctrls[-1:], steps - len(ctrls), axis=0)])
        ctrls = ctrls[:steps]
    if traj.pushes:
        notes.append(f"{len(traj.pushes)} push(es) of the trajectory are not replayed")
    source = f"trajectory {str(path)!r} ({traj.problem}, {traj.controller}, seed {traj.seed})"
    return GateInput(model, traj.initial_state.copy(), ctrls, source, str(name), tuple(notes))


def task_scene_controls(task: str, config: GatesConfig) -> GateInput:
    """A registered task's model from its initial state, without running a controller.

    ``config.controls`` ``"hold"`` keeps the task's reference control ``ctrl_ref``;
    ``"zero"`` applies zeros; ``"keyframes"`` walks the model's keyframes as
    :func:`scene_controls` does (from ``config.keyframe``).
    """
    from mpcbox.registry import task_class

    problem = task_class(task)()
    name = f"task:{task}"
    if config.controls == "keyframes":
        return scene_controls(problem.model, config, name)
    steps = _steps(problem.model, config.duration or DEFAULT_DURATION)
    hold = config.controls == "hold"
    ctrl = np.asarray(problem.ctrl_ref if hold else np.zeros(problem.nu), dtype=np.float64)
    what = "reference control held" if hold else "zero controls"
    return GateInput(
        problem.model,
        np.asarray(problem.initial_state(), dtype=np.float64).copy(),
        np.repeat(ctrl[None, :], steps, axis=0),
        f"task {task!r}: {what} from its initial state",
        name,
    )


def task_controls(task: str, config: GatesConfig, controller: str | None = None) -> GateInput:
    """Run ``task`` in closed loop with ``controller`` and keep its applied controls.

    Args:
        task: A registered task name (``mpcbox list``).
        config: Gate options (``duration``; 2 s when ``None``).
        controller: A controller tuned for the task; default: the first that imports here.

    Raises:
        UnknownNameError: For an unknown task or controller (lists the valid ones).
    """
    from mpcbox.registry import available_controllers, make_controller, task_class
    from mpcbox.sim.simulation import simulate

    problem = task_class(task)()
    names = available_controllers(problem)
    if controller is None:
        if not names:
            raise InvalidArgumentError(f"task {task!r} has no controller that runs here")
        controller = names[0]
    ctrl = make_controller(controller, problem)
    result = simulate(problem, ctrl, config.duration or DEFAULT_DURATION)
    notes = []
    if result.failure:
        notes.append(f"the closed-loop run stopped early: {result.failure}")
    ctrls = np.asarray(result.ctrls[:-1], dtype=np.float64)
    if len(ctrls) == 0:
        raise InvalidArgumentError(f"task {task!r}: the closed-loop run applied no control")
    source = f"task {task!r} in closed loop with {controller!r} ({result.metrics.outcome})"
    return GateInput(
        problem.model, result.states[0].copy(), ctrls, source, f"task:{task}", tuple(notes)
    )


__all__ = [
    "DEFAULT_DURATION",
    "GateInput",
    "load_scene",
    "scene_controls",
    "task_controls",
    "task_scene_controls",
    "trajectory_controls",
]
