"""One window's angle likelihood and its gradient: the plan, the filter, and both backward (numba).

The plan is :func:`.riccati.plan_recursion`'s; the filter :func:`.kalman.angle_filter`'s. Backward,
the filter's adjoints of L_k, f_k and S_k enter the plan's reverse sweep (:func:`.riccati.plan_adjoint`
over the stationary steps, :func:`.reverse.plan_reverse` over the recorded ones), whose direction
2 is τ_nm through the plant. R follows from homogeneity (:mod:`.kernel`): ``θ · ∇_θ log p =
sum_k S_k ∂/∂S_k``, as S_k enters the filter only through 1/(2 S_k).
"""

from __future__ import annotations

import numpy as np

from scioc.models.delayed.kalman import angle_filter, angle_filter_reverse
from scioc.models.delayed.reverse import plan_reverse
from scioc.models.delayed.riccati import SEED, TAPE, plan_adjoint, plan_recursion
from scioc.models.runtime import FASTMATH, njit

#: Entries of :func:`window_kernel`'s ``out``: log p, ∂/∂[q11, q22, R], ∂/∂τ_nm through the plant, ∂/∂σ_m²,
#: ∂/∂z0_mean (3).
OUT = 9


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def window_kernel(Ab, bc, ba, dAb, dbc, q11, q22, R, r, known, d, s2m, s2y, y, mu0, P0, freeze, grad, inn, out):
    """log p(y_1..y_K | y_0) of one window into ``out[0]`` and, with ``grad``, its derivatives (:data:`OUT`).

    ``Ab``, ``bc``, ``ba``: the plant the human moves and plans on; ``dAb`` (3, 3, 4), ``dbc`` (3, 4):
    their derivatives, direction 2 in τ_nm; ``r`` (K + M + 1,) the angle reference, rad; ``known``
    (K + M,) N·m; ``d`` the delay; ``s2m``, ``s2y``: σ_m², σ_y²; ``y`` (K + 1,) rad; ``mu0``, ``P0``:
    z_0's prior; ``inn`` (K,) receives the standardized innovations. Without ``grad``, or where
    the density is 0, the derivatives are 0.
    """
    K = y.shape[0] - 1
    N = known.shape[0]
    n = 3 + d
    f = np.empty(K)
    S_t = np.empty(K)
    L_t = np.empty((K, 3))
    cst = np.zeros(4)
    frozen = (np.empty((3, 3)), np.empty(3))
    W = np.empty((N, 3))
    tape = np.empty((N, TAPE))
    k_R, k_z = plan_recursion(Ab, bc, ba, q11, q22, R, r, known, K, freeze, f, S_t, L_t, cst, frozen, W, tape)
    L = np.empty((K, 3))
    S = np.empty(K)
    for k in range(K):
        src = cst[1:] if k <= k_R else L_t[k]
        S[k] = cst[0] if k <= k_R else S_t[k]
        for j in range(3):
            L[k, j] = src[j]
    KT = K if grad else 0
    t_mu = np.empty((KT, n))
    t_nu = np.empty(KT)
    slot = np.empty(KT, dtype=np.int64)
    t_P = np.empty((KT + 1 if grad else 0, n, n))
    t_c = np.empty((KT, n))
    t_s = np.empty(KT)
    ll = angle_filter(Ab, bc, ba, L, f, S, known, d, s2m, s2y, y, mu0, P0, inn, freeze, grad, t_mu, t_nu, slot, t_P,
                      t_c, t_s)
    out[0] = ll
    for m in range(1, out.shape[0]):
        out[m] = 0.0
    if not grad or ll == -np.inf:
        return
    Lbar = np.empty((K, 3))
    fbar = np.empty(K)
    Sbar = np.empty(K)
    Abar = np.zeros((3, 3))
    bcbar = np.zeros(3)
    mubar0 = np.zeros(3)
    s2mb = angle_filter_reverse(Ab, bc, L, f, S, d, s2m, s2y, y, mu0, P0, t_mu, t_nu, slot, t_P, t_c, t_s, Lbar, fbar,
                                Sbar, Abar, bcbar, mubar0)
    # the stationary observed rows share the plan's constants
    Lc = np.zeros(3)
    Scb = 0.0
    hom = 0.0
    for k in range(K):
        hom += S[k] * Sbar[k]
        if k <= k_R:
            Scb += Sbar[k]
            for j in range(3):
                Lc[j] += Lbar[k, j]
    seed = np.zeros(SEED)
    if k_z > 0:
        plan_adjoint(bc, cst[0], r, known, fbar, K, k_z, frozen, W, seed)
    G = np.zeros(4)
    plan_reverse(Ab, bc, ba, dAb, dbc, r, known, K, k_z, tape, fbar, Sbar, Lbar, Scb, Lc, seed, G)
    for p in range(4):
        for i in range(3):
            G[p] += bcbar[i] * dbc[i, p]
            for j in range(3):
                G[p] += Abar[i, j] * dAb[i, j, p]
    out[1] = G[0]
    out[2] = G[1]
    out[3] = (hom - q11 * G[0] - q22 * G[1]) / R
    out[4] = G[2]
    out[5] = s2mb
    for i in range(3):
        out[6 + i] = mubar0[i]


__all__ = ["OUT", "window_kernel"]
