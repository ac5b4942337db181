"""Shared fixtures: the Warp device for the sampling tests, skipping GPU tests, Menagerie
quadrupeds and the scripts of ``problems/``."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import pytest


def _cuda_available() -> bool:
    try:
        import warp as wp

        return bool(wp.is_cuda_available())
    except Exception:
        return False


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Skip tests marked ``gpu`` when Warp sees no CUDA device, and tests marked
    ``menagerie`` when no offline Menagerie copy (``MENAGERIE_ROOT``) is there: they never
    download robots."""
    root = os.environ.get("MENAGERIE_ROOT")
    if not (root and os.path.isdir(root)):
        skip = pytest.mark.skip(reason="needs an offline Menagerie copy in MENAGERIE_ROOT")
        for item in items:
            if "menagerie" in item.keywords:
                item.add_marker(skip)
    gpu_items = [item for item in items if "gpu" in item.keywords]
    if gpu_items and not _cuda_available():
        skip = pytest.mark.skip(reason="needs a CUDA GPU visible to Warp")
        for item in gpu_items:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def warp_device() -> str:
    """``"cuda"`` when Warp sees a GPU, else ``"cpu"`` (warp's CPU device)."""
    pytest.importorskip("mujoco_warp")
    return "cuda" if _cuda_available() else "cpu"


@pytest.fixture(scope="module")
def menagerie_quadruped(request: pytest.FixtureRequest):
    """``QuadrupedStand`` on the Menagerie robot named by indirect parametrization (one
    thread, a missing visual mesh's warning silenced); skipped without an offline copy of
    that robot."""
    import warnings

    from mpcbox.core import menagerie
    from mpcbox.tasks.legged.quadruped import QuadrupedStand

    robot = request.param
    if not (os.environ.get("MENAGERIE_ROOT") and menagerie.available(robot)):
        pytest.skip(f"no offline Menagerie copy with {robot} (set MENAGERIE_ROOT)")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        problem = QuadrupedStand(f"menagerie:{robot}", threads=1)
    yield problem
    problem.close()


@pytest.fixture(scope="session")
def problem_script():
    """A loader of ``problems/NAME.py`` as a module (``problems/`` is not a package)."""

    def load(name: str):
        path = Path(__file__).resolve().parents[1] / "problems" / f"{name}.py"
        spec = importlib.util.spec_from_file_location(f"{name}_script", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module

    return load
