"""Rollout backends of the sampling controllers: ``cpu`` (:func:`mujoco.rollout`) and ``warp`` (MJWarp)."""
