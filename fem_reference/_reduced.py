"""What the axisymmetric and the sector systems share: the reduced-unknown system base, its
relative residual, and :class:`SolveError`."""

from __future__ import annotations

import numpy as np

from pillar_xval.scenes import ToolError

__all__ = ["ReducedSystem", "SolveError", "relative_residual"]


class SolveError(ToolError):
    """A tool underneath failed: the sparse factorisation, or an inconsistency in the
    assembled system (a non-convergence is reported in the result, never raised)."""


class ReducedSystem:
    """What the axisymmetric and the sector systems share: reduced unknowns (``T`` maps them
    to the full ones), a symmetric diagonal scaling ``scale`` of the factorised matrix
    ``_Ks``, and each body's pressure space in ``pressures``."""

    @property
    def n_reduced(self) -> int:
        return self.T.shape[1]

    def residual(self, x: np.ndarray, rhs: np.ndarray) -> float:
        """Relative scaled residual ||S (K x - b)|| / ||S b|| of a computed solution."""
        b = self.scale * rhs
        return relative_residual((b - self._Ks @ (x / self.scale))[:, None], b[:, None])

    def full(self, x_reduced: np.ndarray) -> tuple[np.ndarray, dict]:
        """Full displacement dofs and each body's physical pressure p (E_ref units)."""
        x = self.T @ x_reduced
        nu = self.T.shape[0] - sum(len(ps.dofs) for ps in self.pressures)
        pressure = {}
        for ps in self.pressures:
            p = np.zeros(ps.basis.N)
            p[ps.dofs] = ps.beta * x[ps.offset:ps.offset + len(ps.dofs)]
            pressure[ps.body] = p
        return x[:nu], pressure


def relative_residual(res, b) -> float:
    num = np.linalg.norm(res, axis=0)
    den = np.maximum(np.linalg.norm(b, axis=0), np.finfo(float).tiny)
    return float(np.max(num / den))
