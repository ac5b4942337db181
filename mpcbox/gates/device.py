"""The machine a gate report was measured on: Warp device, its name, package versions."""

from __future__ import annotations

import importlib.metadata
import os
import platform


def _version(package: str) -> str | None:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return None


def device_info(device: str) -> dict:
    """JSON-ready description of the Warp ``device`` and the software.

    Returns:
        ``{"device", "name", "is_cuda", "memory_gib", "cpu", "cpu_count", "python",
        "mujoco", "mujoco_warp", "warp"}``; ``name`` is the GPU's name on CUDA (e.g.
        ``"NVIDIA H100 80GB HBM3"``) and the processor's on the CPU.
    """
    import warp as wp

    dev = wp.get_device(device)
    cpu = platform.processor() or platform.machine()
    memory = getattr(dev, "total_memory", 0) if dev.is_cuda else 0
    return {
        "device": str(dev),
        "name": str(dev.name) if dev.is_cuda else f"CPU ({cpu})",
        "is_cuda": bool(dev.is_cuda),
        "memory_gib": round(memory / 2**30, 1) if memory else None,
        "cpu": cpu,
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "mujoco": _version("mujoco"),
        "mujoco_warp": _version("mujoco-warp"),
        "warp": _version("warp-lang"),
    }


__all__ = ["device_info"]
