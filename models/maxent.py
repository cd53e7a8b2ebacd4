"""Maximum-entropy likelihood of observed human torques (paper Eq. 7-16), exact and in linear time.

Under maximum entropy the observed torque sequence ``u = u_H,0..u_H,K-1`` has density
``p(u) ∝ exp(-J(u))`` (Eq. 8). J is quadratic in u, so p is Gaussian with mean the
optimal torques u* and precision the Hessian H = 2 (BᵀQB + R) (Eq. 16)::

    log p(u) = -½ gᵀ H⁻¹ g + ½ log|H| - K/2 log 2π        (Eq. 8, g from Eq. 15)

The dense formula (Eq. 11-16 literally: lifted matrices, Cholesky, O(K³)) lives in
:mod:`scioc.models.maxent_dense`, as the reference this module is tested against.

:func:`loglik_grad` is exact and O(K). Dynamic programming (see :mod:`scioc.models.lq`)
gives ``J(u) - min J = sum_k S_k v_k²`` with ``v_k = u_k + L_k x_k - f_k`` the
deviation from the optimal feedback law at the state x_k driven by the observed
torques, and ``log|H| = sum_k log(2 S_k)`` (the map u -> v is unit lower
triangular). Hence the max-ent model is a time-varying linear-Gaussian policy::

    log p(u) = sum_k [ -S_k v_k² + ½ log(2 S_k) - ½ log 2π ].

Because the states are propagated from x_0 with the observed torques, they do not
depend on θ: they are computed once per data set (:func:`scioc.models.segment.prepare_batch`).
The gradient with respect to θ comes from forward tangents carried through the same
single backward sweep.

The Riccati part depends on θ only and becomes stationary to rounding some hundred
steps from the end (the closed loop contracts). From there on the kernel holds the
step quantities constant and obtains the gradient of the remaining steps with one
adjoint sweep instead of three forward tangents; the result agrees with carrying
tangents through every step to rounding error (tested). Each segment is computed on
its own, so a segment's result does not depend on the batch it is in.

The kernel (:func:`batch_kernel` and the per-segment function it calls, about 190
lines) is one documented numba unit: its arithmetic is what every likelihood value of
the project comes from, and it is kept in one piece.

The generative side is the same factorization read forwards:
``u_k | x_k ~ N(-L_k x_k + f_k, 1 / (2 S_k))`` (:func:`maxent_noise`,
:func:`sample_maxent`, :func:`forward_optimal_control`).
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
#: The running product of S_k is logged every 16 steps, or sooner once it leaves [PROD_TINY, PROD_HUGE]:
#: at an extreme θ (S_k ~ 1e20 per step) 16 factors overflow a double, and log(inf) made the density +inf.
PROD_HUGE = 1e150
PROD_TINY = 1e-150


class LoglikGrad(NamedTuple):
    """Log-likelihood per segment and its gradient.

    Attributes
    ----------
    loglik : ndarray, shape (n,)
    grad : ndarray, shape (3, n)
        d loglik / d[q11, q22, R].
    """

    loglik: np.ndarray
    grad: np.ndarray


# --------------------------------------------------------------------------- kernel

#: The Riccati part counts as stationary once one step changes P and each of its
#: θ-tangents by at most this much relative to their size (about 4.5 units in the last
#: place). In floating point P reaches an exact fixed point but a tangent can cycle in
#: its last bit, so "bit for bit" would never trigger for some θ.
FREEZE_RTOL = 1e-15


@njit(cache=True, error_model="numpy", fastmath=False)
def _segment_kernel(A, b, q11, q22, R, x1, x2, r, u, a, freeze, wbuf, vbuf):
    """Log-likelihood and θ-gradient of one segment (see the module docstring).

    Phase 1 runs the Riccati recursion backward with forward-mode tangents, from
    ``P_K = Q`` until P and its tangents are stationary. From there on every step
    quantity (S, L, M, Pb and their tangents) is constant, so phase 2 runs only the
    data recursion for s_k backward (storing w_k and v_k in the scratch buffers) and
    phase 3 sweeps forward with the adjoint of s, collecting the sums that the
    constants' tangents multiply. Phases 2-3 cost about half of carrying three
    tangents of s through every step.

    The plan may look past the observed torques: ``a`` and ``r`` may extend beyond
    ``u`` (preview steps). Those steps shape the policy through s_k but contribute no
    factor, which is exactly the marginal of the max-ent Gaussian over the longer
    horizon (its later controls integrate out of the sequential factorization).
    """
    K_obs = u.shape[0]
    K = a.shape[0]
    a11, a12, a21, a22 = A[0, 0], A[0, 1], A[1, 0], A[1, 1]
    b1, b2 = b[0], b[1]
    # P_K = Q, s_K = Q (r_K, 0), and their tangents with respect to q11 and q22
    # (the R-derivative follows from homogeneity at the end).
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
    # Step quantities (assigned in the first pass of phase 1).
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
    """Assemble log p = quad + ½ sum log(2 S_k) - K/2 log 2π and the R-derivative.

    J and hence every S_k scale with θ (degree-1 homogeneity), so by Euler's theorem
    ``q11 ∂/∂q11 + q22 ∂/∂q22 + R ∂/∂R`` of log p equals ``quad + K/2``; this gives
    ∂/∂R without carrying a third tangent.
    """
    ll = quad + 0.5 * logs + K * (0.5 * math.log(2.0) - HALF_LOG_2PI)
    g2 = (quad + 0.5 * K - q11 * g0 - q22 * g1) / R
    return ll, g0, g1, g2


@njit(cache=True, fastmath=False, error_model="python")
def batch_kernel(A, b, fb, th, x1, x2, r, u, a, freeze, ll, g, wbuf, vbuf):
    """Log-likelihood and θ-gradient of every segment of a batch, written into ``ll`` and ``g``.

    The compiled entry point shared by :func:`loglik_grad` and the PyTensor Op
    (:mod:`scioc.models.bayes.op`). Arguments are C-contiguous float64 arrays: the plant's
    ``A`` (2, 2) and ``b`` (2,); the arrays of a :class:`scioc.models.segment.SegmentBatch`
    (``fb`` (n, 2), ``x1``, ``x2`` (n, K + 1), ``r`` (n, K + M + 1), ``u`` (n, K),
    ``a`` (n, K + M)); ``th`` (3, n) with rows q11, q22, R; ``freeze`` as for
    :func:`loglik_grad`; outputs ``ll`` (n,) and ``g`` (3, n); scratch ``wbuf``
    (K + M, 2) and ``vbuf`` (K + M,), which concurrent callers must not share.
    """
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
    """Exact max-ent log-likelihood and its θ-gradient for a batch of segments, in O(K).

    Parameters
    ----------
    theta : array_like, shape (3,) or (3, n)
        ``[q11, q22, R]``, one for all segments or one column per segment.
    batch : SegmentBatch
        From :func:`scioc.models.segment.prepare_batch` (same plant).
    plant : DiscretePlant
        The 0.01-s wheel discretization.
    freeze : bool
        Treat the Riccati part as constant once it is stationary to rounding
        (:data:`FREEZE_RTOL`) and get the gradient of the rest by an adjoint sweep
        (default). ``False`` carries forward tangents through every step; it exists
        to test the fast path.

    Returns
    -------
    LoglikGrad
        ``loglik`` (n,) in nats and ``grad`` (3, n) with respect to q11, q22, R.

    Examples
    --------
    >>> from models.plant import discretize
    >>> from models.segment import Segment
    >>> plant = discretize(0.01)
    >>> seg = Segment(np.zeros(2), np.zeros(11), np.zeros(10), np.zeros(10))
    >>> res = loglik_grad([10.0, 0.0, 1.0], prepare_batch(plant, [seg]), plant)
    >>> res.loglik.shape, res.grad.shape
    ((1,), (3, 1))
    """
    th = validate_theta(theta)
    n = batch.n
    # Always a fresh writable C array: one compiled specialization serves every call, so a
    # segment's bits never depend on how the caller laid out θ.
    th = np.array(np.broadcast_to(th.reshape(3, -1), (3, n)), dtype=np.float64, order="C")
    ll = np.empty(n)
    g = np.empty((3, n))
    # O(K) scratch for the adjoint sweep, reused across the batch.
    wbuf = np.empty((batch.a.shape[1], 2))
    vbuf = np.empty(batch.a.shape[1])
    batch_kernel(plant.A, plant.b, np.ascontiguousarray(batch.fb, dtype=np.float64), th, batch.x1, batch.x2,
                 batch.r, batch.u, batch.a, bool(freeze), ll, g, wbuf, vbuf)
    return LoglikGrad(ll, g)


def loglik_segments(theta, segments, plant: DiscretePlant) -> LoglikGrad:
    """:func:`loglik_grad` for segments of any lengths (batched by length).

    Parameters
    ----------
    theta : array_like, shape (3,) or (3, n)
    segments : sequence of models.segment.Segment, length n
    plant : DiscretePlant

    Returns
    -------
    LoglikGrad
    """
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


# --------------------------------------------------------------------------- generative side


class Demonstration(NamedTuple):
    """A trajectory generated by the human model.

    Attributes
    ----------
    x : ndarray, shape (K + 1, 2)
        Angle (rad) and velocity (rad/s).
    u_H : ndarray, shape (K,)
        Human torque, N·m.
    """

    x: np.ndarray
    u_H: np.ndarray


def maxent_noise(policy: Policy, rng: np.random.Generator) -> np.ndarray:
    """The max-ent human's deviations from its optimal policy: ``ε_k ~ N(0, 1 / (2 S_k))``, N·m.

    Given the state, the max-ent torque is ``u_k = -L_k x_k + f_k + ε_k`` (the sequential
    factorization of Eq. 8 used by :func:`loglik_grad`). Every simulator of the max-ent
    human draws its ε here, as ``rng.standard_normal(K) / sqrt(2 S_k)`` in step order,
    and then runs them through its own loop: :func:`sample_maxent` (known input),
    :func:`scioc.models.simulate.simulate_run` (the MPC assistant reacting to the state) and
    :func:`scioc.models.humans.simulate_human` (delays and lags). The same generator state
    therefore gives the same deviations in each.

    Parameters
    ----------
    policy : Policy
        From :func:`scioc.models.lq.lq_policy` or :func:`scioc.models.lq.lq_tracking_policy`; ``S`` (K,)
        in 1/(N·m)².
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (K,)
    """
    return rng.standard_normal(policy.S.shape[0]) / np.sqrt(2.0 * policy.S)


def forward_optimal_control(theta, x0, angle_ref, u_A, plant: DiscretePlant) -> Demonstration:
    """The human's optimal torques and states for θ (the dashed trajectories of Fig. 6).

    The mean of the max-ent distribution: ``u_k = -L_k x_k + f_k`` against the known
    assistant torque sequence ``u_A``. For a human who plans with the assistant's law pass
    the wheel and known input of :func:`scioc.models.segment.plan_inputs`; the states are then those of the
    closed loop with the assistant.

    Parameters
    ----------
    theta : array_like, shape (3,)
    x0 : array_like, shape (2,)
        rad, rad/s.
    angle_ref : array_like, shape (K + 1,)
        rad.
    u_A : array_like, shape (K,)
        N·m.
    plant : DiscretePlant

    Returns
    -------
    Demonstration
    """
    pol = lq_policy(plant, theta, angle_ref, u_A)
    a = np.ascontiguousarray(u_A, dtype=float)
    x, u = rollout(plant.A, plant.b, pol.L, pol.f, np.asarray(x0, dtype=float), a, np.zeros(a.shape[0]))
    return Demonstration(x, u)


def sample_maxent(theta, x0, angle_ref, u_A, plant: DiscretePlant, rng: np.random.Generator) -> Demonstration:
    """Draw one demonstration from the max-ent distribution ``u ~ N(u*, H⁻¹)`` exactly.

    Sequentially ``u_k | x_k ~ N(-L_k x_k + f_k, 1 / (2 S_k))``, which is the same
    Gaussian as Eq. 8 (the chain rule of the factorization used by :func:`loglik_grad`).

    Parameters
    ----------
    theta : array_like, shape (3,)
    x0 : array_like, shape (2,)
    angle_ref : array_like, shape (K + 1,)
    u_A : array_like, shape (K,)
        Known assistant torques (an open-loop sequence); with :func:`scioc.models.segment.plan_inputs`, the
        assistant's feedforward on the closed wheel (a draw in closed loop).
    plant : DiscretePlant
    rng : numpy.random.Generator

    Returns
    -------
    Demonstration
    """
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
