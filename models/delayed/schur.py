"""One Schur step on a banded Toeplitz matrix's generator, and its reverse mode (numba).

For :func:`.innovations.banded_loglik`, which derives the algorithm: ``XY[k, 0:2]`` hold the
generator (x, y) of a Schur complement (length d + 1), ``XY[k, 2:4]`` their adjoints.
"""

from __future__ import annotations

import math

import numpy as np

from scioc.models.runtime import FASTMATH, njit

#: Unsigned index type of the kernels' inner loops: no wraparound checks, so LLVM vectorizes them.
U = np.uint64


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def schur_step(XY, k, d):
    """The generator XY[k + 1, 0:2] of the next Schur complement from XY[k, 0:2] (x, y, length d + 1)."""
    a = U(k)
    b = U(k + 1)
    ud = U(d)
    if d == 0:
        XY[b, 0, 0] = XY[a, 0, 0]
        XY[b, 1, 0] = 0.0
        return
    rho = XY[a, 1, 1] / XY[a, 0, 0]
    c = math.sqrt(1.0 - rho * rho)
    ic = 1.0 / c
    for j in range(ud):
        XY[b, 0, j] = (XY[a, 0, j] - rho * XY[a, 1, j + U(1)]) * ic
    XY[b, 0, ud] = XY[a, 0, ud] * ic
    for j in range(ud):
        XY[b, 1, j] = c * XY[a, 1, j + U(1)] - rho * XY[b, 0, j]
    XY[b, 1, 0] = 0.0
    XY[b, 1, ud] = -rho * XY[b, 0, ud]


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def schur_step_adjoint(XY, k, d):
    """Reverse of :func:`schur_step`: the adjoints XY[k - 1, 2:4] from those of step k (overwritten).

    Forward, with ỹ_j = y_{j+1} (ỹ_d = 0), ρ = ỹ_0 / x_0, c = sqrt(1 - ρ²):
    ``x'_j = (x_j - ρ ỹ_j) / c``, ``y'_j = c ỹ_j - ρ x'_j`` (j >= 1; y'_0 = 0).
    """
    a = U(k - 1)
    b = U(k)
    ud = U(d)
    one = U(1)
    if d == 0:
        XY[a, 2, 0] = XY[b, 2, 0]
        XY[a, 3, 0] = 0.0
        return
    x0 = XY[a, 0, 0]
    rho = XY[a, 1, 1] / x0
    c = math.sqrt(1.0 - rho * rho)
    ic = 1.0 / c
    XY[a, 3, 0] = 0.0
    # g_j: the whole adjoint of x'_j (its own plus through y'_j, j >= 1)
    g0 = XY[b, 2, 0]
    XY[a, 2, 0] = g0 * ic
    XY[a, 3, 1] = -rho * g0 * ic
    rb = -g0 * XY[a, 1, 1] * ic
    cb = -g0 * XY[b, 0, 0] * ic
    for j in range(one, ud):
        yt = XY[a, 1, j + one]
        gy = XY[b, 3, j]
        xn = XY[b, 0, j]
        g = XY[b, 2, j] - rho * gy
        cb += gy * yt - g * xn * ic
        rb -= gy * xn + g * yt * ic
        XY[a, 2, j] = g * ic
        XY[a, 3, j + one] = c * gy - rho * g * ic
    gy = XY[b, 3, ud]
    xn = XY[b, 0, ud]
    g = XY[b, 2, ud] - rho * gy
    rb -= gy * xn
    cb -= g * xn * ic
    XY[a, 2, ud] = g * ic
    rb -= cb * rho * ic  # c = sqrt(1 - ρ²)
    XY[a, 3, 1] += rb / x0  # ρ = y_1 / x_0
    XY[a, 2, 0] -= rb * rho / x0


__all__ = ["U", "schur_step", "schur_step_adjoint"]
