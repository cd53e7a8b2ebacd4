"""Maximum-entropy likelihood of observed human torques (paper Eq. 7-16), exact and in linear time.

Under maximum entropy the torques u have density ``p(u) ∝ exp(-J(u))`` (Eq. 8): Gaussian with precision
H = 2 (BᵀQB + R) (Eq. 16), ``log p(u) = -½ gᵀ H⁻¹ g + ½ log|H| - K/2 log 2π``, g from Eq. 15
(:mod:`scioc.models.maxent_dense` evaluates it literally, as the reference). Dynamic programming
(:mod:`scioc.models.lq`) gives ``J(u) - min J = sum_k S_k v_k²``, ``v_k = u_k + L_k x_k - f_k`` at the
states driven by the observed torques (θ-free, computed once), and ``log|H| = sum_k log(2 S_k)``, hence in
O(K) ``log p(u) = sum_k [-S_k v_k² + ½ log(2 S_k) - ½ log 2π]``: the policy ``u_k | x_k ~ N(-L_k x_k + f_k,
1 / (2 S_k))``, which also generates demonstrations.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from scioc.models.cost import validate_theta
from scioc.models.lq import Policy, lq_policy, riccati_gains, riccati_update, rollout
from scioc.models.plant import DiscretePlant
from scioc.models.runtime import njit
from scioc.models.segment import SegmentBatch, prepare_batch

#: ½ log 2π, the Gaussian normalization per observed torque.
HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)
#: Bounds of the running product of S_k, logged every 16 steps or sooner when it leaves them (at an
#: extreme θ 16 factors overflow a double).
PROD_HUGE = 1e150
PROD_TINY = 1e-150


class LoglikGrad(NamedTuple):
    """``loglik`` (n,), nats, and ``grad`` (3, n), its derivative by [q11, q22, R]."""

    loglik: np.ndarray
    grad: np.ndarray


#: Relative change per step below which P and its θ-tangents count as stationary (a few units in the
#: last place: a tangent can cycle in its last bit, so an exact fixed point may never come).
FREEZE_RTOL = 1e-15


@njit(cache=True, error_model="numpy", fastmath=False)
def _segment_kernel(A, b, q11, q22, R, x1, x2, r, u, a, freeze, wbuf, vbuf):
    """Log-likelihood and θ-gradient of one segment. Once the Riccati part is stationary the step
    quantities are constant, and an adjoint sweep of s (phase 3) replaces three forward tangents. Preview
    steps shape s_k but add no factor: the marginal of the max-ent Gaussian over the longer horizon."""
    K_obs = u.shape[0]
    K = a.shape[0]
    a11, a12, a21, a22 = A[0, 0], A[0, 1], A[1, 0], A[1, 1]
    b1, b2 = b[0], b[1]
    # P_K = Q, s_K = Q (r_K, 0) and their q11-, q22-tangents (the R-derivative comes from homogeneity).
    p11, p12, p22 = q11, 0.0, q22
    d11_0, d12_0, d22_0 = 1.0, 0.0, 0.0
    d11_1, d12_1, d22_1 = 0.0, 0.0, 1.0
    s1 = q11 * r[K]
    s2 = 0.0
    ds1_0, ds2_0 = r[K], 0.0
    ds1_1, ds2_1 = 0.0, 0.0
    ll = 0.0  # sum of -S_k v_k²
    logs = 0.0  # sum of log S_k, taken in chunks of products (one log per 16 steps)
    prod = 1.0
    nprod = 0
    g0 = 0.0
    g1 = 0.0
    S = iS = L1 = L2 = pb1 = pb2 = m11 = m12 = m21 = m22 = 0.0
    e1_0 = e2_0 = e1_1 = e2_1 = 0.0
    dS_0 = dS_1 = 0.0
    dL1_0 = dL2_0 = dL1_1 = dL2_1 = 0.0
    k = K - 1
    stationary = False
    # ---- phase 1: Riccati with forward tangents, data step with forward tangents
    while k >= 0 and not stationary:
        S, iS, L1, L2, pb1, pb2, m11, m12, m21, m22 = riccati_gains(p11, p12, p22, a11, a12, a21, a22, b1, b2, R)
        observed = k < K_obs
        if observed:
            prod *= S
            nprod += 1
            if nprod == 16 or not (PROD_TINY < prod < PROD_HUGE):  # a log per 16 steps, or before over/underflow
                logs += math.log(prod)
                prod = 1.0
                nprod = 0
        e1_0 = d11_0 * b1 + d12_0 * b2
        e2_0 = d12_0 * b1 + d22_0 * b2
        e1_1 = d11_1 * b1 + d12_1 * b2
        e2_1 = d12_1 * b1 + d22_1 * b2
        dS_0 = b1 * e1_0 + b2 * e2_0
        dS_1 = b1 * e1_1 + b2 * e2_1
        dL1_0 = ((e1_0 * a11 + e2_0 * a21) - L1 * dS_0) * iS
        dL2_0 = ((e1_0 * a12 + e2_0 * a22) - L2 * dS_0) * iS
        dL1_1 = ((e1_1 * a11 + e2_1 * a21) - L1 * dS_1) * iS
        dL2_1 = ((e1_1 * a12 + e2_1 * a22) - L2 * dS_1) * iS
        # data step k with forward tangents
        ak = a[k]
        rk = r[k]
        w1 = s1 - pb1 * ak
        w2 = s2 - pb2 * ak
        bw = b1 * w1 + b2 * w2
        f = bw * iS
        dw1 = ds1_0 - e1_0 * ak
        dw2 = ds2_0 - e2_0 * ak
        if observed:
            xk1 = x1[k]
            xk2 = x2[k]
            v = u[k] + L1 * xk1 + L2 * xk2 - f
            Sv = S * v
            ll -= Sv * v
            dv = dL1_0 * xk1 + dL2_0 * xk2 - (b1 * dw1 + b2 * dw2 - f * dS_0) * iS
            g0 += 0.5 * dS_0 * iS - dS_0 * v * v - 2.0 * Sv * dv
        ds1_0 = rk - dL1_0 * bw + m11 * dw1 + m21 * dw2
        ds2_0 = -dL2_0 * bw + m12 * dw1 + m22 * dw2
        dw1 = ds1_1 - e1_1 * ak
        dw2 = ds2_1 - e2_1 * ak
        if observed:
            dv = dL1_1 * xk1 + dL2_1 * xk2 - (b1 * dw1 + b2 * dw2 - f * dS_1) * iS
            g1 += 0.5 * dS_1 * iS - dS_1 * v * v - 2.0 * Sv * dv
        ds1_1 = -dL1_1 * bw + m11 * dw1 + m21 * dw2
        ds2_1 = -dL2_1 * bw + m12 * dw1 + m22 * dw2
        s1 = q11 * rk + m11 * w1 + m21 * w2
        s2 = m12 * w1 + m22 * w2
        # P_k from P_{k+1}, tangents by the envelope theorem
        n11, n12, n22 = riccati_update(p11, p12, p22, q11, q22, R, L1, L2, m11, m12, m21, m22)
        t11_0, t12_0, t22_0 = riccati_update(d11_0, d12_0, d22_0, 1.0, 0.0, 0.0, L1, L2, m11, m12, m21, m22)
        t11_1, t12_1, t22_1 = riccati_update(d11_1, d12_1, d22_1, 0.0, 1.0, 0.0, L1, L2, m11, m12, m21, m22)
        if freeze:
            tol = FREEZE_RTOL
            stationary = (
                abs(n11 - p11) + abs(n12 - p12) + abs(n22 - p22) <= tol * (abs(n11) + abs(n12) + abs(n22))
                and abs(t11_0 - d11_0) + abs(t12_0 - d12_0) + abs(t22_0 - d22_0)
                <= tol * (abs(t11_0) + abs(t12_0) + abs(t22_0))
                and abs(t11_1 - d11_1) + abs(t12_1 - d12_1) + abs(t22_1 - d22_1)
                <= tol * (abs(t11_1) + abs(t12_1) + abs(t22_1))
            )
        p11, p12, p22 = n11, n12, n22
        d11_0, d12_0, d22_0 = t11_0, t12_0, t22_0
        d11_1, d12_1, d22_1 = t11_1, t12_1, t22_1
        k -= 1
    logs += math.log(prod)
    if k < 0:
        return _finish(K_obs, q11, q22, R, ll, logs, g0, g1)
    # ---- phase 2: steps k..0 with constant step quantities; primal backward.
    kf = k
    sv2 = 0.0  # sum v²
    svx1 = 0.0  # sum v x1
    svx2 = 0.0  # sum v x2
    svbw = 0.0  # sum v bᵀw
    for k in range(kf, -1, -1):
        ak = a[k]
        w1 = s1 - pb1 * ak
        w2 = s2 - pb2 * ak
        bw = b1 * w1 + b2 * w2
        v = 0.0
        if k < K_obs:
            v = u[k] + L1 * x1[k] + L2 * x2[k] - bw * iS
            sv2 += v * v
            svx1 += v * x1[k]
            svx2 += v * x2[k]
            svbw += v * bw
        wbuf[k, 0] = w1
        wbuf[k, 1] = w2
        vbuf[k] = v
        s1 = q11 * r[k] + m11 * w1 + m21 * w2
        s2 = m12 * w1 + m22 * w2
    cnt = min(kf + 1, K_obs)
    ll -= S * sv2
    logs += cnt * math.log(S)
    # ---- phase 3: adjoint of s forward in time. lam = dF/ds_k (s_0 is unused: 0).
    c2 = 2.0 * S * iS
    lam1 = 0.0
    lam2 = 0.0
    gpb1 = 0.0  # dF/dpb = -sum a_k omega_k
    gpb2 = 0.0
    gm11 = gm12 = gm21 = gm22 = 0.0  # dF/dM_ij = sum w_i lam_j
    gq = 0.0  # dF/dq11 through s: sum lam_1 r_k
    for k in range(0, kf + 1):
        w1 = wbuf[k, 0]
        w2 = wbuf[k, 1]
        gm11 += w1 * lam1
        gm12 += w1 * lam2
        gm21 += w2 * lam1
        gm22 += w2 * lam2
        gq += lam1 * r[k]
        cv = c2 * vbuf[k]
        o1 = cv * b1 + m11 * lam1 + m12 * lam2
        o2 = cv * b2 + m21 * lam1 + m22 * lam2
        gpb1 -= a[k] * o1
        gpb2 -= a[k] * o2
        lam1 = o1
        lam2 = o2
    # Combine: dF = G_L.dL + G_iS diS + G_S dS + G_pb.dpb + G_M:dM + G_q dq11 + lam.ds_boundary
    gL1 = -2.0 * S * svx1
    gL2 = -2.0 * S * svx2
    giS = 2.0 * S * svbw
    gS = -sv2 + cnt * 0.5 * iS
    # dM = -b dLᵀ: G_M:dM = -(b1 (gm11 dL1 + gm12 dL2) + b2 (gm21 dL1 + gm22 dL2))
    hL1 = gL1 - (b1 * gm11 + b2 * gm21)
    hL2 = gL2 - (b1 * gm12 + b2 * gm22)
    hS = gS - giS * iS * iS
    g0 += hL1 * dL1_0 + hL2 * dL2_0 + hS * dS_0 + gpb1 * e1_0 + gpb2 * e2_0 + gq + lam1 * ds1_0 + lam2 * ds2_0
    g1 += hL1 * dL1_1 + hL2 * dL2_1 + hS * dS_1 + gpb1 * e1_1 + gpb2 * e2_1 + lam1 * ds1_1 + lam2 * ds2_1
    return _finish(K_obs, q11, q22, R, ll, logs, g0, g1)


@njit(cache=True, inline="always", fastmath=False, error_model="numpy")
def _finish(K, q11, q22, R, quad, logs, g0, g1):
    """log p = quad + ½ sum log(2 S_k) - K/2 log 2π, and ∂/∂R by Euler: S_k is 1-homogeneous in θ, so
    ``(q11 ∂/∂q11 + q22 ∂/∂q22 + R ∂/∂R) log p = quad + K/2``."""
    ll = quad + 0.5 * logs + K * (0.5 * math.log(2.0) - HALF_LOG_2PI)
    g2 = (quad + 0.5 * K - q11 * g0 - q22 * g1) / R
    return ll, g0, g1, g2


@njit(cache=True, fastmath=False, error_model="python")
def batch_kernel(A, b, fb, th, x1, x2, r, u, a, freeze, ll, g, wbuf, vbuf):
    """Log-likelihood and θ-gradient of each segment into ``ll`` (n,) and ``g`` (3, n), for :func:`loglik_grad`
    and the PyTensor Op; scratch ``wbuf`` (K + M, 2), ``vbuf`` (K + M,) is not to be shared between threads."""
    n = u.shape[0]
    Ai = np.empty((2, 2))
    for i in range(n):
        # The plan's wheel: A - b fbᵀ (exactly A when fb = 0).
        Ai[0, 0] = A[0, 0] - b[0] * fb[i, 0]
        Ai[0, 1] = A[0, 1] - b[0] * fb[i, 1]
        Ai[1, 0] = A[1, 0] - b[1] * fb[i, 0]
        Ai[1, 1] = A[1, 1] - b[1] * fb[i, 1]
        ll[i], g[0, i], g[1, i], g[2, i] = _segment_kernel(
            Ai, b, th[0, i], th[1, i], th[2, i], x1[i], x2[i], r[i], u[i], a[i], freeze, wbuf, vbuf
        )


def loglik_grad(theta, batch: SegmentBatch, plant: DiscretePlant, *, freeze: bool = True) -> LoglikGrad:
    """Exact max-ent log-likelihood (Eq. 8) and θ-gradient of a batch of segments, in O(K).

    Parameters
    ----------
    theta : array_like, shape (3,) or (3, n)
        ``[q11, q22, R]``, shared or one column per segment.
    batch : SegmentBatch
        From :func:`scioc.models.segment.prepare_batch` with the same ``plant``.
    freeze : bool
        Hold the Riccati part once stationary (:data:`FREEZE_RTOL`); ``False`` tests that fast path.
    """
    th = validate_theta(theta)
    n = batch.n
    # A fresh C array: one compiled specialization, so a segment's bits do not depend on θ's layout.
    th = np.array(np.broadcast_to(th.reshape(3, -1), (3, n)), dtype=np.float64, order="C")
    ll = np.empty(n)
    g = np.empty((3, n))
    wbuf = np.empty((batch.a.shape[1], 2))
    vbuf = np.empty(batch.a.shape[1])
    batch_kernel(plant.A, plant.b, np.ascontiguousarray(batch.fb, dtype=np.float64), th, batch.x1, batch.x2,
                 batch.r, batch.u, batch.a, bool(freeze), ll, g, wbuf, vbuf)
    return LoglikGrad(ll, g)


def loglik_segments(theta, segments, plant: DiscretePlant) -> LoglikGrad:
    """:func:`loglik_grad` of n segments of any lengths (batched by length); θ shape (3,) or (3, n)."""
    segs = list(segments)
    th = validate_theta(theta)
    th = np.broadcast_to(th.reshape(3, -1), (3, len(segs)))
    ll = np.empty(len(segs))
    g = np.empty((3, len(segs)))
    by_len: dict[tuple[int, int], list[int]] = {}  # feedback and not may share a batch
    for i, s in enumerate(segs):
        by_len.setdefault((int(np.shape(s.u_H)[0]), int(np.shape(s.u_A)[0])), []).append(i)
    for idx in by_len.values():
        res = loglik_grad(th[:, idx], prepare_batch(plant, [segs[i] for i in idx]), plant)
        ll[idx] = res.loglik
        g[:, idx] = res.grad
    return LoglikGrad(ll, g)



class Demonstration(NamedTuple):
    """A generated trajectory: ``x`` (K + 1, 2) in rad, rad/s; ``u_H`` (K,) in N·m."""

    x: np.ndarray
    u_H: np.ndarray


def maxent_noise(policy: Policy, rng: np.random.Generator) -> np.ndarray:
    """The max-ent deviations ``ε_k ~ N(0, 1 / (2 S_k))`` (K,), N·m, of ``u_k = -L_k x_k + f_k + ε_k``.
    Every max-ent simulator draws ε here, so one generator state gives the same deviations in each."""
    return rng.standard_normal(policy.S.shape[0]) / np.sqrt(2.0 * policy.S)


def forward_optimal_control(theta, x0, angle_ref, u_A, plant: DiscretePlant) -> Demonstration:
    """The optimal torques ``u_k = -L_k x_k + f_k`` and states for θ (Fig. 6's dashed curves); ``x0`` in rad,
    rad/s, ``angle_ref`` (K + 1,) in rad, ``u_A`` (K,) the known input in N·m (or see ``plan_inputs``)."""
    pol = lq_policy(plant, theta, angle_ref, u_A)
    a = np.ascontiguousarray(u_A, dtype=float)
    x, u = rollout(plant.A, plant.b, pol.L, pol.f, np.asarray(x0, dtype=float), a, np.zeros(a.shape[0]))
    return Demonstration(x, u)


def sample_maxent(theta, x0, angle_ref, u_A, plant: DiscretePlant, rng: np.random.Generator) -> Demonstration:
    """One exact draw ``u ~ N(u*, H⁻¹)`` of Eq. 8, step by step; arguments as :func:`forward_optimal_control`."""
    pol = lq_policy(plant, theta, angle_ref, u_A)
    a = np.ascontiguousarray(u_A, dtype=float)
    x, u = rollout(plant.A, plant.b, pol.L, pol.f, np.asarray(x0, dtype=float), a, maxent_noise(pol, rng))
    return Demonstration(x, u)


__all__ = [
    "LoglikGrad",
    "Demonstration",
    "FREEZE_RTOL",
    "HALF_LOG_2PI",
    "batch_kernel",
    "loglik_grad",
    "loglik_segments",
    "forward_optimal_control",
    "maxent_noise",
    "sample_maxent",
]
