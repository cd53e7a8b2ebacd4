"""The batched angle log-likelihood of the ``delayed`` human as a PyTensor Op, with a numba implementation.

For recordings without a torque sensor: each window's ``log p(y_1..y_K | y_0)`` of the encoder's angles
(:func:`scioc.models.delayed.window_loglik`) and its exact gradient in (θ, τ_nm, σ_m), all windows in one compiled
call. The lagged wheel and its τ_nm-derivative come from the lag's closed form
(:func:`scioc.models.bayes.delayed_lag.lagged_wheel_nb`), the arm torque at each window's start from the torques before it, as in the torque Op
(:mod:`scioc.models.bayes.delayed_op`). With delay, lag and motor noise at zero this is the max-ent human's likelihood
of the angles, which is how the max-ent model is fitted through the same likelihood.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytensor.tensor as pt
from pytensor.graph.basic import Apply
from pytensor.graph.op import Op
from pytensor.link.numba.dispatch import basic as numba_basic
from pytensor.link.numba.dispatch.basic import numba_funcify

from scioc.models.bayes.delayed_lag import lag_nb, lagged_wheel_nb, wheel_constants
from scioc.models.bayes.delayed_op import N_PARAMETER_INPUTS, ParameterGradient, pack_tau0, window_start_torque
from scioc.models.delayed.angle_kernel import OUT, window_kernel
from scioc.models.delayed.angles import START_SD, AngleWindow
from scioc.models.delayed.lag import check_wheel
from scioc.models.delayed.sample import known_inputs
from scioc.models.design import WheelParameters
from scioc.models.plant import DiscretePlant
from scioc.models.runtime import njit


@njit(cache=True, fastmath=False, error_model="numpy")
def _evaluate(wheel, Phi, b, theta, tau_nm, sigma_m, rows, delay, s2y, y, ylen, ref, known, nlen, gain, vel0, warm,
              wstart, tstart, p0, grad):
    """Point i: window ``rows[i]`` at θ[:, i], τ_nm[i], σ_m[i]; (log-likelihood (P,), gradient (5, P))."""
    dt, A_c, b_w, Pb, b1, poles = wheel
    n = rows.shape[0]
    J = warm.shape[1]
    ll = np.empty(n)
    g = np.zeros((5, n))
    tau = np.empty(J + 1)
    dtau = np.empty((J + 1, 2))
    dct = np.empty((max(J, 1), 2))
    ba = np.array([b[0], b[1], 0.0])
    out = np.empty(OUT)
    for i in range(n):
        w = rows[i]
        la, al, da, dal = lag_nb(tau_nm[i], dt, A_c, b_w, Pb, b1, poles)
        tau0, dtau0_a, dtau0_al = window_start_torque(la, al, warm[w], wstart[w], tstart[w], tau, dtau, dct)
        A, bc, dA, dbc_t = lagged_wheel_nb(tau_nm[i], dt, A_c, b_w, Phi, b, poles)
        Ab = A.copy()
        for r in range(3):
            Ab[r, 0] -= ba[r] * gain[w, 0]
            Ab[r, 1] -= ba[r] * gain[w, 1]
        dAb = np.zeros((3, 3, 4))
        dbc = np.zeros((3, 4))
        for r in range(3):
            dbc[r, 2] = dbc_t[r]
            for c in range(3):
                dAb[r, c, 2] = dA[r, c]
        K = ylen[w]
        N = nlen[w]
        mu0 = np.array([y[w, 0], vel0[w], tau0])
        P0 = np.diag(np.array([s2y, p0[0], p0[1]]))
        inn = np.empty(K - 1)
        window_kernel(Ab, bc, ba, dAb, dbc, theta[0, i], theta[1, i], theta[2, i], ref[w, :N + 1], known[w, :N],
                      delay[w], sigma_m[i] ** 2, s2y, y[w, :K], mu0, P0, True, grad, inn, out)
        ll[i] = out[0]
        if grad:
            g[0, i] = out[1]
            g[1, i] = out[2]
            g[2, i] = out[3]
            g[3, i] = out[4] + out[8] * (dtau0_a * da + dtau0_al * dal)
            g[4, i] = 2.0 * sigma_m[i] * out[5]
    return ll, g


def _frozen(x, dtype=np.float64) -> np.ndarray:
    arr = np.array(x, dtype=dtype, order="C", copy=True)
    arr.flags.writeable = False
    return arr


def pack_windows(windows: Sequence[AngleWindow]) -> dict:
    """The windows' arrays padded to common lengths, with each window's lengths, for :func:`_evaluate`."""
    n = len(windows)
    if n == 0:
        raise ValueError("need at least one window")
    parts = [known_inputs(w.angle_ref, w.u_A, w.feedback) for w in windows]
    ylen = np.array([np.asarray(w.angles).shape[0] for w in windows], dtype=np.int64)
    nlen = np.array([k.shape[0] for _, k, _ in parts], dtype=np.int64)
    if np.any(ylen < 2) or np.any(ylen > nlen + 1):
        raise ValueError("each window needs 2 <= K + 1 <= its plan's length + 1 angles")
    y = np.zeros((n, int(ylen.max())))
    ref = np.zeros((n, int(nlen.max()) + 1))
    known = np.zeros((n, int(nlen.max())))
    for i, (w, (r, k, _)) in enumerate(zip(windows, parts)):
        y[i, :ylen[i]] = np.asarray(w.angles, dtype=float)
        ref[i, :nlen[i] + 1] = r
        known[i, :nlen[i]] = k
    if not (np.isfinite(y).all() and np.isfinite(ref).all() and np.isfinite(known).all()):
        raise ValueError("the windows' angles, references and assistant inputs must be finite")
    warm, wstart, tstart = pack_tau0([w.warmup for w in windows], n)
    vel0 = np.array([float(w.velocity0) for w in windows])
    if not np.isfinite(vel0).all():
        raise ValueError("the windows' start velocities must be finite")
    return {"y": y, "ylen": ylen, "ref": ref, "known": known, "nlen": nlen,
            "gain": np.array([g for _, _, g in parts], dtype=float).reshape(n, 2), "vel0": vel0, "warm": warm,
            "wstart": wstart, "tstart": tstart}


def _constants(plant: DiscretePlant, sigma_y: float, params: WheelParameters):
    """What both Ops compile in: the wheel's constants, Φ, b, σ_y² and the start's prior variances."""
    check_wheel(plant, params)
    if not (np.isfinite(sigma_y) and sigma_y > 0):
        raise ValueError(f"sigma_y must be a positive number of rad; got {sigma_y!r}")
    return (wheel_constants(plant.dt, params), _frozen(plant.A), _frozen(plant.b), float(sigma_y) ** 2,
            _frozen(np.square(START_SD)))


#: The data inputs of :class:`AngleLoglikDataOp` after θ, τ_nm and σ_m: each window's delay and
#: :func:`pack_windows`'s arrays.
ANGLE_DATA_NAMES = ("delay", "y", "ylen", "ref", "known", "nlen", "gain", "vel0", "warm", "wstart", "tstart")
_INT_DATA = ("delay", "ylen", "nlen", "wstart")


def angle_data(windows: Sequence[AngleWindow], delay) -> dict:
    """The inputs of :class:`AngleLoglikDataOp` by :data:`ANGLE_DATA_NAMES`: the windows and each one's delay."""
    data = pack_windows(windows)
    n = data["y"].shape[0]
    d = np.broadcast_to(np.asarray(delay), (n,))
    if not (np.all(np.isfinite(d.astype(float))) and np.all(d == np.round(d)) and np.all(d >= 0)):
        raise ValueError(f"delay must be whole numbers of samples >= 0, one per window; got {delay!r}")
    return {"delay": np.ascontiguousarray(d, dtype=np.int64), **data}


