r"""Cube stacking: put the red cube on the blue one, judged by the issue's success check.

After the cubes settle, with :math:`p_r, p_b` the cube centres,

.. math::
    e_{xy} = \|(p_r - p_b)_{xy}\| \le 0.015\ \text{m},\qquad
    0.035 \le \Delta z = (p_r - p_b)_z \le 0.055\ \text{m}.

For 44 mm cubes a perfect stack has :math:`e_{xy} = 0` and :math:`\Delta z = 0.044`.
"Settled" is checked too: both cubes slower than :data:`SETTLE_SPEED` at the end of the run.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import mujoco
import numpy as np

from mpcbox.core.problem import Problem
from mpcbox.errors import UnknownNameError
from mpcbox.tasks.manipulation.arms import ArmSpec, arm_spec
from mpcbox.tasks.manipulation.scene import (
    ARM_PREFIX,
    CUBE_SIZE,
    CubeLayout,
    default_layout,
    home_ctrl,
    home_qpos,
    stacking_scene,
)
from mpcbox.validation import as_array, positive

#: Largest horizontal centre-to-centre error of a stack (m).
XY_TOLERANCE = 0.015
#: Range of the vertical centre-to-centre separation of a stack (m).
DZ_RANGE = (0.035, 0.055)
#: Largest cube speed (m/s) at which the cubes count as settled.
SETTLE_SPEED = 0.02
#: Smallest distance between the start centres of the two cubes (m).
MIN_SEPARATION = 0.10


class StackCheck(NamedTuple):
    """The success check of one stack.

    Attributes:
        xy_err: Horizontal centre-to-centre distance (m).
        dz: Height of the red centre above the blue one (m).
        success: ``xy_err <= 0.015`` and ``0.035 <= dz <= 0.055``.
    """

    xy_err: float
    dz: float
    success: bool


def stack_check(red: np.ndarray, blue: np.ndarray) -> StackCheck:
    """The issue's success check for cube centres ``red`` and ``blue`` ``(3,)`` (m)."""
    red = as_array("red", red, (3,))
    blue = as_array("blue", blue, (3,))
    xy_err = float(np.linalg.norm(red[:2] - blue[:2]))
    dz = float(red[2] - blue[2])
    ok = xy_err <= XY_TOLERANCE and DZ_RANGE[0] <= dz <= DZ_RANGE[1]
    return StackCheck(xy_err, dz, bool(ok))


def random_layout(rng: np.random.Generator, arm: ArmSpec, *, spread: float = 0.7) -> CubeLayout:
    """Random start poses of the cubes in front of ``arm``.

    Each centre is drawn uniformly in the annular sector of radii ``arm.reach`` and bearing
    within ``±spread`` rad of the arm's forward direction, the two at least
    :data:`MIN_SEPARATION` apart; each yaw uniformly in :math:`[-\\pi/4, \\pi/4)` (all yaws,
    given the cube's symmetry).
    """
    near, far = arm.reach
    base = np.asarray(arm.mount[:2])
    while True:
        radius = np.sqrt(rng.uniform(near**2, far**2, size=2))
        bearing = arm.mount_yaw + rng.uniform(-spread, spread, size=2)
        xy = base + radius[:, None] * np.stack([np.cos(bearing), np.sin(bearing)], axis=1)
        if np.linalg.norm(xy[0] - xy[1]) >= MIN_SEPARATION:
            break
    yaw = rng.uniform(-np.pi / 4, np.pi / 4, size=2)
    return CubeLayout(
        red=(float(xy[0, 0]), float(xy[0, 1])),
        blue=(float(xy[1, 0]), float(xy[1, 1])),
        red_yaw=float(yaw[0]),
        blue_yaw=float(yaw[1]),
    )


