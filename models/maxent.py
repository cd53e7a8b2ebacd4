"""Maximum-entropy likelihood of observed human torques (paper Eq. 7-16), exact and in linear time.

Under maximum entropy the observed torque sequence ``u = u_H,0..u_H,K-1`` has density
``p(u) ∝ exp(-J(u))`` (Eq. 8). J is quadratic in u, so p is Gaussian with mean the
optimal torques u* and precision the Hessian H = 2 (BᵀQB + R) (Eq. 16)::

    log p(u) = -½ gᵀ H⁻¹ g + ½ log|H| - K/2 log 2π        (Eq. 8, g from Eq. 15)

Two implementations live here:

* :func:`loglik_dense` — Eq. 11-16 literally (lifted matrices, Cholesky), O(K³).
  It exists to test the fast one and for the benchmark, nowhere else.
* :func:`loglik_grad` — exact and O(K). Dynamic programming (see :mod:`models.lq`)
  gives ``J(u) - min J = sum_k S_k v_k²`` with ``v_k = u_k + L_k x_k - f_k`` the
  deviation from the optimal feedback law at the state x_k driven by the observed
  torques, and ``log|H| = sum_k log(2 S_k)`` (the map u -> v is unit lower
  triangular). Hence the max-ent model is a time-varying linear-Gaussian policy::

      log p(u) = sum_k [ -S_k v_k² + ½ log(2 S_k) - ½ log 2π ].

  Because the states are propagated from x_0 with the observed torques, they do
  not depend on θ: they are computed once per data set (:func:`prepare_batch`).
  The gradient with respect to θ comes from forward tangents carried through the
  same single backward sweep.

The Riccati part depends on θ only and becomes stationary to rounding some hundred
steps from the end (the closed loop contracts). From there on the kernel holds the
step quantities constant and obtains the gradient of the remaining steps with one
adjoint sweep instead of three forward tangents; the result agrees with carrying
tangents through every step to rounding error (tested). Each segment is computed on
its own, so a segment's result does not depend on the batch it is in.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.linalg import cho_factor, cho_solve, solve_triangular

from models.cost import validate_theta
from models.lq import Policy, lq_policy, riccati_gains, riccati_update, rollout  # noqa: F401
from models.plant import DiscretePlant, propagate

_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)


class Feedback(NamedTuple):
    """The assistant as a feedback law the human knows and plans with.

    ``u_A,k = -gain @ x_k + feedforward[k]``: to the human the assistant is part of the
    wheel (closed by ``-gain``, an added spring and damper) plus a known input, the
    feedforward. :func:`models.assistant.human_feedback` builds it for the MPC assistant.

    Attributes
    ----------
    gain : ndarray, shape (2,)
        N·m per (rad, rad/s).
    feedforward : ndarray, shape (K + M,)
        N·m.
    """

    gain: np.ndarray
    feedforward: np.ndarray

    def window(self, start: int, n: int) -> "Feedback":
        """The same law over samples ``start .. start + n - 1`` of the run it was built for."""
        return Feedback(self.gain, self.feedforward[start : start + n])


def planning_plant(plant: DiscretePlant, gain) -> DiscretePlant:
    """The wheel closed by the assistant's state feedback: ``A - b gainᵀ``, same b and dt."""
    g = np.asarray(gain, dtype=float).reshape(2)
    return DiscretePlant(plant.A - np.outer(plant.b, g), plant.b, plant.dt)


class Segment(NamedTuple):
    """One demonstration (a subject × condition window) in the data convention.

    Attributes
    ----------
    x0 : ndarray, shape (2,)
        Initial angle (rad) and velocity (rad/s).
    angle_ref : ndarray, shape (K + M + 1,)
        Reference angle r_0..r_{K+M}, rad.
    u_H : ndarray, shape (K,)
        Observed human torque, N·m, acting from t_k to t_{k+1}.
    u_A : ndarray, shape (K + M,)
        Recorded assistant torque, N·m (zeros in manual control).
    feedback : Feedback or None
        How the human models the assistant. None is the paper's model (Eq. 15-16):
        the recorded u_A is a known input sequence. A :class:`Feedback` is a human who
        knows the assistant's law and plans with the wheel it closes and with its
        feedforward; the recorded u_A still drives the observed states. The two differ
        in closed loop: the recorded u_A reacts to the human's own variability, which
        the paper's model lets the human anticipate.

    M >= 0 preview steps extend the human's planning horizon past the observed torques
    (the reference and u_A after the window are known from the recording); M = 0 is
    the paper's model, planning exactly over the window.
    """

    x0: np.ndarray
    angle_ref: np.ndarray
    u_H: np.ndarray
    u_A: np.ndarray
    feedback: Feedback | None = None

    @property
    def K(self) -> int:
        return int(self.u_H.shape[0])

    @property
    def preview(self) -> int:
        return int(self.u_A.shape[0] - self.u_H.shape[0])


