"""One BLAS thread while a controller plans.

NumPy and SciPy call OpenBLAS (or MKL), which by default starts one thread per core for a
matrix product above a small size and keeps those threads spinning after it. A controller's
tick is thousands of small products (iLQR's backward pass on 50-100 states, QP-MPC's
condensing) next to mpcbox's own finite-difference threads (:class:`~mpcbox.core.dynamics.
Dynamics` ``threads``) and, in a comparison, other worker processes: the BLAS threads then
compete with those for the same cores. On 2 cores the humanoid's iLQR-MPC tick took 21.3 ms
median and 32.6 ms p99 with OpenBLAS's two threads against 16.0 and 22.1 ms with one, and
in a two-process comparison 49 and 186 ms against 21 and 25 ms
(``python benchmarks/blas_threads.py``).

:func:`single_blas_thread` limits every loaded BLAS library to one thread for the length of
a ``with`` block, through threadpoolctl (about 10 us per block), and restores the previous
limits afterwards; iLQR enters it once per solve or replan (QP-MPC's tick, whose OSQP solve
is sparse, measured no difference; the sampling planners were not measured). Outside the
block the user's settings apply (``OPENBLAS_NUM_THREADS``, ``threadpoolctl``). The
environment variable ``MPCBOX_PLANNER_BLAS_THREADS`` sets another limit; ``0`` leaves BLAS
alone (for a model whose matrices are large enough to gain from threads).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from mpcbox.errors import InvalidArgumentError

_LOCK = threading.Lock()
_CONTROLLER: Any = None


def _controller() -> Any:
    """threadpoolctl's view of the BLAS libraries loaded now (built on first use)."""
    global _CONTROLLER
    with _LOCK:
        if _CONTROLLER is None:
            from threadpoolctl import ThreadpoolController

            _CONTROLLER = ThreadpoolController()
        return _CONTROLLER


def planner_blas_threads() -> int:
    """BLAS threads inside :func:`single_blas_thread`: ``MPCBOX_PLANNER_BLAS_THREADS`` (``0``:
    no limit), 1 by default.

    Raises:
        InvalidArgumentError: If the variable is set to something other than an integer >= 0.
    """
    text = os.environ.get("MPCBOX_PLANNER_BLAS_THREADS", "1").strip()
    if not text.isdigit():
        raise InvalidArgumentError(
            f"MPCBOX_PLANNER_BLAS_THREADS must be an integer >= 0 (0: no limit), got {text!r}"
        )
    return int(text)


@contextmanager
def single_blas_thread() -> Iterator[None]:
    """Limit BLAS to one thread (or ``MPCBOX_PLANNER_BLAS_THREADS``) inside the block; the
    previous limits return after it."""
    limit = planner_blas_threads()
    if limit == 0:
        yield
        return
    with _controller().limit(limits=limit, user_api="blas"):
        yield


__all__ = ["planner_blas_threads", "single_blas_thread"]