class StackCubes(Problem):
    """Stack the red cube on the blue cube with an arm, from a (random) layout.

    The goal (:meth:`goal_failure`) is the issue's success check on the final state, with
    the cubes settled. :meth:`failure` stops a run whose cube fell off the table. Drive it
    with :func:`~mpcbox.tasks.manipulation.pick_place.stacking_controller`.

    Args:
        arm: Arm name (``"aloha"``, ``"panda"``) or :class:`~.arms.ArmSpec`.
        layout: Start poses of the cubes (default: :func:`~.scene.default_layout`).
        seed: Draw the layout with :func:`random_layout` from this seed instead.
        cube_size: Cube edge (m).
        cube_mass: Mass of each cube (kg).
        **kwargs: Passed to :class:`~mpcbox.Problem`.
    """

    name = "stack_cubes"

    def __init__(
        self,
        arm: str | ArmSpec = "aloha",
        *,
        layout: CubeLayout | None = None,
        seed: int | None = None,
        cube_size: float = CUBE_SIZE,
        cube_mass: float = 0.05,
        **kwargs: Any,
    ) -> None:
        source = arm_spec(arm) if isinstance(arm, str) else arm
        self.arm = source.prefixed(ARM_PREFIX)
        self.cube_size = positive("cube_size", cube_size)
        if seed is not None:
            layout = random_layout(np.random.default_rng(seed), self.arm)
        self.layout = default_layout(self.arm) if layout is None else layout
        spec = stacking_scene(source, cube_size=cube_size, cube_mass=cube_mass)
        super().__init__(spec, **kwargs)

    def prepare(self, model: mujoco.MjModel) -> None:
        self.qpos_ref = home_qpos(model, self.arm, self.layout, self.cube_size)
        self.ctrl_ref = home_ctrl(model, self.arm)
        self._cube_adr = {
            name: int(model.jnt_qposadr[model.joint(name + "_joint").id])
            for name in ("red_cube", "blue_cube")
        }
        self._cube_dof = {
            name: int(model.jnt_dofadr[model.joint(name + "_joint").id])
            for name in ("red_cube", "blue_cube")
        }

    def layout_state(self, layout: CubeLayout) -> np.ndarray:
        """The start state ``(nstate,)`` for ``layout``: arm at home, cubes at rest."""
        state = np.zeros(self.nstate)
        state[: self.nq] = home_qpos(self.model, self.arm, layout, self.cube_size)
        return state

    def trial_state(self, seed: int) -> np.ndarray:
        """The start state of trial ``seed``: a :func:`random_layout` drawn from it."""
        return self.layout_state(random_layout(np.random.default_rng(seed), self.arm))

    def initial_state(self) -> np.ndarray:
        return self.layout_state(self.layout)

    # ------------------------------------------------------------------ measures
    def cube_position(self, state: np.ndarray, cube: str) -> np.ndarray:
        """Centre ``(3,)`` of ``cube`` (``"red_cube"`` or ``"blue_cube"``) at ``state``
        ``(nstate,)``."""
        adr = self._cube_adr[self._cube_name(cube)]
        return as_array("state", state, (self.nstate,))[adr : adr + 3].copy()

    def cube_speed(self, state: np.ndarray, cube: str) -> float:
        """Linear speed of ``cube``'s centre at ``state`` ``(nstate,)`` (m/s)."""
        dof = self.nq + self._cube_dof[self._cube_name(cube)]
        state = as_array("state", state, (self.nstate,))
        return float(np.linalg.norm(state[dof : dof + 3]))

    def _cube_name(self, cube: str) -> str:
        if cube not in self._cube_adr:
            raise UnknownNameError("cube", cube, self._cube_adr, "cube")
        return cube

    def check(self, state: np.ndarray) -> StackCheck:
        """:func:`stack_check` of the cubes at ``state``."""
        return stack_check(
            self.cube_position(state, "red_cube"), self.cube_position(state, "blue_cube")
        )

    def failure(self, model: mujoco.MjModel, data: mujoco.MjData) -> str | None:
        """Non-finite state, or a cube below the table top (fell off)."""
        reason = super().failure(model, data)
        if reason is not None:
            return reason
        for cube, adr in self._cube_adr.items():
            if data.qpos[adr + 2] < -0.05:
                return f"the {cube.replace('_', ' ')} fell off the table"
        return None

    def goal_failure(self, time: np.ndarray, states: np.ndarray) -> str | None:
        """Why the run is not a stack, or ``None``: the success check at the final state.

        The reason says what went wrong: never lifted (a failed grasp), not settled, or the
        final ``xy_err`` and ``dz`` against their limits.

        Args:
            time: Times ``(T,)`` (s).
            states: States ``(T, nstate)``.
        """
        states = np.asarray(states)
        final = states[-1]
        check = self.check(final)
        moving = max(self.cube_speed(final, c) for c in self._cube_adr)
        if check.success and moving <= SETTLE_SPEED:
            return None
        adr = self._cube_adr["red_cube"]
        lifted = float(np.max(states[:, adr + 2]) - self.cube_size / 2)
        what = f"xy_err={1000 * check.xy_err:.1f} mm, dz={1000 * check.dz:.1f} mm"
        if lifted < 0.02:
            return f"red cube never lifted (grasp failed; rose {1000 * lifted:.0f} mm): {what}"
        if check.success:
            return f"cubes not settled ({moving:.3f} m/s > {SETTLE_SPEED} m/s): {what}"
        return (
            f"not stacked: {what} (need xy_err <= {1000 * XY_TOLERANCE:.0f} mm, "
            f"{1000 * DZ_RANGE[0]:.0f} <= dz <= {1000 * DZ_RANGE[1]:.0f} mm)"
        )
