"""Simulated humans that are not the max-ent LQ agent: negative controls for model adequacy.

The likelihood of :mod:`scioc.models.maxent` assumes a human who sees the wheel's state
now, plans an LQ-optimal torque on the wheel (closed by the assistant's feedback in
SC) and varies it with white Gaussian max-ent noise that is the only randomness.
Each human here breaks that in one named way, with magnitudes from the
manual-control literature:

``maxent``
    The paper's agent, as :func:`scioc.models.simulate.simulate_run` draws it.
``delay``
    Perceptual delay of 0.12 s with prediction, plus white motor noise the human does
    not know. The human sees the state d = 12 samples late and predicts the present
    with its internal model and its own past commands. With a perfect model and no
    unknown noise that prediction is exact and the delay is invisible (tested), so the
    delay shows only through the motor noise, which the human corrects 0.12 s late.
    The old state is the full state (with a lag, also the arm's torque, felt by
    proprioception); before the first d samples the human predicts from the known
    state at rest, z_0.
``lag``
    Neuromuscular lag, tau_nm = 0.06 s. The human plans knowing the lag
    (:func:`scioc.models.lq.lq_tracking_policy` on :func:`scioc.models.plant.discretize_lagged`);
    its max-ent noise enters before the lag, so the torque the wheel feels is
    low-passed, not white.
``coloured``
    The ``delay`` human's motor-noise intensity, low-passed with 0.1 s before it is
    added to the torque; no delay, no lag.
``combined``
    Delay 0.12 s, lag 0.06 s and white motor noise entering before the lag, as in the
    optimal control model of Kleinman, Baron & Levison (1970).
``kbl``
    ``combined`` with each subject's delay (uniform on 0.10-0.20 s) and lag (0.05-0.10 s)
    drawn once and kept in every level and trial; the lag colours the motor noise. The
    ranges (issue 13's) span the literature values below.
``crossover``
    Not an LQ controller: McRuer's compensatory operator with remnant (below). Its
    cost θ is not used.

Magnitudes and sources
----------------------
* Delay 0.12 s. Kleinman, Baron & Levison (1970), "An optimal control model of human
  response, part I", Automatica 6, use an observation delay of about 0.15-0.2 s; the
  pure reaction-time delay of McRuer & Jex (1967), "A review of quasi-linear pilot
  models", IEEE Trans. Human Factors in Electronics 8(3), is of the same order. We take
  the lower end because the subject also feels the wheel (proprioception is faster
  than vision).
* Neuromuscular lag. McRuer & Jex (1967) and Kleinman et al. (1970) use a first-order
  neuromuscular time constant of about 0.1 s. Abbink, Mulder & Boer (2012), "Haptic
  shared control: smoothly shifting control authority?", Cognition, Technology & Work
  14, show that the arm's admittance on a haptic device is set by co-contraction and
  reflexes; a hand that holds a wheel firmly is faster than a relaxed one. We use
  0.06 s for the LQ humans and 0.1 s for the crossover operator.
* Motor noise 0.25 N·m per 10-ms sample (:data:`MOTOR_SD`). Kleinman et al. (1970)
  give the motor-noise ratio ρ_u ≈ 0.003 (-25 dB) as a white-noise intensity
  ``V_u = ρ_u π E[u²]``. A white noise of intensity V averaged over a sample of
  dt = 0.01 s has variance V / dt, so the per-sample SD is
  ``sqrt(ρ_u π / dt) RMS(u) ≈ 1.0 RMS(u)``. The max-ent human of the default
  population (θ = [400, 0, 20]) has a command RMS of 0.26 N·m on the study reference
  (measured; its own max-ent noise SD 1/sqrt(2 S) is 0.15 N·m), hence 0.25 N·m:
  larger than the max-ent noise, so it is clearly present.
* Crossover operator (McRuer & Jex 1967, precision model without the very-low-frequency
  terms)::

      c(s) = K_p (T_L s + 1) / (T_I s + 1) · e^{-τ s} · E(s),   τ_N τ' = c + n - τ

  on the displayed error e = r - phi (a compensatory display). The wheel behaves as a
  spring (a position-like element) below its 5.4-rad/s resonance, so the operator
  adopts lag equalization (T_I large, an approximate integrator, McRuer & Jex's
  adjustment rule for position-like elements) and a little lead against the
  resonance's phase. τ = 0.15 s of pure delay plus τ_N = 0.1 s gives an effective
  delay at crossover of about 0.25 s, the order McRuer & Jex report for position- and
  rate-like elements. K_p = 23 N·m/rad, T_L = 0.3 s, T_I = 10 s put the crossover at
  2.4 rad/s with a phase margin of 57° and a gain margin of 1.8 in MC; in SC the
  assistant's spring stiffens the wheel and the crossover drops to 1 rad/s (phase
  margin 88°). Both are computed from the continuous loop in the tests.
* Remnant n: white noise of 0.4 N·m per sample through a first-order filter of 0.1 s
  (``motor_sd``, ``motor_tau``), injected at the operator's output before the
  neuromuscular lag (McRuer & Jex's output-injected remnant; Levison's remnant is
  likewise broadband filtered noise). On the study reference the remnant makes 13 %
  of the torque variance in MC (measured against the same run without it; 40 % in SC,
  where the operator's own torque is small), of the order of the remnant share these
  authors report for simple compensatory tasks.

Conventions
-----------
The simulator keeps the data convention "u_H,k acts from t_k to t_{k+1}". Without a
lag u_H,k is the held torque c_k + m_k and ``x_{k+1} = A x_k + b (u_H,k + u_A,k)``
exactly. With a lag the torque changes within the sample; u_H,k is then the
ZOH-equivalent torque that reproduces the velocity x_{k+1}[1] from x_k with the
2-state wheel, so the velocity relation is exact and the angle relation holds to
1e-5 rad RMS per step (at most 5e-5); states propagated from x_0 with the recorded
torques stay within 1e-4 rad of the truth over 4 minutes, less than one encoder
increment (tested). The lag's torque starts at 0. The assistant acts on
the true state every sample: ``u_A,k = -gain @ x_k + feedforward_k``
(:func:`scioc.models.assistant.human_feedback`). The LQ humans use the exact finite-horizon
recursion over the whole run, as :func:`scioc.models.simulate.simulate_run` does.
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
#: White motor-noise SD per 10-ms sample, N·m (KBL's -25 dB; see the module docstring).
MOTOR_SD = 0.25
#: Time constant of the ``coloured`` human's motor-noise filter, s.
MOTOR_TAU = 0.1


@dataclass(frozen=True)
class HumanSpec:
    """A simulated human.

    Attributes
    ----------
    name : str
    kind : {"lq", "crossover"}
        Max-ent LQ planner (cost θ) or McRuer's crossover operator (θ unused).
    delay_s : float
        Perceptual delay, s (rounded to whole samples).
    tau_nm : float
        Neuromuscular lag time constant, s (0: the command is the torque).
    motor_sd : float
        SD of the white motor noise (the remnant for ``crossover``) per sample, N·m,
        unknown to the human; added to the command before the lag.
    motor_tau : float
        If > 0, the motor noise passes a unit-gain first-order low-pass with this time
        constant, s, first (stationary SD ``motor_sd sqrt((1 - a) / (1 + a))``,
        ``a = exp(-dt / motor_tau)``).
    crossover_gain : float
        K_p, N·m per rad of displayed error (``crossover`` only, > 0).
    lead_s : float
        Lead time constant T_L, s (``crossover`` only).
    lag_s : float
        Lag time constant T_I, s (``crossover`` only).
    delay_spread_s, tau_spread : float
        Each subject's delay (lag) is ``delay_s`` (``tau_nm``) + U[0, spread) (:meth:`for_subject`).
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
        """One subject: delay and lag drawn from their spreads (two uniforms; without spreads, self, rng unused)."""
        if not self.varies:
            return self
        u = rng.random(2)
        return replace(self, delay_s=self.delay_s + u[0] * self.delay_spread_s,
                       tau_nm=self.tau_nm + u[1] * self.tau_spread, delay_spread_s=0.0, tau_spread=0.0)


