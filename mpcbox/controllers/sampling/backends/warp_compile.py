r"""Compile the kernels of one warp-backend tick in parallel before it first runs.

Warp compiles a module the first time one of its kernels is launched, one module after the
other. MuJoCo Warp builds many small modules per model (one per specialised kernel), so a cold
first tick of the humanoid spends most of its time compiling them in series. :func:`precompile`
runs the tick's Python code once with every launch *recorded instead of executed*, then hands
the recorded modules to :func:`warp.force_load`, which compiles (or loads from Warp's kernel
cache) up to ``max_workers`` modules at a time. The real tick that follows finds every module
loaded.

All ``(module, block_dim)`` variants go into one pool, heaviest first. Loading them in one
:func:`warp.force_load` call per ``block_dim`` instead, one call after the other, waits for the
slowest module of each group in turn: on the humanoid, four groups whose slowest modules take
20, 13, 11 and a few seconds made a 51 s cold start on an H100 (``benchmarks/startup.py``).
Warp's compile time of a module is not known before it compiles, so "heaviest" is a guess:
tiled kernels (those launched with a ``block_dim``) first, then modules by their number of
kernels.

Warp's kernel cache (``warp.config.kernel_cache_dir``, by default under ``~/.cache/warp``)
is keyed by a hash of each module's source and options, so a re-run of the same model in a
new process loads the compiled modules instead of compiling them again.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any


@contextlib.contextmanager
def _recording(
    wp: Any, modules: dict[tuple[int, int | None], tuple[Any, int | None]]
) -> Iterator[None]:
    """Replace Warp's launches (and graph conditionals) by recorders while active.

    Args:
        wp: The ``warp`` package.
        modules: Filled with ``(id(module), block_dim) -> (module, block_dim)``.
    """

    def record(kernel: Any, block_dim: int | None) -> None:
        module = kernel.module
        modules[(id(module), block_dim)] = (module, block_dim)

    def launch(kernel: Any, *args: Any, **kwargs: Any) -> None:
        record(kernel, kwargs.get("block_dim"))

    def launch_tiled(kernel: Any, *args: Any, **kwargs: Any) -> None:
        record(kernel, kwargs.get("block_dim"))

    def capture_if(condition: Any, on_true: Any = None, on_false: Any = None, **kwargs: Any):
        for branch in (on_true, on_false):
            if callable(branch):
                branch(**kwargs)

    def capture_while(condition: Any, while_body: Any, **kwargs: Any) -> None:
        while_body(**kwargs)

    names = {
        "launch": launch,
        "launch_tiled": launch_tiled,
        "capture_if": capture_if,
        "capture_while": capture_while,
    }
    saved = {name: getattr(wp, name) for name in names}
    try:
        for name, fn in names.items():
            setattr(wp, name, fn)
        yield
    finally:
        for name, fn in saved.items():
            setattr(wp, name, fn)


def precompile(run: Callable[[], None], device: str, max_workers: int | None = None) -> int:
    """Load every module that ``run`` launches kernels of, ``max_workers`` at a time.

    ``run`` is called once with launches recorded, not executed (its Python code runs, so it
    must not read device results back); then the recorded modules are compiled or loaded
    from the kernel cache in parallel. Any failure of the recording pass is ignored: the
    modules then load one by one at the first real launch, as without this call.

    Args:
        run: The tick's device work (e.g. :meth:`WarpBackend._run`).
        device: Warp device name.
        max_workers: Parallel compilations (default: the CPU count, at most 32).

    Returns:
        The number of distinct ``(module, block_dim)`` variants loaded.
    """
    import warp as wp

    modules: dict[tuple[int, int | None], tuple[Any, int | None]] = {}
    try:
        with _recording(wp, modules):
            run()
    except Exception:  # pragma: no cover - a tick that cannot run without device results
        return 0
    workers = max_workers if max_workers is not None else min(os.cpu_count() or 1, 32)
    variants = sorted(modules.values(), key=_weight, reverse=True)

    def load(variant: tuple[Any, int | None]) -> None:
        module, block_dim = variant
        wp.force_load(device=device, modules=[module], block_dim=block_dim, max_workers=0)

    if workers <= 1:
        for variant in variants:
            load(variant)
    else:
        with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="mpcbox-compile") as pool:
            for future in [pool.submit(load, variant) for variant in variants]:
                future.result()
    return len(modules)


def _weight(variant: tuple[Any, int | None]) -> tuple[bool, int]:
    """Guessed compile cost of a ``(module, block_dim)`` variant, for ordering the loads."""
    module, block_dim = variant
    return block_dim is not None, len(getattr(module, "kernels", ()))


__all__ = ["precompile"]
