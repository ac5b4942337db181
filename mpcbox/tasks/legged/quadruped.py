"""Quadrupeds standing on four feet: LeggedBalance with the feet of known Menagerie robots."""

from __future__ import annotations

from collections.abc import Sequence
from types import MappingProxyType
from typing import Any

from mpcbox.core.model import ModelSource
from mpcbox.errors import InvalidArgumentError
from mpcbox.tasks.legged.balance import LeggedBalance

#: The four feet of Menagerie quadrupeds, by robot name (``"menagerie:NAME"``). The Go1 has
#: a site and a geom called ``FR``; its sphere geoms are the feet. The A1's and ANYmal C's
#: foot spheres have no names, so their lower-leg bodies stand for them (their soles are the
#: spheres' bottoms).
MENAGERIE_FEET: MappingProxyType[str, tuple[str, ...]] = MappingProxyType(
    {
        "unitree_go1": ("geom:FR", "geom:FL", "geom:RR", "geom:RL"),
        "unitree_go2": ("geom:FR", "geom:FL", "geom:RR", "geom:RL"),
        "unitree_a1": ("body:FR_calf", "body:FL_calf", "body:RR_calf", "body:RL_calf"),
        "anybotics_anymal_c": (
            "body:LF_SHANK",
            "body:RF_SHANK",
            "body:LH_SHANK",
            "body:RH_SHANK",
        ),
    }
)


def menagerie_feet(model: ModelSource) -> tuple[str, ...] | None:
    """The feet of a ``"menagerie:NAME"`` robot listed in :data:`MENAGERIE_FEET`, else None."""
    if isinstance(model, str) and model.startswith("menagerie:"):
        return MENAGERIE_FEET.get(model.removeprefix("menagerie:").partition("/")[0])
    return None


class QuadrupedStand(LeggedBalance):
    """A quadruped standing on its four feet; by default Unitree's Go1 from MuJoCo Menagerie.

    :class:`~mpcbox.tasks.legged.balance.LeggedBalance` with its defaults, and the feet of
    a known Menagerie robot (:data:`MENAGERIE_FEET`) filled in. Any other quadruped works
    with its ``feet`` named. The Menagerie robots need ``pip install "mpcbox[menagerie]"``
    (or ``MENAGERIE_ROOT`` pointing at an offline copy).

    Args:
        model: The robot (default ``"menagerie:unitree_go1"``).
        feet: Its feet (default: from :data:`MENAGERIE_FEET`).
        **kwargs: Passed to :class:`~mpcbox.tasks.legged.balance.LeggedBalance`.

    Raises:
        InvalidArgumentError: If ``feet`` is omitted for a robot not in
            :data:`MENAGERIE_FEET`.
    """

    name = "quadruped_stand"

    def __init__(
        self,
        model: ModelSource = "menagerie:unitree_go1",
        *,
        feet: Sequence[str] | None = None,
        **kwargs: Any,
    ) -> None:
        if feet is None:
            feet = menagerie_feet(model)
        if feet is None:
            raise InvalidArgumentError(
                "feet: name the four feet (sites, bodies or geoms) of this model; they are "
                "known only for " + ", ".join(f"'menagerie:{n}'" for n in MENAGERIE_FEET)
            )
        super().__init__(model, feet=feet, **kwargs)