class AngleLoglikOp(ParameterGradient, Op):
    """Per-window angle log-likelihood for fixed recorded windows: inputs θ (3, n), τ_nm (n,), σ_m (n,); outputs
    ``loglik`` (n,), nats, and ``grad`` (5, n) in each window's q11, q22, R, τ_nm, σ_m.

    ``windows``: the recorded windows (:class:`scioc.models.delayed.AngleWindow`); ``delay``: each window's delay,
    samples; ``sigma_y``: the encoder's noise SD, rad; ``plant``: the wheel at the recording's sample time, ``params``
    the wheel it was discretized from.
    """

    __eq__ = object.__eq__
    __hash__ = object.__hash__

    def __init__(self, windows: Sequence[AngleWindow], plant: DiscretePlant, *, delay, sigma_y: float,
                 params: WheelParameters = WheelParameters()):
        self.wheel, self.Phi, self.b, self.s2y, self.p0 = _constants(plant, sigma_y, params)
        data = angle_data(windows, delay)
        self.delay = _frozen(data.pop("delay"), np.int64)
        self.data = {k: _frozen(v, v.dtype) for k, v in data.items()}
        self.n = self.delay.shape[0]
        self.rows = _frozen(np.arange(self.n), np.int64)

    def __str__(self):
        return f"AngleLoglik{{n={self.n}, d={int(self.delay.min())}..{int(self.delay.max())}}}"

    def _args(self):
        D = self.data
        return (self.rows, self.delay, self.s2y, D["y"], D["ylen"], D["ref"], D["known"], D["nlen"], D["gain"], D["vel0"],
                D["warm"], D["wstart"], D["tstart"], self.p0)

    def make_node(self, theta, tau_nm, sigma_m):
        theta, tau_nm, sigma_m = (pt.cast(pt.as_tensor_variable(v), "float64") for v in (theta, tau_nm, sigma_m))
        if theta.type.ndim != 2 or tau_nm.type.ndim != 1 or sigma_m.type.ndim != 1:
            raise TypeError(f"theta must be a matrix (3, {self.n}), tau_nm and sigma_m vectors ({self.n},)")
        theta = pt.specify_shape(theta, (3, self.n))
        tau_nm = pt.specify_shape(tau_nm, (self.n,))
        sigma_m = pt.specify_shape(sigma_m, (self.n,))
        return Apply(self, [theta, tau_nm, sigma_m], [pt.dvector(shape=(self.n,)), pt.dmatrix(shape=(5, self.n))])

    def values(self, inputs, grad: bool = True):
        """(log-likelihood (n,), gradient (5, n)) at the parameters ``inputs``; ``grad`` False: the value alone."""
        theta, tau_nm, sigma_m = (np.ascontiguousarray(v, dtype=np.float64) for v in inputs[:N_PARAMETER_INPUTS])
        return _evaluate(self.wheel, self.Phi, self.b, theta, tau_nm, sigma_m, *self._args(), grad)

    def window_values(self, j: int, theta, tau_nm, sigma_m) -> np.ndarray:
        """Window j's log-likelihood (P,) at P points: θ (3, P), τ_nm (P,), σ_m (P,)."""
        theta, tau_nm, sigma_m = (np.ascontiguousarray(v, dtype=np.float64) for v in (theta, tau_nm, sigma_m))
        rows = np.full(tau_nm.shape[0], int(j), dtype=np.int64)
        return _evaluate(self.wheel, self.Phi, self.b, theta, tau_nm, sigma_m, rows, *self._args()[1:], False)[0]

    def infer_shape(self, node, input_shapes):
        return [(self.n,), (5, self.n)]


