"""``scioc assistant``: the MPC assistant alone on the study reference (nobody holds the wheel).

The paper's θ_A = [5, 0, 1] gives "slight assistance"; this shows how well it tracks alone and at what torque.
"""

from __future__ import annotations

import numpy as np

from scioc.models.assistant import design_assistant, simulate_closed_loop
from scioc.models.plant import DT_HUMAN, discretize
from scioc.models.reference import reference_trajectory, window_slice


def assistant_alone(seconds: float = 240.0) -> dict:
    """Wheel + assistant in closed loop with u_H = 0 for ``seconds``: per run and analysis window, the
    reference's, the tracking error's (also with nobody steering) and the torque's RMS and peak."""
    plant = discretize(DT_HUMAN)
    ref = reference_trajectory(seconds)
    x0 = [ref.angle[0], 0.0]
    run = simulate_closed_loop(plant, design_assistant(), x0, ref.angle)
    passive = simulate_closed_loop(plant, None, x0, ref.angle)
    out = {}
    windows = [("run", slice(None))]
    if window_slice().stop <= ref.t.shape[0]:
        windows.append(("window", window_slice()))
    for name, sl in windows:
        r = ref.angle[sl]
        e = run.x[sl, 0] - r
        u = run.u_A[sl][:-1] if sl.stop is not None else run.u_A
        out[name] = {
            "reference_rms_rad": float(np.sqrt(np.mean(r**2))),
            "reference_peak_rad": float(np.abs(r).max()),
            "reference_peak_rate_rad_s": float(np.abs(np.diff(r)).max() / DT_HUMAN),
            "error_rms_rad": float(np.sqrt(np.mean(e**2))),
            "error_peak_rad": float(np.abs(e).max()),
            "error_rms_nobody_steering_rad": float(np.sqrt(np.mean((passive.x[sl, 0] - r) ** 2))),
            "u_A_rms_Nm": float(np.sqrt(np.mean(u**2))),
            "u_A_peak_Nm": float(np.abs(u).max()),
        }
    return out


def format_assistant(res: dict) -> str:
    lines = ["MPC assistant alone (θ_A = [5, 0, 1], N_P = 50 × 0.02 s), u_H = 0, study reference"]
    lines.append(f"{'':>30} {'whole run':>10} {'window':>10}")
    for key, label in (
        ("reference_rms_rad", "reference RMS (rad)"),
        ("reference_peak_rad", "reference peak (rad)"),
        ("reference_peak_rate_rad_s", "reference peak rate (rad/s)"),
        ("error_rms_rad", "tracking error RMS (rad)"),
        ("error_peak_rad", "tracking error peak (rad)"),
        ("error_rms_nobody_steering_rad", "error, nobody steering (rad)"),
        ("u_A_rms_Nm", "assistant torque RMS (N·m)"),
        ("u_A_peak_Nm", "assistant torque peak (N·m)"),
    ):
        window = f"{res['window'][key]:>10.3f}" if "window" in res else f"{'-':>10}"
        lines.append(f"{label:>30} {res['run'][key]:>10.3f} {window}")
    return "\n".join(lines)
