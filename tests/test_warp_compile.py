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