class SegmentBatch(NamedTuple):
    """Segments of equal length K, one row each, for the kernel.

    Attributes
    ----------
    x1, x2 : ndarray, shape (n, K + 1)
        Angle (rad) and velocity (rad/s) propagated from x_0 with the observed torques.
    r : ndarray, shape (n, K + M + 1)
        Angle reference, rad (M preview steps).
    u : ndarray, shape (n, K)
        Human torque, N·m.
    a : ndarray, shape (n, K + M)
        The known input of the human's plan, N·m: the recorded assistant torque, or the
        assistant's feedforward for a segment with :class:`Feedback`.
    fb : ndarray, shape (n, 2)
        The assistant's state feedback the human plans with (zeros without Feedback);
        the plan uses the wheel ``A - b fbᵀ``.
    """

    x1: np.ndarray
    x2: np.ndarray
    r: np.ndarray
    u: np.ndarray
    a: np.ndarray
    fb: np.ndarray

    @property
    def n(self) -> int:
        return int(self.u.shape[0])

    def repeat(self, j: int, n: int) -> "SegmentBatch":
        """A batch of ``n`` copies of segment ``j`` (to evaluate it under n θ in one call)."""
        return SegmentBatch(*(np.repeat(arr[j : j + 1], n, axis=0) for arr in self))

    @property
    def K(self) -> int:
        return int(self.u.shape[1])


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


def _check_segment(seg: Segment) -> Segment:
    x0 = np.asarray(seg.x0, dtype=float).reshape(2)
    r = np.asarray(seg.angle_ref, dtype=float)
    u = np.asarray(seg.u_H, dtype=float)
    a = np.asarray(seg.u_A, dtype=float)
    if u.ndim != 1 or a.ndim != 1 or a.shape[0] < u.shape[0] or r.shape != (a.shape[0] + 1,):
        raise ValueError(
            f"a segment needs u_H of shape (K,), u_A of shape (K + M,) and angle_ref of shape (K + M + 1,) "
            f"with M >= 0; got {u.shape}, {a.shape}, {r.shape}"
        )
    if u.shape[0] < 1:
        raise ValueError("a segment needs at least two samples (K >= 1)")
    fb = seg.feedback
    if fb is not None:
        gain = np.asarray(fb.gain, dtype=float)
        ff = np.asarray(fb.feedforward, dtype=float)
        if gain.shape != (2,) or ff.shape != a.shape:
            raise ValueError(
                f"a segment's feedback needs gain of shape (2,) and feedforward of the shape of u_A {a.shape}; "
                f"got {gain.shape}, {ff.shape}"
            )
        fb = Feedback(gain, ff)
    return Segment(x0, r, u, a, fb)


def plan_inputs(segment: Segment, plant: DiscretePlant) -> tuple[DiscretePlant, np.ndarray]:
    """The wheel and the known input the human plans with for this segment.

    Returns
    -------
    plant : DiscretePlant
        ``plant`` itself, or the wheel closed by the assistant's feedback.
    u_known : ndarray, shape (K + M,)
        The recorded u_A, or the assistant's feedforward.
    """
    seg = _check_segment(segment)
    if seg.feedback is None:
        return plant, seg.u_A
    return planning_plant(plant, seg.feedback.gain), seg.feedback.feedforward


def prepare_batch(plant: DiscretePlant, segments) -> SegmentBatch:
    """Lay out equal-length segments for :func:`loglik_grad` (θ-independent, done once).

    Parameters
    ----------
    plant : DiscretePlant
        The 0.01-s discretization of the wheel.
    segments : sequence of Segment
        All with the same K.

    Returns
    -------
    SegmentBatch
    """
    segs = [_check_segment(s) for s in segments]
    if not segs:
        raise ValueError("no segments given")
    K, M = segs[0].K, segs[0].preview
    if any(s.K != K or s.preview != M for s in segs):
        raise ValueError(
            "prepare_batch needs segments of equal length and preview; use loglik_segments for mixed lengths"
        )
    n = len(segs)
    x1 = np.empty((n, K + 1))
    x2 = np.empty((n, K + 1))
    r = np.empty((n, K + M + 1))
    u = np.empty((n, K))
    a = np.empty((n, K + M))
    fb = np.zeros((n, 2))
    for i, s in enumerate(segs):
        x = propagate(plant, s.x0, s.u_H + s.u_A[:K])
        x1[i] = x[:, 0]
        x2[i] = x[:, 1]
        r[i] = s.angle_ref
        u[i] = s.u_H
        if s.feedback is None:
            a[i] = s.u_A
        else:
            a[i] = s.feedback.feedforward
            fb[i] = s.feedback.gain
    return SegmentBatch(x1, x2, r, u, a, fb)


