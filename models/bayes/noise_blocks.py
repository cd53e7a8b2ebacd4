"""Other forms of a subject's noise scales: ρ centred or folded per subject (``mixed``), ρ = u² (``squared``), and
ρ and σ_m in polar coordinates (``polar``), which straighten the arc the data leave between them.

Where the data fix only the sum of the policy noise (∝ ρ², ρ = R^(-1/2)) and the motor noise (∝ σ_m²), folded
centred ρ̃, σ̃ (ρ = |ρ̃|, σ_m = |σ̃|) follow a long arc of the ellipse ρ̃² + k σ̃² ≈ c. Polar coordinates
ρ̃ = r cos φ, σ̃ = r sin φ / √k, a = log r, b = φ keep the law ρ̃ ~ N(0, s_ρ), σ̃ ~ N(0, s_m) with the Jacobian
r²/√k; as that density has period π in φ, an envelope w with Σ_n w(φ + nπ) = 1 gives it finite mass::

    log p(a, φ) = log N(r cos φ; 0, s_ρ) + log N(r sin φ / √k; 0, s_m) + 2a - ½ log k + log w(φ) + log 2
    w(φ) = N(φ; 0, π) / Σ_n N(φ + nπ; 0, π) = π N(φ; 0, π) / (1 + 2 e^(-2π²) cos 2φ)   (Poisson's formula)

A subject with k = NaN stays folded centred (a = ρ̃, b = σ̃). In PyMC b carries the joint density with a as its
parameter; ancestral draws take a from its marginal, then φ given r by rejection and its copy n by w(φ + nπ).
"""

from __future__ import annotations

import numpy as np
import pymc as pm
import pytensor.tensor as pt

#: The free variables of the block: a (log r, or ρ̃) and b (φ, or σ̃).
NOISE_A, NOISE_B = "noise_a", "noise_b"
#: e^(-2π²): the first term of the envelope's Poisson sum past its constant.
_POISSON_1 = float(np.exp(-2.0 * np.pi**2))
#: Copies n of φ's draw considered (|n| <= this): w beyond them is below e^(-32).
_COPIES = 8


def log_envelope(phi):
    """log w(φ) (module docstring), elementwise; numpy or PyTensor."""
    lib = pt if isinstance(phi, pt.TensorVariable) else np
    return -phi**2 / (2.0 * np.pi**2) - 0.5 * np.log(2.0 * np.pi) - lib.log1p(2.0 * _POISSON_1 * lib.cos(2.0 * phi))


def _normal_logp(x, s):
    return -0.5 * (x / s) ** 2 - pt.log(s) - 0.5 * np.log(2.0 * np.pi)


def noise_values(a, b, k):
    """(ρ̃, σ̃) from the block's (a, b), elementwise over subjects; k NaN where a subject is not polar."""
    k = np.asarray(k, dtype=float)
    polar = np.isfinite(k)
    root_k = np.sqrt(np.where(polar, k, 1.0))
    lib = pt if isinstance(a, pt.TensorVariable) or isinstance(b, pt.TensorVariable) else np
    r = lib.exp(a)
    return lib.where(polar, r * lib.cos(b), a), lib.where(polar, r * lib.sin(b) / root_k, b)


def noise_logp(a, b, s_rho, s_m, k):
    """log p(a, b) per subject (module docstring), PyTensor."""
    k = np.asarray(k, dtype=float)
    polar = np.isfinite(k)
    log_k = np.log(np.where(polar, k, 1.0))
    rho_t, sig_t = noise_values(a, b, k)
    both = _normal_logp(rho_t, s_rho) + _normal_logp(sig_t, s_m)
    return both + pt.where(polar, 2.0 * a - 0.5 * log_k + log_envelope(b) + np.log(2.0), 0.0)


def _phi_given_r(r, s_rho, s_m, kk, rng):
    """φ given r: on [0, π) by rejection from the uniform, then its copy φ + nπ with probability w(φ + nπ)."""
    A = r**2 / (2.0 * np.asarray(s_rho) ** 2)
    B = np.broadcast_to(r**2 / (2.0 * kk * np.asarray(s_m) ** 2), A.shape)
    phi = np.empty(A.shape)
    todo = np.ones(A.shape, dtype=bool)
    while todo.any():
        idx = np.nonzero(todo)
        cand = rng.uniform(0.0, np.pi, size=idx[0].shape)
        c2 = np.cos(cand) ** 2
        log_acc = -A[idx] * c2 - B[idx] * (1.0 - c2) + np.minimum(A[idx], B[idx])
        ok = np.log(rng.uniform(size=cand.shape)) < log_acc
        hit = tuple(i[ok] for i in idx)
        phi[hit] = cand[ok]
        todo[hit] = False
    n = np.arange(-_COPIES, _COPIES + 1)
    logw = log_envelope(phi[..., None] + np.pi * n)
    cdf = np.cumsum(np.exp(logw - logw.max(axis=-1, keepdims=True)), axis=-1)
    u = rng.uniform(size=phi.shape)[..., None] * cdf[..., -1:]
    return phi + np.pi * n[np.minimum((cdf < u).sum(axis=-1), n.size - 1)]


def draw_a(s_rho, s_m, k, rng, size):
    """a from its marginal per subject (last axis): log r of independent ρ̃, σ̃ where k > 0, ρ̃ where k is NaN."""
    k = np.asarray(k, dtype=float)
    polar = np.isfinite(k)
    rho_t = rng.normal(0.0, 1.0, size=size) * s_rho
    sig_t = rng.normal(0.0, 1.0, size=size) * s_m
    r = np.sqrt(rho_t**2 + np.where(polar, k, 1.0) * sig_t**2)
    return np.where(polar, np.log(r), rho_t)


