"""Finished jobs kept on disk as they finish, so that a re-run skips them.

``compare(..., checkpoint=folder)`` writes each finished job to
``folder/<setup fingerprint>/<job key>.pkl`` the moment it is done. A later comparison with
the same folder and the same setup (task, options, controllers, scenarios, seeds' trace,
push tests) loads those jobs instead of running them; another setup gets its own subfolder,
so runs of different setups are never mixed.
"""

from __future__ import annotations

import os
import pickle
from pathlib import Path

from mpcbox.comparison.jobs import Done, Job, Setup
from mpcbox.errors import InvalidArgumentError, InvalidTypeError


class Checkpoint:
    """A folder of finished jobs of one comparison setup.

    Args:
        folder: Where the jobs are kept (created when missing).
        setup: The comparison's setup; its :meth:`~mpcbox.comparison.jobs.Setup.fingerprint`
            names the subfolder.

    Raises:
        InvalidArgumentError: If ``folder`` is a file.
    """

    def __init__(self, folder: str | Path, setup: Setup) -> None:
        if not isinstance(folder, (str, Path)):
            raise InvalidTypeError(f"checkpoint must be a folder path, got {type(folder).__name__}")
        root = Path(folder)
        if root.exists() and not root.is_dir():
            raise InvalidArgumentError(f"checkpoint must be a folder, got the file {folder}")
        self.fingerprint = setup.fingerprint()
        self.folder = root / self.fingerprint
        self.folder.mkdir(parents=True, exist_ok=True)

    def load(self, jobs: list[Job]) -> dict[Job, Done]:
        """The finished jobs among ``jobs`` (unreadable files are run again)."""
        out = {}
        for job in jobs:
            path = self.folder / f"{job.key}.pkl"
            if not path.exists():
                continue
            try:
                done = pickle.loads(path.read_bytes())
            except Exception:  # a file cut short by a crash: run the job again
                continue
            if isinstance(done, Done) and done.job == job:
                out[job] = done
        return out

    def save(self, done: Done) -> None:
        """Keep a finished job (written to a temporary file, then renamed: never half)."""
        path = self.folder / f"{done.job.key}.pkl"
        tmp = path.with_suffix(".tmp")
        tmp.write_bytes(pickle.dumps(done))
        os.replace(tmp, path)


__all__ = ["Checkpoint"]
