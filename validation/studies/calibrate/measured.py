"""What every measured table of calibrate shares: the quantities' keys, the models that
carry the Hooke pillar's error, and the signed error table."""

from __future__ import annotations




from ...registry import MODELS, QUANTITIES
from ...planner.tables import ErrorTable


QKEYS = [q.key for q in QUANTITIES]

# Every candidate without elastic pillars carries the Hooke pillar's error (the closed forms
# too: the spring is a Hooke pillar, the Hertz-like limit is fitted on Hooke lattices).
HOOKE_MODELS = [m.name for m in MODELS.values()
                if m.candidate and m.physics != "elastic-pillar"]


def _measured(*args, **kwargs) -> ErrorTable:
    """An error table calibrate measured: its errors keep their signs (``signed``; the
    hand bounds it carries over do not)."""
    return ErrorTable(*args, signed=True, **kwargs)
