r"""Options of the MuJoCo-to-MJWarp validation gates (:class:`GatesConfig`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.validation import (
    checked_options,
    in_range,
    integer,
    non_negative,
    one_of,
    positive,
    positive_int,
)
from mpcbox.validation import seed as check_seed

#: What is applied when no trajectory or task gives the controls.
CONTROL_MODES: tuple[str, ...] = ("hold", "keyframes", "zero")

#: Default ``worlds`` on a CUDA device and on warp's CPU device.
GPU_WORLDS: tuple[int, ...] = (256, 1024, 2048, 4096, 8192)
CPU_WORLDS: tuple[int, ...] = (2, 4)


@checked_options
@dataclass(frozen=True, kw_only=True)
class GatesConfig:
    r"""Options of :func:`~mpcbox.gates.validate_scene`.

    Attributes:
        duration: Simulated seconds of the CPU baseline and the parity run; ``None`` means the
            length of the given trajectory, or 2 s otherwise.
        controls: Controls when neither a trajectory nor a task gives them: ``"hold"`` keeps
            the keyframe's ``ctrl`` (zero without keyframes), ``"keyframes"`` moves
            linearly through the ``ctrl`` of every keyframe in turn (an equal share of the
            duration each, starting from ``keyframe``'s state), ``"zero"`` applies zeros.
        keyframe: Keyframe (index or name) the run starts from; ``None``: the first keyframe
            when the model has one, else ``qpos0`` at rest.
        device: Warp device, ``"cpu"``, ``"cuda"`` or ``"cuda:<index>"``; ``None``: CUDA
            when Warp sees a GPU, else warp's CPU device.
        worlds: World counts of the throughput gate, e.g. ``(256, 1024, 4096, 8192)``;
            ``None``: :data:`GPU_WORLDS` on CUDA, :data:`CPU_WORLDS` on the CPU.
        scaling_worlds: Worlds of the N-world gate; ``None``: the largest of ``worlds``.
        parity_tolerance: Largest :math:`\max_i |q^{\text{warp}}_{k,i} - q^{\text{cpu}}_{k,i}|`
            (rad or m) that counts as the same motion.
        parity_window: Seconds from the start during which the one-world MJWarp run must stay
            within ``parity_tolerance`` (the whole run when shorter); contact-rich scenes
            drift apart chaotically after that (MJWarp is float32, MuJoCo float64), which
            the report shows as the time until the tolerance is exceeded.
        headroom: Suggested capacities are ``ceil(headroom * observed maximum)``.
        nconmax: Contacts per world for the N-world and throughput runs; ``None``: the
            suggested capacity. A value below what the scene needs makes an overflow,
            which fails the capacity gate.
        njmax: Constraint rows per world, as ``nconmax``.
        perturbation: Standard deviation of the noise on the initial ``qvel`` (rad/s or m/s)
            and on hinge and slide ``qpos`` (rad or m) of worlds ``1 .. N-1`` (world 0
            starts unperturbed).
        seed: Seed of that noise.
        throughput_steps: Steps timed per world count (in blocks of ``block_steps``).
        block_steps: Steps per launch block (the CUDA graph holds this many steps).
    """

    duration: float | None = None
    controls: str = "hold"
    keyframe: int | str | None = None
    device: str | None = None
    worlds: tuple[int, ...] | None = None
    scaling_worlds: int | None = None
    parity_tolerance: float = 1e-3
    parity_window: float = 0.1
    headroom: float = 1.5
    nconmax: int | None = None
    njmax: int | None = None
    perturbation: float = 1e-3
    seed: int = 0
    throughput_steps: int = 200
    block_steps: int = 20

    def __post_init__(self) -> None:
        if self.duration is not None:
            positive("duration", self.duration)
        one_of("controls", self.controls, CONTROL_MODES)
        if self.keyframe is not None and not isinstance(self.keyframe, (int, str)):
            raise InvalidTypeError(
                f"keyframe must be an index, a name or None, got {type(self.keyframe).__name__}"
            )
        if self.device is not None and not isinstance(self.device, str):
            raise InvalidTypeError(f"device must be a string or None, got {self.device!r}")
        if self.worlds is not None:
            if isinstance(self.worlds, (str, bytes)) or not hasattr(self.worlds, "__iter__"):
                raise InvalidTypeError(
                    f"worlds must be a sequence of positive integers, got {self.worlds!r}"
                )
            worlds = tuple(positive_int("worlds", w) for w in self.worlds)
            if not worlds:
                raise InvalidArgumentError("worlds must hold at least one world count")
            object.__setattr__(self, "worlds", worlds)
        if self.scaling_worlds is not None:
            positive_int("scaling_worlds", self.scaling_worlds)
        positive("parity_tolerance", self.parity_tolerance)
        non_negative("parity_window", self.parity_window)
        in_range("headroom", self.headroom, 1.0, math.inf, low_open=False, high_open=True)
        for name in ("nconmax", "njmax"):
            if getattr(self, name) is not None:
                integer(name, getattr(self, name), 0)
        non_negative("perturbation", self.perturbation)
        check_seed("seed", self.seed)
        positive_int("throughput_steps", self.throughput_steps)
        positive_int("block_steps", self.block_steps)
        if self.throughput_steps < self.block_steps:
            raise InvalidArgumentError(
                f"throughput_steps must be at least block_steps ({self.block_steps}), the steps "
                f"of one launch block, got {self.throughput_steps}"
            )


__all__ = ["CONTROL_MODES", "CPU_WORLDS", "GPU_WORLDS", "GatesConfig"]
