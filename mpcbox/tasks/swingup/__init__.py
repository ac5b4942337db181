"""Swing-up tasks: the generic :class:`Swingup` for any underactuated chain, and presets.

* :mod:`~mpcbox.tasks.swingup.task`: :class:`Swingup`, "up" by named joints or sites;
* :mod:`~mpcbox.tasks.swingup.goal`: the upright error, the success rule and its measure;
* :mod:`~mpcbox.tasks.swingup.weights`: :class:`SwingupWeights`;
* :mod:`~mpcbox.tasks.swingup.presets`: the shipped pendulum, cart-pole and acrobot;
* :mod:`~mpcbox.tasks.swingup.dm_control`: dm_control's cart-pole and acrobot.
"""

from mpcbox.tasks.swingup.presets import AcrobotSwingup, CartpoleSwingup, PendulumSwingup
from mpcbox.tasks.swingup.task import Swingup
from mpcbox.tasks.swingup.weights import SwingupWeights

__all__ = ["AcrobotSwingup", "CartpoleSwingup", "PendulumSwingup", "Swingup", "SwingupWeights"]