@numba_funcify.register(AngleLoglikOp)
def numba_funcify_angle_loglik(op: AngleLoglikOp, node=None, **kwargs):
    """Numba implementation of :class:`AngleLoglikOp`, no object mode."""
    wheel, Phi, b = op.wheel, op.Phi, op.b
    args = op._args()
    rows, delay, s2y, y, ylen, ref, known, nlen, gain, vel0, warm, wstart, tstart, p0 = args
    evaluate = _evaluate

    @numba_basic.numba_njit
    def angle_loglik(theta, tau_nm, sigma_m):
        c = np.ascontiguousarray
        return evaluate(wheel, Phi, b, c(theta), c(tau_nm), c(sigma_m), rows, delay, s2y, y, ylen, ref, known, nlen,
                        gain, vel0, warm, wstart, tstart, p0, True)

    return angle_loglik


class AngleLoglikDataOp(ParameterGradient, Op):
    """:class:`AngleLoglikOp` with the windows as inputs, so one compiled model serves every data set of one shape
    (``pm.Data``) and the delay can be a graph (sampled). Inputs: θ (3, n), τ_nm (n,), σ_m (n,), then
    :data:`ANGLE_DATA_NAMES` (:func:`angle_data`); outputs as :class:`AngleLoglikOp`'s."""

    __props__ = ("key",)

    def __init__(self, plant: DiscretePlant, *, sigma_y: float, params: WheelParameters = WheelParameters()):
        self.wheel, self.Phi, self.b, self.s2y, self.p0 = _constants(plant, sigma_y, params)
        self.key = (tuple(self.Phi.ravel().tolist()), tuple(self.b.tolist()), float(plant.dt), tuple(params), self.s2y)

    def make_node(self, theta, tau_nm, sigma_m, *data):
        if len(data) != len(ANGLE_DATA_NAMES):
            raise TypeError(f"need the inputs {', '.join(ANGLE_DATA_NAMES)} after theta, tau_nm and sigma_m")
        theta, tau_nm, sigma_m = (pt.cast(pt.as_tensor_variable(v), "float64") for v in (theta, tau_nm, sigma_m))
        if theta.type.ndim != 2 or tau_nm.type.ndim != 1 or sigma_m.type.ndim != 1:
            raise TypeError("theta must be a matrix (3, n), tau_nm and sigma_m vectors (n,)")
        data = [pt.cast(pt.as_tensor_variable(v), "int64" if name in _INT_DATA else "float64")
                for name, v in zip(ANGLE_DATA_NAMES, data)]
        return Apply(self, [theta, tau_nm, sigma_m, *data], [pt.dvector(), pt.dmatrix()])

    def values(self, inputs, grad: bool = True):
        """(log-likelihood (n,), gradient (5, n)) at the parameters and data ``inputs`` (the Op's order)."""
        theta, tau_nm, sigma_m = (np.ascontiguousarray(v, dtype=np.float64) for v in inputs[:N_PARAMETER_INPUTS])
        d = dict(zip(ANGLE_DATA_NAMES, (np.ascontiguousarray(v) for v in inputs[N_PARAMETER_INPUTS:])))
        rows = np.arange(theta.shape[1], dtype=np.int64)
        return _evaluate(self.wheel, self.Phi, self.b, theta, tau_nm, sigma_m, rows, d["delay"], self.s2y, d["y"],
                         d["ylen"], d["ref"], d["known"], d["nlen"], d["gain"], d["vel0"], d["warm"], d["wstart"],
                         d["tstart"], self.p0, grad)

    def infer_shape(self, node, input_shapes):
        n = input_shapes[0][1]
        return [(n,), (5, n)]


@numba_funcify.register(AngleLoglikDataOp)
def numba_funcify_angle_loglik_data(op: AngleLoglikDataOp, node=None, **kwargs):
    """Numba implementation of :class:`AngleLoglikDataOp`, no object mode."""
    wheel, Phi, b, s2y, p0 = op.wheel, op.Phi, op.b, op.s2y, op.p0
    evaluate = _evaluate

    @numba_basic.numba_njit
    def angle_loglik_data(theta, tau_nm, sigma_m, delay, y, ylen, ref, known, nlen, gain, vel0, warm, wstart, tstart):
        c = np.ascontiguousarray
        rows = np.arange(theta.shape[1])
        return evaluate(wheel, Phi, b, c(theta), c(tau_nm), c(sigma_m), rows, c(delay), s2y, c(y), c(ylen), c(ref),
                        c(known), c(nlen), c(gain), c(vel0), c(warm), c(wstart), c(tstart), p0, True)

    return angle_loglik_data


__all__ = ["ANGLE_DATA_NAMES", "AngleLoglikDataOp", "AngleLoglikOp", "angle_data", "numba_funcify_angle_loglik",
           "numba_funcify_angle_loglik_data", "pack_windows"]
