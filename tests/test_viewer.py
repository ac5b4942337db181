"""Viewers of running simulations (mpcbox.sim.viewer and friends).

The loop side is tested in this process with a viewer that only records what it is given;
the offscreen video needs an OpenGL context, which MuJoCo picks on import, so it runs in a
subprocess per backend (as in test_video.py) and skips where none works.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import mujoco
import numpy as np
import pytest

from mpcbox.errors import BackendUnavailableError, InvalidArgumentError, InvalidTypeError
from mpcbox.registry import make_controller, task_class
from mpcbox.sim.live_viewer import LiveViewer, display_missing
from mpcbox.sim.offscreen_viewer import OffscreenViewer
from mpcbox.sim.realtime import simulate_realtime
from mpcbox.sim.simulation import simulate
from mpcbox.sim.viewer import Viewer
from mpcbox.sim.viewer_choice import as_viewer, make_viewer

ROOT = Path(__file__).resolve().parents[1]
SMALL = {"num_samples": 16, "horizon": 0.2}


class Recorder(Viewer):
    """Keeps, per frame, the time, the traced site's position and the trace drawn."""

    def open(self, problem, controller) -> None:
        self.tip = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, "tip")
        self.seen: list[tuple[float, np.ndarray, object]] = []
        self.closed = False

    def draw(self, trace) -> None:
        self.seen.append((float(self.data.time), self.data.site_xpos[self.tip].copy(), trace))

    def close(self) -> None:
        self.closed = True


@pytest.fixture(scope="module")
def problem():
    return task_class("cartpole_swingup")()


def test_simulate_feeds_the_viewer_the_current_plan(problem) -> None:
    ctrl = make_controller("ps", problem, **SMALL)
    plain = simulate(problem, ctrl, 0.2)
    view = Recorder(fps=50.0, traces=4)
    watched = simulate(problem, ctrl, 0.2, viewer=view)
    np.testing.assert_array_equal(watched.states, plain.states)  # the viewer changes nothing
    assert view.closed and view.frames == len(view.seen) == 10  # t = 0, 0.02, ..., 0.18
    times = [t for t, _, _ in view.seen]
    np.testing.assert_allclose(times, np.arange(10) * 0.02, atol=1e-9)
    for t, tip, trace in view.seen:
        # the controller ran at this very state just before the frame
        assert trace is not None and trace.time == pytest.approx(t)
        assert trace.positions.shape[0] == 4
        np.testing.assert_allclose(trace.positions[:, 0], np.tile(tip, (4, 1)), atol=1e-9)
        assert np.all(np.diff(trace.costs) >= 0.0)
    assert ctrl.trace_recorder is None  # the viewer turned recording off again


def test_a_viewer_with_no_traces_leaves_recording_off(problem) -> None:
    ctrl = make_controller("ps", problem, **SMALL)
    view = Recorder(fps=20.0, traces=0)
    simulate(problem, ctrl, 0.1, viewer=view)
    assert view.frames == 2 and all(trace is None for _, _, trace in view.seen)
    assert ctrl.trace_recorder is None and ctrl.stats["ticks"] == 10
    # a non-sampling controller: the world only
    lqr_view = Recorder(fps=20.0)
    simulate(problem, make_controller("lqr", problem), 0.1, viewer=lqr_view)
    assert lqr_view.frames == 2 and all(trace is None for _, _, trace in lqr_view.seen)


def test_realtime_loop_draws_the_planner_traces(problem) -> None:
    ctrl = make_controller("ps", problem, **SMALL)
    view = Recorder(fps=20.0, traces=3)
    res = simulate_realtime(problem, ctrl, 0.2, viewer=view, speed=0.5)
    assert view.closed and view.frames == 4 and res.realtime.ticks > 0
    traces = [trace for _, _, trace in view.seen]
    assert all(trace is not None and trace.positions.shape[0] == 3 for trace in traces)
    # each frame shows a plan made no later than the frame
    assert all(trace.time <= t + 1e-9 for (t, _, _), trace in zip(view.seen, traces))
    assert ctrl.trace_recorder is None