#: The simulated humans by name (``scioc simulate --human NAME``).
HUMANS: dict[str, HumanSpec] = {
    h.name: h
    for h in (
        HumanSpec("maxent", "lq"),
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
        # Prediction: the state d samples ago, run forward on the internal model with the
        # human's own commands (it does not know the motor noise).
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
    """Simulate one run of a human of :data:`HUMANS` (or any :class:`HumanSpec`).

    Parameters
    ----------
    spec : HumanSpec
    theta : array_like, shape (3,)
        [q11, q22, R] of an LQ human; ignored by the crossover operator.
    condition : str
        The level: ``MC`` is unassisted; any other level is assisted by ``assistant``
        unless it is None (``SC`` needs one).
    angle_ref : array_like, shape (K + 1,)
        Reference angle, rad.
    plant : DiscretePlant
        The wheel at the recording's sample time.
    assistant : MPCAssistant or None
        The level's assistant; it must re-solve every sample.
    rng : numpy.random.Generator
        The only source of randomness. An LQ human draws its max-ent noise first
        (:func:`scioc.models.maxent.maxent_noise`, as :func:`scioc.models.simulate.simulate_run` does), then
        the motor noise (the remnant of the crossover operator) as
        ``rng.standard_normal(K)`` if ``motor_sd > 0``.
    x0 : array_like, shape (2,)
        Initial angle (rad) and velocity (rad/s).
    params : WheelParameters
        The wheel ``plant`` was discretized from, needed for the lag; checked against it.

    Returns
    -------
    ClosedLoop
        ``x`` (K + 1, 2) in rad, rad/s; ``u_H`` (K,) and ``u_A`` (K,) in N·m, acting from
        t_k to t_{k+1}.

    Examples
    --------
    >>> from models.assistant import design_assistant
    >>> from models.reference import reference_trajectory
    >>> ref = reference_trajectory(10.0).angle
    >>> run = simulate_human(HUMANS["combined"], [400.0, 0.0, 20.0], "SC", ref, discretize(0.01),
    ...                      design_assistant(), np.random.default_rng(0))
    >>> run.x.shape, run.u_H.shape, run.u_A.shape
    ((1001, 2), (1000,), (1000,))
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
        # The human plans on the wheel closed by the assistant's feedback (SC), knowing its lag.
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
