"""The servo step test (:func:`mpcbox.servo_ringing`) across Menagerie robots and test models.

For each model, as a user would load it (``menagerie:NAME``, a ``NAME/ENTRY`` scene, or an
MJCF path; missing visual meshes dropped), the script runs the set-point step test at the
first keyframe and records which actuators ring, the largest crossing rate and amplitude
of the others (how far they are from the thresholds), and the test's wall time::

    MENAGERIE_ROOT=... python benchmarks/servo_ringing.py [--robots unitree_z1,...]
        [--timestep 0.001] [--out benchmarks/results/servo_ringing.json]
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from json_report import finish  # benchmarks/ is not a package

#: Menagerie robots (``name`` or ``name/entry``) of the project's sweeps.
ROBOTS = (
    "unitree_z1 franka_emika_panda kuka_iiwa_14 universal_robots_ur5e rethink_robotics_sawyer "
    "kinova_gen3 robotiq_2f85 unitree_g1 unitree_h1 booster_t1 berkeley_humanoid robotis_op3 "
    "apptronik_apollo pndbotics_adam_lite fourier_n1 agility_cassie pal_talos/scene_position "
    "pal_talos/scene_motor unitree_go2 unitree_go1 unitree_a1 boston_dynamics_spot "
    "anybotics_anymal_b anybotics_anymal_c"
).split()


def load(name: str, timestep: float | None):
    """The compiled model of ``name`` (Menagerie name, ``name/entry`` or a path)."""
    from mpcbox.core.menagerie import MissingMeshWarning, model_source, robot_xml
    from mpcbox.core.model import compile_spec, load_spec

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MissingMeshWarning)
        if name.endswith(".xml"):
            source = name
        elif "/" in name:
            robot, entry = name.split("/", 1)
            source = str(robot_xml(robot, entry))
        else:
            source = model_source(name)
        spec = load_spec(source)
        if timestep is not None:
            spec.option.timestep = timestep
        return compile_spec(spec)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default=",".join(ROBOTS))
    parser.add_argument("--timestep", type=float, default=None, help="override the model's")
    parser.add_argument("--out", default="")
    args = parser.parse_args()
    from mpcbox import servo_ringing

    started = time.perf_counter()
    rows = {}
    for name in [r for r in args.robots.split(",") if r]:
        try:
            model = load(name, args.timestep)
            tic = time.perf_counter()
            report = servo_ringing(model)
            quiet = ~report.ringing
            rows[name] = {
                "actuators": len(report.names),
                "timestep_s": report.timestep,
                "ringing": list(report.ringing_names),
                "ringing_crossing_rate": [
                    round(float(c), 3) for c in report.crossing_rate[report.ringing]
                ],
                "ringing_amplitude": [round(float(a), 3) for a in report.amplitude[report.ringing]],
                "others_max_crossing_rate": round(float(report.crossing_rate[quiet].max()), 3)
                if quiet.any()
                else None,
                "others_max_velocity_gain_ratio": round(
                    float(np.nanmax(np.r_[report.velocity_gain_ratio[quiet], np.nan, 0.0])), 2
                ),
                "test_s": round(time.perf_counter() - tic, 2),
            }
        except Exception as exc:  # recorded: a model the test could not run on
            rows[name] = {"error": f"{type(exc).__name__}: {exc}"}
    flagged = {k: v["ringing"] for k, v in rows.items() if v.get("ringing")}
    out = {
        "benchmark": "servo_ringing: set-point step test per actuator (mpcbox.servo_ringing)",
        "command": "MENAGERIE_ROOT=... python benchmarks/servo_ringing.py"
        + (f" --timestep {args.timestep}" if args.timestep else ""),
        "flagged": flagged,
        "robots": rows,
    }
    return finish(out, args.out, started=started)


if __name__ == "__main__":
    raise SystemExit(main())