def test_viewer_arguments_are_named_errors(problem, tmp_path, monkeypatch) -> None:
    ctrl = make_controller("lqr", problem)
    with pytest.raises(InvalidTypeError, match="viewer must be"):
        simulate(problem, ctrl, 0.1, viewer=42)
    with pytest.raises(InvalidArgumentError, match="viewer must be"):
        simulate(problem, ctrl, 0.1, viewer=str(tmp_path / "run.avi"))
    with pytest.raises(InvalidArgumentError, match=r"\.mp4 or \.gif"):
        OffscreenViewer(tmp_path / "run.txt")
    with pytest.raises(InvalidArgumentError, match="mode must be one of"):
        make_viewer(tmp_path / "run.gif", mode="window")
    with pytest.raises(InvalidArgumentError, match="traces"):
        Recorder(traces=-1)
    with pytest.raises(InvalidArgumentError, match="fps"):
        OffscreenViewer(tmp_path / "run.gif", fps=0.0)
    assert isinstance(as_viewer(tmp_path / "run.gif"), OffscreenViewer)


def test_no_display_is_a_named_error_before_any_window(problem, tmp_path, monkeypatch) -> None:
    """MuJoCo's viewer ends the process without a display: the check must come first."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    assert "DISPLAY" in display_missing()
    with pytest.raises(BackendUnavailableError, match=r"DISPLAY.*offscreen"):
        make_viewer(mode="live")
    with pytest.raises(BackendUnavailableError, match="needs a display"):
        simulate(problem, make_controller("ps", problem, **SMALL), 0.05, viewer=LiveViewer())
    with pytest.raises(InvalidArgumentError, match="path is needed"):
        make_viewer(None, mode="auto")
    chosen = make_viewer(tmp_path / "run.gif", mode="auto", traces=2, width=64)
    assert isinstance(chosen, OffscreenViewer) and "DISPLAY" in chosen.note
    monkeypatch.setenv("DISPLAY", ":0")
    assert isinstance(make_viewer(tmp_path / "run.gif", width=64), LiveViewer)


class FakeWindow:
    """What ``mujoco.viewer.launch_passive`` returns, without a window."""

    def __init__(self, model, data, **_):
        import contextlib
        import threading

        self.cam = mujoco.MjvCamera()
        self.user_scn = mujoco.MjvScene(model, maxgeom=1000)
        self.lock = lambda: contextlib.nullcontext(threading.Lock())
        self.syncs = 0
        self.most_geoms = 0

    def is_running(self) -> bool:
        return True

    def sync(self) -> None:
        self.syncs += 1
        self.most_geoms = max(self.most_geoms, self.user_scn.ngeom)

    def close(self) -> None:
        pass


def test_live_window_frames_the_model_and_draws_the_traces(problem, monkeypatch) -> None:
    """Tried for real under Xvfb (docs/tutorials/img/live_viewer_cartpole.png); here the
    window is a stand-in: it gets MuJoCo's free camera of the whole model (its own default
    left the cart-pole's pole out of view) and the planner's traces in its scene."""
    import mujoco.viewer

    from mpcbox.sim.rendering import free_camera

    windows = []

    def launch(model, data, **kw):
        windows.append(FakeWindow(model, data, **kw))
        return windows[-1]

    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.setattr(mujoco.viewer, "launch_passive", launch)
    viewer = LiveViewer(traces=4, realtime=False)
    simulate(problem, make_controller("ps", problem, **SMALL), 0.2, viewer=viewer)
    (window,) = windows
    want = free_camera(problem.model)
    np.testing.assert_allclose(window.cam.lookat, want.lookat)
    assert window.cam.distance == pytest.approx(want.distance)
    assert window.cam.type == mujoco.mjtCamera.mjCAMERA_FREE  # a fixed base: no tracking
    assert window.syncs > 0 and window.most_geoms > 0


VIDEO = """
import sys
import mujoco
import numpy as np
from mpcbox.registry import make_controller, task_class
from mpcbox.sim.offscreen_viewer import OffscreenViewer
from mpcbox.sim.simulation import simulate
problem = task_class("cartpole_swingup")()
swinging = np.array([0.0, 1.0, 0.0, 4.0])  # the pole at 1 rad, swinging up: long traces
for traces, style, path in zip((8, 8, 0), ("line", "capsule", "line"), sys.argv[1:]):
    ctrl = make_controller("ps", problem, num_samples=16, horizon=0.6)
    cam = mujoco.MjvCamera()  # close, from the side
    cam.lookat[:], cam.distance, cam.azimuth, cam.elevation = (0.3, 0, 0.8), 2.0, 90, -5
    view = OffscreenViewer(
        path, fps=10, width=160, height=120, camera=cam, traces=traces, style=style, radius=0.02
    )
    simulate(problem, ctrl, 0.3, viewer=view, initial_state=swinging)