# --------------------------------------------------------------------------- kernel

#: The Riccati part counts as stationary once one step changes P and each of its
#: θ-tangents by at most this much relative to their size (about 4.5 units in the last
#: place). In floating point P reaches an exact fixed point but a tangent can cycle in
#: its last bit, so "bit for bit" would never trigger for some θ.
FREEZE_RTOL = 1e-15


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
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
            if nprod == 16:
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


@njit(cache=True, inline="always")
def _finish(K, q11, q22, R, quad, logs, g0, g1):
    """Assemble log p = quad + ½ sum log(2 S_k) - K/2 log 2π and the R-derivative.

    J and hence every S_k scale with θ (degree-1 homogeneity), so by Euler's theorem
    ``q11 ∂/∂q11 + q22 ∂/∂q22 + R ∂/∂R`` of log p equals ``quad + K/2``; this gives
    ∂/∂R without carrying a third tangent.
    """
    ll = quad + 0.5 * logs + K * (0.5 * math.log(2.0) - _HALF_LOG_2PI)
    g2 = (quad + 0.5 * K - q11 * g0 - q22 * g1) / R
    return ll, g0, g1, g2


@njit(cache=True)
def _batch_kernel(A, b, fb, th, x1, x2, r, u, a, freeze, ll, g, wbuf, vbuf):
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
        From :func:`prepare_batch` (same plant).
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
    _batch_kernel(plant.A, plant.b, np.ascontiguousarray(batch.fb, dtype=np.float64), th, batch.x1, batch.x2,
                  batch.r, batch.u, batch.a, bool(freeze), ll, g, wbuf, vbuf)
    return LoglikGrad(ll, g)


