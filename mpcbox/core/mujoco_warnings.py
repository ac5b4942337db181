"""MuJoCo's warnings collected in a list instead of printed (its handler is process-wide)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import mujoco


@contextmanager
def captured_warnings() -> Iterator[list[str]]:
    """Collect MuJoCo's warning messages in a list instead of printing them.

    MuJoCo's warning handler (``mju_user_warning``) is process-wide: while the block runs,
    warnings from any thread land in the list. The previous handler is restored on exit.

    Yields:
        The list the messages are appended to.
    """
    messages: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(messages.append)
    try:
        yield messages
    finally:
        mujoco.set_mju_user_warning(previous)