"""


def _python(code: str, *args: str, gl: str, display: str | None = None):
    env = {**os.environ, "MUJOCO_GL": gl, "PYTHONPATH": str(ROOT)}
    env.pop("DISPLAY", None)
    env.pop("WAYLAND_DISPLAY", None)
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code), *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=180,
        check=False,
    )


def _green(frame: np.ndarray) -> np.ndarray:
    """Pixels of the best trace's colour (nothing else in the cart-pole scene is green)."""
    r, g, b = frame[..., 0], frame[..., 1], frame[..., 2]
    return (g > 140) & (g > r + 60) & (g > b + 60)


def test_offscreen_video_draws_the_traces(tmp_path) -> None:
    from PIL import Image

    paths = [tmp_path / f"{name}.gif" for name in ("lines", "capsules", "plain")]
    reasons = []
    for gl in ("egl", "osmesa"):
        proc = _python(VIDEO, *map(str, paths), gl=gl)
        if proc.returncode == 0:
            break
        reasons.append(f"MUJOCO_GL={gl}: {proc.stderr.strip().splitlines()[-1]}")
    else:
        pytest.skip("no offscreen GL backend here: " + "; ".join(reasons))
    *traced, plain = (Image.open(p) for p in paths)
    for gif in traced:
        assert gif.n_frames == plain.n_frames == 3  # t = 0, 0.1, 0.2
        for i in range(3):
            gif.seek(i)
            plain.seek(i)
            a = np.asarray(gif.convert("RGB")).astype(int)
            b = np.asarray(plain.convert("RGB")).astype(int)
            assert a.shape == b.shape == (120, 160, 3)
            scene = slice(20, None)  # below the caption
            assert _green(a[scene]).sum() > 30, (gif.filename, i)
            assert _green(b[scene]).sum() == 0, i
            assert np.abs(a[scene] - b[scene]).max() > 100


def test_neither_window_nor_context_is_one_named_error(tmp_path) -> None:
    proc = _python(
        """
        import sys
        from mpcbox.errors import BackendUnavailableError
        from mpcbox.registry import make_controller, task_class
        from mpcbox.sim.simulation import simulate
        from mpcbox.sim.viewer_choice import make_viewer
        problem = task_class("cartpole_swingup")()
        ctrl = make_controller("ps", problem, num_samples=8, horizon=0.1)
        try:
            simulate(problem, ctrl, 0.05, viewer=make_viewer(sys.argv[1]))
        except BackendUnavailableError as exc:
            print("named:", exc)
        print("recording:", ctrl.trace_recorder)
        """,
        str(tmp_path / "x.gif"),
        gl="disable",
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("named:"), proc.stdout
    assert "DISPLAY" in proc.stdout and "MUJOCO_GL='disable'" in proc.stdout
    assert "recording: None" in proc.stdout  # the failed start turned recording off again


def test_cli_viewer_writes_a_video_without_a_display(tmp_path) -> None:
    from PIL import Image

    argv = ["simulate", "cartpole_swingup", "--controller", "ps", "--duration", "0.1"]
    argv += ["--viewer", "--viewer-fps", "20", "--out", str(tmp_path)]
    code = "import sys; from mpcbox.cli import main; sys.exit(main(sys.argv[1:]))"
    reasons = []
    for gl in ("egl", "osmesa"):
        proc = _python(code, *argv, gl=gl)
        if proc.returncode == 0:
            break
        reasons.append(f"MUJOCO_GL={gl}: {proc.stderr.strip()[-200:]}")
        assert proc.returncode == 2 and "MUJOCO_GL" in proc.stderr, proc.stderr
    else:
        pytest.skip("no offscreen GL backend here: " + "; ".join(reasons))
    assert "2 viewer frames" in proc.stdout and "viewer.gif" in proc.stdout
    assert Image.open(tmp_path / "viewer.gif").n_frames == 2


def test_cli_viewer_errors_are_one_line(tmp_path, monkeypatch, capsys) -> None:
    from mpcbox.cli import main

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    base = ["simulate", "cartpole_swingup", "--controller", "ps", "--duration", "0.05"]
    base += ["--out", str(tmp_path)]
    for flags, text in (
        (["--viewer", "live"], "needs a display"),
        (["--viewer", str(tmp_path / "run.avi")], ".mp4 or .gif"),
        (["--viewer", "--viewer-traces", "-1"], "--viewer-traces"),
    ):
        assert main([*base, *flags]) == 2
        err = capsys.readouterr().err
        assert err.startswith("error:") and text in err and "Traceback" not in err
