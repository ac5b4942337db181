"""Parallel precompilation of a tick's Warp modules (warp_compile) on warp's CPU device."""

from __future__ import annotations

import numpy as np
import pytest

wp = pytest.importorskip("warp")

from mpcbox.controllers.sampling.backends import warp_compile  # noqa: E402


@wp.kernel
def _add_one(x: wp.array(dtype=wp.float32)):
    i = wp.tid()
    x[i] = x[i] + 1.0


def test_recording_runs_no_kernel_and_precompile_loads_its_module():
    x = wp.zeros(4, dtype=wp.float32, device="cpu")

    def run():
        wp.launch(_add_one, dim=4, inputs=[x], device="cpu")

    assert warp_compile.precompile(run, "cpu", max_workers=2) == 1
    # The recording pass launched nothing.
    np.testing.assert_array_equal(x.numpy(), 0.0)
    # Warp's launch is restored and the module is loaded: the real launch runs.
    run()
    np.testing.assert_array_equal(x.numpy(), 1.0)
    assert _add_one.module.execs


def test_a_tick_that_fails_while_recording_is_skipped():
    def run():
        raise RuntimeError("needs device results")

    assert warp_compile.precompile(run, "cpu") == 0
    assert wp.launch.__name__ == "launch"


@wp.kernel(module="unique")
def _double(x: wp.array(dtype=wp.float32)):
    i = wp.tid()
    x[i] = x[i] * 2.0


def test_variants_of_every_block_dim_load_in_one_pool_heaviest_first(monkeypatch):
    """Each (module, block_dim) variant is loaded once, from one pool, tiled ones first."""
    x = wp.ones(4, dtype=wp.float32, device="cpu")

    def run():
        wp.launch(_add_one, dim=4, inputs=[x], device="cpu")
        wp.launch(_double, dim=4, inputs=[x], device="cpu", block_dim=32)

    loads = []
    real = wp.force_load

    def force_load(device=None, modules=None, block_dim=None, max_workers=None):
        loads.append((modules[0].name, block_dim, max_workers))
        real(device=device, modules=modules, block_dim=block_dim, max_workers=max_workers)

    monkeypatch.setattr(wp, "force_load", force_load)
    assert warp_compile.precompile(run, "cpu", max_workers=1) == 2
    assert [(b, w) for _, b, w in loads] == [(32, 0), (None, 0)]
    assert loads[0][0] == _double.module.name
    monkeypatch.undo()
    run()
    np.testing.assert_array_equal(x.numpy(), 4.0)
