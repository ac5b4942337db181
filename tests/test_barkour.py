"""Google's Barkour vB (MuJoCo Menagerie): a quadruped whose feet are rounded mesh tips.

Each lower leg carries two collision meshes, the leg (whose lowest part hangs 2.5 cm above
the floor) and a small foot whose bottom vertices span about 1 x 1.1 cm. Read as four sole
corners per foot, the QP-MPC problem was degenerate (every OSQP solve of the standing robot
hit its iteration cap; under noise it fell in 1.4 s); each tip is now one point
(:data:`mpcbox.core.contact.POINT_SOLE`).
"""

from __future__ import annotations

import pytest

import mpcbox

pytestmark = [
    pytest.mark.menagerie,
    pytest.mark.parametrize("menagerie_quadruped", ["google_barkour_vb"], indirect=True),
]


def test_qp_mpc_stands_the_barkour_on_one_point_per_rounded_foot(menagerie_quadruped) -> None:
    barkour = menagerie_quadruped
    qp = mpcbox.make_controller("qp", barkour)
    assert qp.points.count == 4  # one per foot tip, the leg meshes' lifted points dropped
    res = mpcbox.simulate(barkour, qp, 1.0, noise=barkour.noise(), seed=0)
    assert res.survived, res.failure
    assert qp.stats["failed_solves"] == 0 and res.metrics.fallbacks == 0
    assert res.metrics.measures["tilt_rms_deg"] < 3.0
