"""Simulated humans that are not the max-ent LQ agent: negative controls for model adequacy.

Each breaks one assumption of :mod:`scioc.models.maxent` (sees the state now, plans LQ-optimally, varies
only by white max-ent noise), with magnitudes from the manual-control literature
(docs/decisions/simulated-humans.md):

- ``maxent``: the paper's agent, as :func:`scioc.models.simulate.simulate_run` draws it.
- ``delay``: sees the state 0.12 s late (McRuer & Jex 1967; Kleinman, Baron & Levison 1970) and predicts
  the present with its own commands (from z_0 before the first d samples), plus unknown white motor noise.
- ``lag``: a neuromuscular lag of 0.06 s (Abbink, Mulder & Boer 2012) it plans with; its noise passes the lag.
- ``coloured``: the ``delay`` human's motor noise low-passed with 0.1 s; no delay, no lag.
- ``combined``: delay, lag and motor noise before the lag, as in Kleinman et al. (1970).
- ``kbl``: ``combined`` with each subject's delay (0.10-0.20 s) and lag (0.05-0.10 s) drawn once.
- ``crossover``: McRuer & Jex's (1967) compensatory operator with remnant n (θ unused),
  ``c(s) = K_p (T_L s + 1) / (T_I s + 1) · e^{-τ s} · E(s)``, ``τ_N τ' = c + n - τ``.

With a lag, u_H,k is the ZOH-equivalent torque: held from t_k to t_{k+1}, it reproduces x_{k+1}'s
velocity on the 2-state wheel. The lag's torque starts at 0.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from scioc.models.assistant import ClosedLoop, MPCAssistant, human_feedback
from scioc.models.cost import validate_theta
from scioc.models.design import MANUAL, SHARED
from scioc.models.lq import lq_tracking_policy
from scioc.models.maxent import maxent_noise
from scioc.models.plant import DiscretePlant, WheelParameters, discretize, discretize_lagged
from scioc.models.runtime import njit

#: Perceptual delay of the ``delay`` and ``combined`` humans, s.
DELAY_S = 0.12
#: Neuromuscular time constant of the LQ humans with a lag, s.
TAU_NM = 0.06
#: White motor-noise SD per 10-ms sample, N·m (Kleinman et al.'s -25 dB; docs/decisions/simulated-humans.md).
MOTOR_SD = 0.25
#: Time constant of the ``coloured`` human's motor-noise filter, s.
MOTOR_TAU = 0.1


@dataclass(frozen=True)
class HumanSpec:
    """A simulated human: ``kind`` "lq" (max-ent LQ planner) or "crossover" (McRuer's operator).

    In s: ``delay_s``, ``tau_nm`` (0: no lag), ``motor_tau`` (low-pass of the motor noise; 0: white), and for
    ``crossover`` ``lead_s`` = T_L, ``lag_s`` = T_I, with K_p = ``crossover_gain``, N·m/rad. ``motor_sd``,
    N·m per sample: the unknown motor noise (remnant) before the lag. :meth:`for_subject` adds U[0, spread).
    """

    name: str
    kind: str
    delay_s: float = 0.0
    tau_nm: float = 0.0
    motor_sd: float = 0.0
    motor_tau: float = 0.0
    crossover_gain: float = 0.0
    lead_s: float = 0.0
    lag_s: float = 0.0
    delay_spread_s: float = 0.0
    tau_spread: float = 0.0

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"human name must be a non-empty string; got {self.name!r}")
        if self.kind not in ("lq", "crossover"):
            raise ValueError(f"human kind must be 'lq' or 'crossover'; got {self.kind!r}")
        for f in fields(self)[2:]:
            value = getattr(self, f.name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value >= 0):
                raise ValueError(f"human {self.name!r}: {f.name} must be a finite number >= 0; got {value!r}")
        if self.kind == "crossover" and self.crossover_gain <= 0:
            raise ValueError(f"human {self.name!r}: crossover_gain must be > 0 for a crossover operator")
        if self.kind == "lq":
            for name in ("crossover_gain", "lead_s", "lag_s"):
                if getattr(self, name) != 0:
                    raise ValueError(f"human {self.name!r}: {name} applies to kind 'crossover' only")
        if self.tau_spread > 0 and self.tau_nm == 0:
            raise ValueError(f"human {self.name!r}: a spread of the lag needs tau_nm > 0")

    @property
    def varies(self) -> bool:  # subjects differ in delay or lag (for_subject draws them)
        return self.delay_spread_s > 0 or self.tau_spread > 0

    def for_subject(self, rng: np.random.Generator) -> HumanSpec:
        """One subject: delay and lag drawn from their spreads (two uniforms; without spreads, self)."""
        if not self.varies:
            return self
        u = rng.random(2)
        return replace(self, delay_s=self.delay_s + u[0] * self.delay_spread_s,
                       tau_nm=self.tau_nm + u[1] * self.tau_spread, delay_spread_s=0.0, tau_spread=0.0)


#: The paper's max-ent agent, the simulated human the max-ent likelihood describes exactly.
PAPER_AGENT = "maxent"
#: The simulated humans by name (``scioc simulate --human NAME``).
HUMANS: dict[str, HumanSpec] = {
    h.name: h
    for h in (
        HumanSpec(PAPER_AGENT, "lq"),
        HumanSpec("delay", "lq", delay_s=DELAY_S, motor_sd=MOTOR_SD),
        HumanSpec("lag", "lq", tau_nm=TAU_NM),
        HumanSpec("coloured", "lq", motor_sd=MOTOR_SD, motor_tau=MOTOR_TAU),
        HumanSpec("combined", "lq", delay_s=DELAY_S, tau_nm=TAU_NM, motor_sd=MOTOR_SD),
        HumanSpec("kbl", "lq", delay_s=0.10, delay_spread_s=0.10, tau_nm=0.05, tau_spread=0.05, motor_sd=MOTOR_SD),
        HumanSpec("crossover", "crossover", delay_s=0.15, tau_nm=0.1, motor_sd=0.4, motor_tau=0.1,
                  crossover_gain=23.0, lead_s=0.3, lag_s=10.0),
    )
}


@njit(cache=True, inline="always", fastmath=False, error_model="python")
def _step(A, b_c, b_a, z, k, cmd, ua):
    n = A.shape[0]
    for i in range(n):
        acc = b_c[i] * cmd + b_a[i] * ua
        for j in range(n):
            acc += A[i, j] * z[k, j]
        z[k + 1, i] = acc


@njit(cache=True, inline="always", fastmath=False, error_model="python")
def _torque(z, k, cmd, ua, Aw, bw, lagged):
    # The ZOH-equivalent torque: the one that, held, gives x_{k+1}'s velocity on the 2-state wheel.
    if not lagged:
        return cmd
    return (z[k + 1, 1] - Aw[1, 0] * z[k, 0] - Aw[1, 1] * z[k, 1]) / bw[1] - ua


@njit(cache=True, fastmath=False, error_model="python")
def _lq_kernel(A, b_c, b_a, A_plan, gain, ff, L, f, eps, w, a_m, d, z0, Aw, bw, lagged):
    K = f.shape[0]
    n = A.shape[0]
    z = np.empty((K + 1, n))
    z[0] = z0
    c = np.empty(K)
    uH = np.empty(K)
    uA = np.empty(K)
    zh = np.empty(n)
    tmp = np.empty(n)
    m = 0.0
    for k in range(K):
        # The state d samples ago, run forward on the internal model with the human's own commands.
        j0 = k - d if k >= d else 0
        zh[:] = z[j0]
        for j in range(j0, k):
            for i in range(n):
                acc = b_c[i] * c[j] + b_a[i] * ff[j]
                for l in range(n):
                    acc += A_plan[i, l] * zh[l]
                tmp[i] = acc
            zh[:] = tmp
        ck = f[k] + eps[k]
        for i in range(n):
            ck -= L[k, i] * zh[i]
        c[k] = ck
        m = a_m * m + (1.0 - a_m) * w[k]
        ua = ff[k] - (gain[0] * z[k, 0] + gain[1] * z[k, 1])
        uA[k] = ua
        _step(A, b_c, b_a, z, k, ck + m, ua)
        uH[k] = _torque(z, k, ck + m, ua, Aw, bw, lagged)
    return z, uH, uA


@njit(cache=True, fastmath=False, error_model="python")
def _crossover_kernel(A, b_c, b_a, gain, ff, r, rdot, Kp, TL, a_I, d, w, a_m, z0, Aw, bw, lagged):
    K = ff.shape[0]
    z = np.empty((K + 1, A.shape[0]))
    z[0] = z0
    ell = np.empty(K)
    uH = np.empty(K)
    uA = np.empty(K)
    p = 0.0
    m = 0.0
    for k in range(K):
        # Lead on the displayed error; the reference's rate is read off the previewed curve.
        ell[k] = (r[k] - z[k, 0]) + TL * (rdot[k] - z[k, 1])
        p = a_I * p + (1.0 - a_I) * ell[k - d if k >= d else 0]  # delayed, then lag equalization
        m = a_m * m + (1.0 - a_m) * w[k]
        cmd = Kp * p + m
        ua = ff[k] - (gain[0] * z[k, 0] + gain[1] * z[k, 1])
        uA[k] = ua
        _step(A, b_c, b_a, z, k, cmd, ua)
        uH[k] = _torque(z, k, cmd, ua, Aw, bw, lagged)
    return z, uH, uA


def _decay(dt: float, tau: float) -> float:
    """Pole of the exact discretization of a first-order lag (0 for tau = 0: no filter)."""
    return float(np.exp(-dt / tau)) if tau > 0 else 0.0


def simulate_human(
    spec: HumanSpec,
    theta,
    condition: str,
    angle_ref,
    plant: DiscretePlant,
    assistant: MPCAssistant | None,
    rng: np.random.Generator,
    x0=(0.0, 0.0),
    *,
    params: WheelParameters = WheelParameters(),
) -> ClosedLoop:
    """Simulate one run of a :class:`HumanSpec` as a :class:`ClosedLoop`.

    ``theta`` = [q11, q22, R] (unused by ``crossover``); ``condition`` ``MC`` is unassisted, another level
    assisted by ``assistant`` (re-solving every sample) unless None; ``angle_ref`` (K + 1,), rad; ``x0`` in
    rad, rad/s; ``params``, the wheel ``plant`` came from. ``rng`` draws an LQ human's max-ent noise first
    (as :func:`scioc.models.simulate.simulate_run`), then the motor noise.
    """
    ref = np.ascontiguousarray(angle_ref, dtype=float)
    if ref.ndim != 1 or ref.shape[0] < 2:
        raise ValueError(f"angle_ref must be a vector of at least two samples; got shape {ref.shape}")
    K = ref.shape[0] - 1
    dt = plant.dt
    x0 = np.asarray(x0, dtype=float).reshape(2)
    if condition == SHARED and assistant is None:
        raise ValueError("shared control (SC) needs the assistant")
    if condition == MANUAL or assistant is None:
        gain2, ff = np.zeros(2), np.zeros(K)
    else:
        fb = human_feedback(assistant, ref)
        gain2, ff = np.asarray(fb.gain, dtype=float), np.ascontiguousarray(fb.feedforward)

    lagged = spec.tau_nm > 0
    if lagged:
        wheel = discretize(dt, params)
        if not (np.allclose(wheel.A, plant.A, rtol=1e-12, atol=1e-15)
                and np.allclose(wheel.b, plant.b, rtol=1e-12, atol=1e-15)):
            raise ValueError("plant is not the discretization of params; pass the WheelParameters it came from")
        lp = discretize_lagged(spec.tau_nm, dt, params)
        A, b_c, b_a = lp.A, lp.b_c, lp.b_a
        z0 = np.array([x0[0], x0[1], 0.0])
    else:
        A, b_c, b_a = plant.A, plant.b, plant.b
        z0 = x0.copy()
    n = A.shape[0]
    if spec.varies:
        raise ValueError(f"human {spec.name!r} varies between subjects; simulate spec.for_subject(rng)")
    d = int(round(spec.delay_s / dt))
    a_m = _decay(dt, spec.motor_tau)

    if spec.kind == "lq":
        q11, q22, R = validate_theta(theta)
        # The plan: the wheel closed by the assistant's feedback, with the lag.
        gain = np.zeros(n)
        gain[:2] = gain2
        A_plan = A - np.outer(b_a, gain)
        Q = np.zeros((n, n))
        Q[0, 0], Q[1, 1] = q11, q22
        x_ref = np.zeros((K + 1, n))
        x_ref[:, 0] = ref
        pol = lq_tracking_policy(A_plan, b_c, b_a, Q, R, x_ref, ff)
        eps = maxent_noise(pol, rng)
        w = rng.standard_normal(K) * spec.motor_sd if spec.motor_sd > 0 else np.zeros(K)
        z, u_H, u_A = _lq_kernel(A, b_c, b_a, A_plan, gain2, ff, pol.L, pol.f, eps, w, a_m, d, z0, plant.A,
                                 plant.b, lagged)
    else:
        w = rng.standard_normal(K) * spec.motor_sd if spec.motor_sd > 0 else np.zeros(K)
        rdot = np.gradient(ref, dt)
        z, u_H, u_A = _crossover_kernel(A, b_c, b_a, gain2, ff, ref, rdot, spec.crossover_gain, spec.lead_s,
                                        _decay(dt, spec.lag_s), d, w, a_m, z0, plant.A, plant.b, lagged)
    return ClosedLoop(np.ascontiguousarray(z[:, :2]), u_H, u_A)