def draw_b(a, s_rho, s_m, k, rng):
    """b given a, per subject (last axis): φ given r = e^a where k > 0, σ̃ ~ N(0, s_m) (independent of a) where NaN."""
    k = np.asarray(k, dtype=float)
    polar = np.isfinite(k)
    a = np.asarray(a, dtype=float)
    sig_t = rng.normal(0.0, 1.0, size=a.shape) * s_m
    phi = _phi_given_r(np.exp(np.where(polar, a, 0.0)), s_rho, s_m, np.where(polar, k, 1.0), rng)
    return np.where(polar, phi, sig_t)


def mixed_half_normal_block(name: str, scale, pinned: np.ndarray, *, start: float):
    """Per subject ``name`` ~ HalfNormal(``scale``) from one unconstrained ``<name>_free`` v: centred (exp(v)) where
    ``pinned``, folded centred (|v|) elsewhere, starting at ``start`` (docs/decisions/delayed-rho-form.md)."""
    pinned = np.asarray(pinned, dtype=bool)
    n = len(pm.modelcontext(None).coords["subject"])
    if pinned.shape != (n,):
        raise ValueError(f"{name}: {pinned.size} pinned flags for {n} subjects")

    def to_value(v):
        return pt.switch(pinned, pt.exp(v), pt.abs(v))

    def logp(v, s):
        half_normal = pm.logp(pm.HalfNormal.dist(s), to_value(v))
        # pinned: the density at exp(v) times the Jacobian exp(v); else |v| of v ~ N(0, s): 2 N(|v|; 0, s)
        return pt.switch(pinned, half_normal + v, half_normal - np.log(2.0))

    def random(s, rng=None, size=None):
        v = rng.normal(0.0, s, size=size)
        return np.where(pinned, np.log(np.abs(v)), v)

    free = pm.CustomDist(f"{name}_free", scale, logp=logp, random=random, dims="subject",
                         initval=np.where(pinned, np.log(start), start))
    return pm.Deterministic(name, to_value(free), dims="subject")


def squared_half_normal_block(name: str, scale, *, start: float):
    """Per subject ``name`` ~ HalfNormal(``scale``) as u², u unconstrained (``<name>_root``), starting at √``start``:
    the density of u, |u| p(u²), vanishes at ρ = 0 like |u|, a finite step, so a chain need not cross between ±u."""
    n = len(pm.modelcontext(None).coords["subject"])

    def logp(u, s):
        return pm.logp(pm.HalfNormal.dist(s), u**2) + pt.log(pt.abs(u))

    def random(s, rng=None, size=None):
        rho = np.abs(rng.normal(0.0, 1.0, size=size)) * s
        return np.sqrt(rho) * rng.choice([-1.0, 1.0], size=np.shape(rho))

    root = pm.CustomDist(f"{name}_root", scale, logp=logp, random=random, dims="subject",
                         initval=np.full(n, np.sqrt(start)))
    return pm.Deterministic(name, root**2, dims="subject")


def polar_noise_block(rho_scale, sigma_scale, k, *, start_rho: float, start_sigma: float):
    """Per subject ρ ~ HalfNormal(``rho_scale``) and σ_m ~ HalfNormal(``sigma_scale``) as (``noise_a``, ``noise_b``),
    polar where ``k`` > 0 (module docstring), starting at ``start_rho``, ``start_sigma``; returns (ρ, σ_m)."""
    k = np.asarray(k, dtype=float)
    n = len(pm.modelcontext(None).coords["subject"])
    if k.shape != (n,):
        raise ValueError(f"polar noise block: {k.size} values of k for {n} subjects")
    if np.any(np.isfinite(k) & ~(k > 0)) or np.any(np.isinf(k)):
        raise ValueError(f"polar noise block: k must be > 0 and finite (or NaN: not polar); got {k.tolist()}")
    polar = np.isfinite(k)
    kk = np.where(polar, k, 1.0)
    r0 = np.sqrt(start_rho**2 + kk * start_sigma**2)
    a0 = np.where(polar, np.log(r0), start_rho)
    b0 = np.where(polar, np.arctan2(np.sqrt(kk) * start_sigma, start_rho), start_sigma)

    def a_random(s_rho, s_m, rng=None, size=None):
        return draw_a(s_rho, s_m, k, rng, size)

    def b_random(a, s_rho, s_m, rng=None, size=None):
        return draw_b(np.broadcast_to(a, size) if size is not None else a, s_rho, s_m, k, rng)

    a = pm.CustomDist(NOISE_A, rho_scale, sigma_scale, logp=lambda v, s_rho, s_m: pt.zeros_like(v),
                      random=a_random, dims="subject", initval=a0)
    b = pm.CustomDist(NOISE_B, a, rho_scale, sigma_scale, logp=lambda v, a_, s_rho, s_m: noise_logp(a_, v, s_rho,
                                                                                                       s_m, k),
                      random=b_random, dims="subject", initval=b0)
    rho_t, sig_t = noise_values(a, b, k)
    return (pm.Deterministic("rho", pt.abs(rho_t), dims="subject"),
            pm.Deterministic("sigma_m", pt.abs(sig_t), dims="subject"))


__all__ = ["NOISE_A", "NOISE_B", "draw_a", "draw_b", "log_envelope", "mixed_half_normal_block", "noise_logp", "noise_values",
           "polar_noise_block", "squared_half_normal_block"]
