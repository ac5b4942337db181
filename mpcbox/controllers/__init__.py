"""Controllers: LQR, iLQR, QP-MPC with contact forces, sampling MPC and the IPOPT reference.

Each controller takes a :class:`~mpcbox.core.problem.Problem` and implements
:class:`~mpcbox.controllers.base.Controller`. Controllers import only from :mod:`mpcbox.core`
and each other.
"""
