"""Run the public API on models nobody tuned mpcbox for, and record what breaks.

For each model (dm_control suite, mujoco-warp's test data, Menagerie robots when
``MENAGERIE_ROOT`` is set) the sweep builds the generic ``Problem(path)`` a user would, then
finds the equilibrium, linearizes at the reference, builds LQR and simulates it for a short
time, and does the same for every registered controller (the sampling ones on the CPU
backend with 16 samples). A second part feeds bad inputs to the main public arguments.

Every check is one of: ``ok``; ``mpcbox_error`` (an :class:`mpcbox.MpcboxError`, the
documented way to refuse an input); ``raw_error`` (any other exception: a bug); ``nan`` (a
non-finite result passed silently); ``stderr`` (MuJoCo printed a warning); ``timeout``;
``accepted`` (a bad input was taken silently). Each model runs in its own process with a
time limit.

Usage::

    nice -n 5 python benchmarks/model_sweep.py [--label after] [--models cartpole,go1]
        [--skip-bad-inputs] [--timeout 240]

Prints JSON and stores it in ``benchmarks/results/model_sweep.json`` under ``--label``
(``--merge --groups cli`` re-runs some bad-input groups into a stored label). The stored
``before`` label ran this script on the code before the sweep's fixes (commit 473809b,
``git archive 473809b mpcbox | tar -x -C /tmp/base`` and ``PYTHONPATH=/tmp/base``), ``after``
on the fixed code; both with ``MENAGERIE_ROOT`` set.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import traceback
import warnings
from pathlib import Path

RESULTS = Path(__file__).parent / "results" / "model_sweep.json"
MACHINE = "2-core sandbox CPU, shared"
SIM_DURATION = 0.2
SAMPLING = dict(num_samples=16, horizon=0.1, backend="cpu")
CONTROLLERS = ("lqr", "ilqr", "qp", "ps", "mppi", "cem")
OPTIONS = {
    "ilqr": dict(horizon=5, max_iterations=3),
    "qp": dict(horizon=3),
    "ps": SAMPLING,
    "mppi": SAMPLING,
    "cem": SAMPLING,
}


def models(all_menagerie: bool = False) -> dict[str, str]:
    """Model name -> MJCF path (or ``menagerie:`` name); ``all_menagerie`` adds every robot
    folder of ``MENAGERIE_ROOT`` to the nine tuned-for or long-swept ones."""
    import dm_control.suite
    import mujoco_warp

    out = {}
    suite = os.path.dirname(dm_control.suite.__file__)
    for name in (
        "cartpole acrobot pendulum quadruped humanoid walker cheetah hopper finger reacher "
        "manipulator swimmer point_mass ball_in_cup fish stacker lqr"
    ).split():
        out[f"dm:{name}"] = os.path.join(suite, f"{name}.xml")
    warp = os.path.join(os.path.dirname(mujoco_warp.__file__), "test_data")
    for rel in (
        "aloha_pot/scene.xml humanoid/humanoid.xml actuation/muscle.xml actuation/actuators.xml "
        "actuation/slidercrank.xml actuation/position.xml actuation/adhesion.xml "
        "actuation/site.xml tendon/fixed.xml tendon/pulley_wrap.xml tendon/tendon_limit.xml "
        "jdotv/connect_3d.xml jdotv/weld_3d.xml constraints.xml pendula.xml mug/mug.xml "
        "hfield/hfield.xml primitives.xml"
    ).split():
        out[f"warp:{rel}"] = os.path.join(warp, rel)
    if os.environ.get("MENAGERIE_ROOT"):
        for name in (
            "franka_emika_panda universal_robots_ur5e kuka_iiwa_14 unitree_go1 unitree_a1 "
            "anybotics_anymal_c unitree_go2 unitree_g1 robotiq_2f85"
        ).split():
            out[f"menagerie:{name}"] = f"menagerie:{name}"
        if all_menagerie:
            root = Path(os.environ["MENAGERIE_ROOT"])
            for folder in sorted(root.iterdir()):
                if folder.is_dir() and f"menagerie:{folder.name}" not in out:
                    out[f"menagerie:{folder.name}"] = f"menagerie:{folder.name}"
    return out


#: Tasks by name on robots nobody tuned them for: label -> (module:class, kwargs).
TASKS = {
    "swingup:dm_cartpole": ("mpcbox.tasks.swingup:Swingup", dict(joints={"hinge_1": 0.0})),
    "swingup:dm_acrobot": ("mpcbox.tasks.swingup:Swingup", dict(joints={"shoulder": 0.0})),
    "swingup:dm_pendulum": ("mpcbox.tasks.swingup:Swingup", dict(joints={"hinge": 0.0})),
    "legged:dm_quadruped": (
        "mpcbox.tasks.legged.balance:LeggedBalance",
        dict(feet=["toe_front_left", "toe_front_right", "toe_back_right", "toe_back_left"]),
    ),
}
MENAGERIE_TASKS = {
    "quadruped_stand:unitree_go1": ("mpcbox.tasks.legged.quadruped:QuadrupedStand", {}),
    "quadruped_stand:unitree_a1": ("mpcbox.tasks.legged.quadruped:QuadrupedStand", {}),
    "quadruped_stand:anybotics_anymal_c": ("mpcbox.tasks.legged.quadruped:QuadrupedStand", {}),
    "quadruped_stand:unitree_go2": ("mpcbox.tasks.legged.quadruped:QuadrupedStand", {}),
    "biped_stand:unitree_g1": ("mpcbox.tasks.legged.biped:BipedStand", {}),
    "reach:franka_emika_panda": (
        "mpcbox.tasks.reach:ArmReach",
        dict(frame="hand", target=[0.05, 0.05, -0.05], relative=True),
    ),
    "reach:universal_robots_ur5e": (
        "mpcbox.tasks.reach:ArmReach",
        dict(frame="attachment_site", target=[0.05, 0.05, -0.05], relative=True),
    ),
    "reach:kuka_iiwa_14": (
        "mpcbox.tasks.reach:ArmReach",
        dict(frame="link7", target=[0.05, 0.05, -0.05], relative=True),
    ),
}


def task_entries() -> dict[str, str]:
    """Task label -> the label itself (the child looks it up)."""
    labels = list(TASKS)
    if os.environ.get("MENAGERIE_ROOT"):
        labels += list(MENAGERIE_TASKS)
    return {f"task:{label}": label for label in labels}


class _Stderr:
    """Capture what C code writes to file descriptor 2."""

    def __enter__(self):
        sys.stderr.flush()
        self.file = tempfile.TemporaryFile(mode="w+b")
        self.saved = os.dup(2)
        os.dup2(self.file.fileno(), 2)
        return self

    def __exit__(self, *exc):
        sys.stderr.flush()
        os.dup2(self.saved, 2)
        os.close(self.saved)
        self.file.seek(0)
        self.text = self.file.read().decode(errors="replace")
        self.file.close()


def _finite(value) -> bool:
    import numpy as np

    if value is None:
        return True
    if isinstance(value, (tuple, list)) and not hasattr(value, "_fields"):
        return all(_finite(v) for v in value)
    if hasattr(value, "_fields"):
        return all(_finite(getattr(value, f)) for f in value._fields)
    try:
        arr = np.asarray(value)
    except Exception:
        return True
    if arr.dtype.kind in "fc":
        return bool(np.all(np.isfinite(arr)))
    return True


def check(record: dict, name: str, fn, expect_error: bool = False):
    """Run ``fn`` and file its outcome under ``record[name]``; return its value or None."""
    from mpcbox.errors import MpcboxError

    start = time.perf_counter()
    entry: dict = {}
    value = None
    with warnings.catch_warnings(record=True) as caught, _Stderr() as err:
        warnings.simplefilter("always")
        try:
            value = fn()
        except MpcboxError as exc:
            entry = {"status": "mpcbox_error", "error": type(exc).__name__, "message": str(exc)}
        except Exception as exc:
            tb = traceback.extract_tb(exc.__traceback__)[-3:]
            entry = {
                "status": "raw_error",
                "error": type(exc).__name__,
                "message": str(exc)[:500],
                "where": [f"{f.filename.split('mpcbox/')[-1]}:{f.lineno}" for f in tb],
            }
        else:
            if expect_error:
                entry = {"status": "accepted", "message": repr(value)[:200]}
            elif not _finite(value):
                entry = {"status": "nan", "message": "non-finite result"}
            else:
                entry = {"status": "ok"}
    if err.text.strip():
        entry.setdefault("stderr", err.text.strip()[:500])
        if entry["status"] == "ok":
            entry["status"] = "stderr"
    names = sorted({f"{w.category.__name__}: {str(w.message)[:160]}" for w in caught})
    names = [n for n in names if "GLFW" not in n]
    if names:
        entry["warnings"] = names[:5]
    entry["seconds"] = round(time.perf_counter() - start, 3)
    record[name] = entry
    return value


def sweep_model(path: str) -> dict:
    """Every check on one model (a path, ``menagerie:NAME`` or a task label)."""
    import mpcbox

    record: dict = {}
    if path in TASKS or path in MENAGERIE_TASKS:
        from mpcbox.registry import resolve

        entry, kwargs = {**TASKS, **MENAGERIE_TASKS}[path]
        robot = path.split(":")[1]
        if robot.startswith("dm_"):
            from mpcbox.tasks.swingup.dm_control import suite_path

            model = suite_path(robot[3:])
        else:
            model = f"menagerie:{robot}"
        if entry.endswith("BipedStand"):
            model = None  # its default robot
        args = dict(kwargs) if model is None else dict(kwargs, model=model)
        if entry.endswith(("ArmReach", "LeggedBalance", "Swingup")):
            model = args.pop("model")
            make = lambda: resolve(entry)(model, **args)  # noqa: E731
        else:
            make = lambda: resolve(entry)(**args)  # noqa: E731
        problem = check(record, "task", make)
        if problem is not None:
            _controllers(record, problem, mpcbox)
        return record
    problem = check(record, "problem", lambda: mpcbox.Problem(path))
    if problem is None:
        return record
    record["sizes"] = dict(nq=problem.nq, nv=problem.nv, nu=problem.nu, na=problem.na)
    eq = check(record, "equilibrium", lambda: problem.find_equilibrium(on_infeasible="ignore"))
    _controllers(record, problem, mpcbox)
    if problem.model.nkey and eq is not None:
        # The recipe of tutorial 1: the first keyframe, its equilibrium as the reference.
        def keyed():
            key = mpcbox.Problem(path, keyframe=0)
            held = key.find_equilibrium(on_infeasible="ignore")
            return mpcbox.Problem(path, keyframe=0, qpos_ref=held.qpos, ctrl_ref=held.ctrl)

        sub: dict = {}
        keyed_problem = check(sub, "problem", keyed)
        if keyed_problem is not None:
            _controllers(sub, keyed_problem, mpcbox)
        record.update({f"key0_{k}": v for k, v in sub.items()})
    return record


def _controllers(record: dict, problem, mpcbox) -> None:
    import numpy as np

    x0, u0 = problem.reference_state(), problem.ctrl_ref
    check(record, "linearize", lambda: problem.linearize(x0, u0))
    check(record, "quadratize", lambda: problem.quadratize(x0, u0))
    for name in CONTROLLERS:
        ctrl = check(
            record, name, lambda n=name: mpcbox.make_controller(n, problem, **OPTIONS.get(n, {}))
        )
        if ctrl is None:
            continue
        result = check(
            record, f"simulate_{name}", lambda c=ctrl: mpcbox.simulate(problem, c, SIM_DURATION)
        )
        if result is not None:
            entry = record[f"simulate_{name}"]
            entry["outcome"] = result.metrics.outcome
            if result.metrics.outcome == "controller error":
                entry["status"] = "controller_error"
                entry["message"] = str(result.failure)[:500]
            if not np.all(np.isfinite(result.states)) and result.metrics.outcome != "diverged":
                entry["status"] = "nan"
        close = getattr(ctrl, "close", None)
        if close is not None:
            close()


def _run_child(kind: str, arg: str, timeout: float) -> dict:
    cmd = [sys.executable, __file__, f"--child-{kind}", arg]
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"timeout": {"status": "timeout", "message": f"over {timeout} s"}}
    lines = [line for line in out.stdout.splitlines() if line.startswith("{")]
    if out.returncode != 0 or not lines:
        return {"process": {"status": "crash", "rc": out.returncode, "message": out.stderr[-800:]}}
    return json.loads(lines[-1])


def summarize(results: dict) -> dict:
    counts: dict = {}
    bugs = []
    for group, record in results.items():
        for name, entry in record.items():
            if not isinstance(entry, dict) or "status" not in entry:
                continue
            counts[entry["status"]] = counts.get(entry["status"], 0) + 1
            if entry["status"] not in ("ok", "mpcbox_error"):
                bugs.append(f"{group} / {name}: {entry['status']} {entry.get('error', '')}")
    return {"counts": counts, "not_ok": bugs}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--label", default="run")
    parser.add_argument("--models", default="", help="comma-separated substrings")
    parser.add_argument("--skip-models", action="store_true")
    parser.add_argument(
        "--all-menagerie",
        action="store_true",
        help="also every other robot folder of MENAGERIE_ROOT (generic Problem and controllers)",
    )
    parser.add_argument("--skip-bad-inputs", action="store_true")
    parser.add_argument("--timeout", type=float, default=300.0)
    parser.add_argument("--groups", default="", help="bad-input groups (default: all)")
    parser.add_argument(
        "--merge", action="store_true", help="update the label's stored results, not replace"
    )
    parser.add_argument("--child-model", help=argparse.SUPPRESS)
    parser.add_argument("--child-bad", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child_model:
        print(json.dumps(sweep_model(args.child_model)))
        return 0
    if args.child_bad:
        sys.path.insert(0, str(Path(__file__).parent))
        from model_sweep_inputs import bad_inputs

        print(json.dumps(bad_inputs(check, args.child_bad)))
        return 0

    results: dict = {}
    if not args.skip_models:
        wanted = [s for s in args.models.split(",") if s]
        for name, path in {**models(args.all_menagerie), **task_entries()}.items():
            if wanted and not any(w in name for w in wanted):
                continue
            start = time.perf_counter()
            results[name] = _run_child("model", path, args.timeout)
            print(f"{name}: {time.perf_counter() - start:.1f} s", file=sys.stderr, flush=True)
    if not args.skip_bad_inputs:
        sys.path.insert(0, str(Path(__file__).parent))
        from model_sweep_inputs import GROUPS

        for group in [g for g in args.groups.split(",") if g] or GROUPS:
            results[f"inputs:{group}"] = _run_child("bad", group, args.timeout)
            print(f"inputs:{group} done", file=sys.stderr, flush=True)
    stored = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    if args.merge and args.label in stored:
        results = {**stored[args.label]["results"], **results}
    report = {"machine": MACHINE, "summary": summarize(results), "results": results}
    print(json.dumps(report, indent=1))
    stored[args.label] = report
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(stored, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
