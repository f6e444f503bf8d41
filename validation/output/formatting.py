"""Numbers as the reports print them: one formatter for every study's percentages."""

from __future__ import annotations


def percent(value: float | None, spec: str = "+.2f", space: str = " ",
            missing: str = "-") -> str:
    """``value``, a fraction, as a percentage: ``100 value`` formatted by ``spec``, then
    ``space`` and "%" (``percent(0.0123)`` is "+1.23 %"); ``missing`` where it is None."""
    return missing if value is None else f"{100 * value:{spec}}{space}%"
