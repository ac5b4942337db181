"""Offscreen videos: frames with push markers where a GL backend exists, a named error where
none does.

MuJoCo reads ``MUJOCO_GL`` once, on import, so each backend is tried in a subprocess.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from mpcbox.errors import BackendUnavailableError, InvalidArgumentError
from mpcbox.registry import make_controller, task_class
from mpcbox.sim.disturbances import Push
from mpcbox.sim.simulation import simulate
from mpcbox.sim.trajectory import trajectory_from_result
from mpcbox.sim.trajectory_files import save_trajectory
from mpcbox.sim.video import check_video_path

ROOT = Path(__file__).resolve().parents[1]
PUSH = Push(force=(3.0, 0.0, 0.0), start=0.2, duration=0.2, body="pole")
FPS = 10.0


@pytest.fixture(scope="module")
def saved(tmp_path_factory) -> Path:
    problem = task_class("pendulum_swingup")()
    result = simulate(problem, make_controller("lqr", problem), 0.6, pushes=(PUSH,))
    traj = trajectory_from_result(result, problem, metadata={"task": "pendulum_swingup"})
    return save_trajectory(traj, tmp_path_factory.mktemp("video") / "run")[0]


RENDER = """
import sys
from mpcbox.registry import task_class
from mpcbox.sim.trajectory_files import load_trajectory
from mpcbox.sim.video import render_video
problem = task_class("pendulum_swingup")()
render_video(load_trajectory(sys.argv[1]), problem, sys.argv[2], fps={fps}, width=96, height=64)
"""


def _python(code: str, *args: str, gl: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "MUJOCO_GL": gl, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code), *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def test_gif_frames_mark_the_push(saved, tmp_path) -> None:
    from PIL import Image

    reasons = []
    for gl in ("egl", "osmesa"):
        out = tmp_path / f"run_{gl}.gif"
        proc = _python(RENDER.format(fps=FPS), str(saved), str(out), gl=gl)
        if proc.returncode == 0:
            break
        reasons.append(f"MUJOCO_GL={gl}: {proc.stderr.strip().splitlines()[-1]}")
    else:
        pytest.skip("no offscreen GL backend here: " + "; ".join(reasons))
    gif = Image.open(out)
    assert gif.n_frames == int(0.6 * FPS + 1e-6) + 1
    times = np.arange(gif.n_frames) / FPS
    for i, t in enumerate(times):
        gif.seek(i)
        frame = np.asarray(gif.convert("RGB")).astype(int)
        corner = frame[2, 2]
        red = corner[0] > 150 and corner[1] < 90 and corner[2] < 90
        active = PUSH.active(t + 1e-9)
        assert red == active, (i, t, corner)
        assert frame.shape == (64, 96, 3) and frame[20:, 10:-10].std() > 1.0  # a scene


def test_no_gl_context_is_a_named_error(saved, tmp_path) -> None:
    proc = _python(
        """
        import sys
        from mpcbox.errors import BackendUnavailableError
        from mpcbox.registry import task_class
        from mpcbox.sim.trajectory_files import load_trajectory
        from mpcbox.sim.video import render_video
        problem = task_class("pendulum_swingup")()
        try:
            render_video(load_trajectory(sys.argv[1]), problem, sys.argv[2])
        except BackendUnavailableError as exc:
            print("named:", exc)
        """,
        str(saved),
        str(tmp_path / "x.gif"),
        gl="disable",
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("named:") and "MUJOCO_GL='disable'" in proc.stdout
    assert "egl" in proc.stdout and "osmesa" in proc.stdout


def test_cli_without_gl_exits_2_with_one_line(saved, tmp_path) -> None:
    proc = _python(
        "import sys; from mpcbox.cli import main; sys.exit(main(sys.argv[1:]))",
        "replay",
        str(saved),
        "--video",
        str(tmp_path / "x.gif"),
        gl="disable",
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("error:") and "MUJOCO_GL" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_video_paths_are_checked_before_rendering(tmp_path) -> None:
    with pytest.raises(InvalidArgumentError, match=r"\.mp4 or \.gif"):
        check_video_path(tmp_path / "run.avi")
    assert check_video_path(tmp_path / "run.GIF") == ".gif"
    try:
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        with pytest.raises(BackendUnavailableError, match="imageio-ffmpeg"):
            check_video_path(tmp_path / "run.mp4")
    else:
        assert check_video_path(tmp_path / "run.mp4") == ".mp4"
