"""Linear MPC with explicit contact forces in friction cones, solved as a sparse QP.

* :mod:`.config`: :class:`QPMPCConfig`, the options;
* :mod:`.dynamics`: the prediction's MuJoCo models, their contact-free
  :class:`Linearization` and the soft-contact forces;
* :mod:`.prediction`: the prediction models (:class:`SoftStance`, :class:`RigidStance`);
* :mod:`.layout`, :mod:`.formulation`, :mod:`.terminal`: the sparse QP;
* :mod:`.solvers`: OSQP and ``qpsolvers`` backends, QP export and import;
* :mod:`.controller`: :class:`QPMPC`, the controller.
"""

from mpcbox.controllers.qp_mpc.config import QPMPCConfig
from mpcbox.controllers.qp_mpc.controller import QPMPC, QPPlan, TickTiming
from mpcbox.controllers.qp_mpc.dynamics import ContactDynamics, Linearization
from mpcbox.controllers.qp_mpc.prediction import PredictionModel, RigidStance, SoftStance
from mpcbox.controllers.qp_mpc.solvers import QPData, load_qp, to_qpsolvers

__all__ = [
    "QPMPC",
    "ContactDynamics",
    "Linearization",
    "PredictionModel",
    "QPData",
    "QPMPCConfig",
    "QPPlan",
    "RigidStance",
    "SoftStance",
    "TickTiming",
    "load_qp",
    "to_qpsolvers",
]