def loglik_segments(theta, segments, plant: DiscretePlant) -> LoglikGrad:
    """:func:`loglik_grad` for segments of any lengths (batched by length).

    Parameters
    ----------
    theta : array_like, shape (3,) or (3, n)
    segments : sequence of Segment, length n
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


# --------------------------------------------------------------------------- dense reference


def lifted_matrices(plant: DiscretePlant, K: int) -> tuple[np.ndarray, np.ndarray]:
    """Lifted system of Eq. 11-12: ``x = Φ x0 + Γ (u_H + u_A)`` for states x_1..x_K.

    Dense K×K reference only.

    Returns
    -------
    Phi : ndarray, shape (2K, 2)
    Gamma : ndarray, shape (2K, K)
    """
    A, b = plant.A, plant.b
    Phi = np.empty((2 * K, 2))
    Gamma = np.zeros((2 * K, K))
    powers_b = np.empty((K, 2))  # A^j b
    Ak = np.eye(2)
    for j in range(K):
        powers_b[j] = Ak @ b
        Ak = A @ Ak
        Phi[2 * j : 2 * j + 2] = Ak
    for i in range(K):  # block row i is x_{i+1}
        for j in range(i + 1):
            Gamma[2 * i : 2 * i + 2, j] = powers_b[i - j]
    return Phi, Gamma


class DenseResult(NamedTuple):
    """Dense reference evaluation of Eq. 8 and its ingredients."""

    loglik: float
    grad: np.ndarray
    g: np.ndarray
    H: np.ndarray
    u_opt: np.ndarray


def loglik_dense(theta, segment: Segment, plant: DiscretePlant, *, with_grad: bool = True) -> DenseResult:
    """Max-ent log-likelihood by Eq. 8 with Eq. 11-16 literally (Cholesky of the K×K Hessian).

    The reference implementation: O(K²) memory and O(K³) time. Used by the tests and
    the benchmark, nowhere else. With :class:`Feedback` it plans on the closed wheel
    with the feedforward as the known input, and so also propagates the states that
    way: it equals :func:`loglik_grad` when the recorded u_A follows the law exactly.

    Parameters
    ----------
    theta : array_like, shape (3,)
    segment : Segment
    plant : DiscretePlant
    with_grad : bool
        Also compute the θ-gradient (needs H⁻¹ explicitly for the trace term).

    Returns
    -------
    DenseResult
        ``loglik``, ``grad`` (3,) (NaN if not requested), gradient ``g`` (Eq. 15),
        Hessian ``H`` (Eq. 16) and the optimal torques ``u_opt = u - H⁻¹ g``.
    """
    q11, q22, R = validate_theta(theta)
    seg = _check_segment(segment)
    if seg.feedback is not None:
        plant, known = plan_inputs(seg, plant)
        seg = Segment(seg.x0, seg.angle_ref, seg.u_H, known)
    if seg.preview > 0:
        return _loglik_dense_marginal(q11, q22, R, seg, plant)
    K = seg.K
    Phi, Gamma = lifted_matrices(plant, K)
    x = Phi @ seg.x0 + Gamma @ (seg.u_H + seg.u_A)
    xref = np.zeros(2 * K)
    xref[0::2] = seg.angle_ref[1:]
    e = x - xref
    qdiag = np.tile([q11, q22], K)
    g = 2.0 * Gamma.T @ (qdiag * e) + 2.0 * R * seg.u_H
    GtQG = Gamma.T @ (qdiag[:, None] * Gamma)
    H = 2.0 * GtQG + 2.0 * R * np.eye(K)
    c = cho_factor(H, lower=True)
    y = cho_solve(c, g)
    logdet = 2.0 * np.sum(np.log(np.diag(c[0])))
    ll = -0.5 * g @ y + 0.5 * logdet - K * _HALF_LOG_2PI
    grad = np.full(3, np.nan)
    if with_grad:
        # d log p = -yᵀ dg + ½ yᵀ dH y + ½ tr(H⁻¹ dH), y = H⁻¹ g, with
        # dH/dq_ii = 2 Γᵀ E_ii Γ and dH/dR = 2 I: the traces need the weighted column
        # norms of L⁻¹ Γᵀ and the Frobenius norm of L⁻¹ (H = L Lᵀ).
        Lc = np.tril(c[0])
        W = solve_triangular(Lc, Gamma.T, lower=True)
        col2 = np.sum(W * W, axis=0)  # diag(Γ H⁻¹ Γᵀ)
        Linv = solve_triangular(Lc, np.eye(K), lower=True)
        Gy = Gamma @ y
        for j in range(2):
            dg = 2.0 * Gamma[j::2].T @ e[j::2]
            grad[j] = -dg @ y + Gy[j::2] @ Gy[j::2] + np.sum(col2[j::2])
        grad[2] = -2.0 * seg.u_H @ y + y @ y + np.sum(Linv * Linv)
    return DenseResult(float(ll), grad, g, H, seg.u_H - y)


def _loglik_dense_marginal(q11, q22, R, seg: Segment, plant: DiscretePlant) -> DenseResult:
    """Dense reference with preview: the max-ent Gaussian over all K + M controls
    (Eq. 8 on the longer horizon), marginalized to the K observed ones. Value only."""
    K, Kt = seg.K, seg.u_A.shape[0]
    Phi, Gamma = lifted_matrices(plant, Kt)
    xref = np.zeros(2 * Kt)
    xref[0::2] = seg.angle_ref[1:]
    qdiag = np.tile([q11, q22], Kt)
    g0 = 2.0 * Gamma.T @ (qdiag * (Phi @ seg.x0 + Gamma @ seg.u_A - xref))  # g at u_H = 0
    H = 2.0 * Gamma.T @ (qdiag[:, None] * Gamma) + 2.0 * R * np.eye(Kt)
    Sigma = np.linalg.inv(H)
    u_opt = -Sigma @ g0
    c = cho_factor(Sigma[:K, :K], lower=True)
    d = seg.u_H - u_opt[:K]
    ll = -0.5 * d @ cho_solve(c, d) - np.sum(np.log(np.diag(c[0]))) - K * _HALF_LOG_2PI
    return DenseResult(float(ll), np.full(3, np.nan), g0 + H @ np.concatenate([seg.u_H, u_opt[K:]]), H, u_opt)


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


def forward_optimal_control(theta, x0, angle_ref, u_A, plant: DiscretePlant) -> Demonstration:
    """The human's optimal torques and states for θ (the dashed trajectories of Fig. 6).

    The mean of the max-ent distribution: ``u_k = -L_k x_k + f_k`` against the known
    assistant torque sequence ``u_A``. For a human who plans with the assistant's law pass
    the wheel and known input of :func:`plan_inputs`; the states are then those of the
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
        Known assistant torques (an open-loop sequence); with :func:`plan_inputs`, the
        assistant's feedforward on the closed wheel (a draw in closed loop).
    plant : DiscretePlant
    rng : numpy.random.Generator

    Returns
    -------
    Demonstration
    """
    pol = lq_policy(plant, theta, angle_ref, u_A)
    a = np.ascontiguousarray(u_A, dtype=float)
    noise = rng.standard_normal(a.shape[0]) / np.sqrt(2.0 * pol.S)
    x, u = rollout(plant.A, plant.b, pol.L, pol.f, np.asarray(x0, dtype=float), a, noise)
    return Demonstration(x, u)


__all__ = [
    "Feedback",
    "Segment",
    "SegmentBatch",
    "plan_inputs",
    "planning_plant",
    "LoglikGrad",
    "DenseResult",
    "Demonstration",
    "Policy",
    "prepare_batch",
    "loglik_grad",
    "loglik_segments",
    "loglik_dense",
    "lifted_matrices",
    "forward_optimal_control",
    "sample_maxent",
]
