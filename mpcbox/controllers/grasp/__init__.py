"""Grasps held by contact forces: the grasp-force QP and the grasp controllers.

* :mod:`.force_qp`: :class:`GraspQP`, finger forces in friction cones that balance a load;
* :mod:`.contacts`: :func:`finger_contacts`, the measured contacts of each finger;
* :mod:`.config`: :class:`ForceGraspConfig`, the options of the force grasp;
* :mod:`.controller`: :class:`ForceGrasp` (adaptive, force QP through the actuator model) and
  :class:`PositionGrasp` (a fixed closing set-point).
"""

from mpcbox.controllers.grasp.config import ForceGraspConfig
from mpcbox.controllers.grasp.contacts import FingerContacts, finger_contacts
from mpcbox.controllers.grasp.controller import ForceGrasp, GraspCommand, PositionGrasp
from mpcbox.controllers.grasp.force_qp import GraspForces, GraspQP, contact_frames

__all__ = [
    "FingerContacts",
    "ForceGrasp",
    "ForceGraspConfig",
    "GraspCommand",
    "GraspForces",
    "GraspQP",
    "PositionGrasp",
    "contact_frames",
    "finger_contacts",
]
