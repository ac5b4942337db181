"""Core: the MuJoCo model, tangent-space states, the Problem, its dynamics, costs and equilibria.

Nothing here imports from :mod:`mpcbox.controllers`, :mod:`mpcbox.sim`,
:mod:`mpcbox.comparison` or :mod:`mpcbox.tasks`.
"""
