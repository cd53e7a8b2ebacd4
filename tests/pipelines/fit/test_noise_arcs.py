"""pipelines.fit.noise_arcs: a subject's arc between policy and motor noise, and its k, read off its likelihood."""

import numpy as np
import pytest

from scioc.pipelines.fit.noise_arcs import ARC_MIN, subject_arc


def _ring(rho2, sigma2, k, width=0.002, tilt=0.0):
    """A log-likelihood whose ridge is s ρ² + k v = ρ² + k σ² (an arc), ``width`` its SD across, ``tilt`` a pull
    along it towards s = 1 (the weakly identified position)."""
    c = rho2 + k * sigma2

    def loglik(s, v):
        return -0.5 * ((s * rho2 + k * v - c) / width) ** 2 - 0.5 * tilt * (s - 1.0) ** 2

    return loglik


@pytest.mark.parametrize("k", [1.5, 3.0, 10.0])
def test_an_arc_gives_its_k_and_a_fall_of_sigma_squared(k):
    """On an exact ridge ρ² + k σ_m² = c the maximizing σ_m² falls by 1.5 ρ² / k from s = ½ to 2: k comes back to the
    search's tolerance, and the fall is that, relative to σ_m² (σ_m² > 0 all along: see the next test for the bound)."""
    rho2, sigma2 = 0.1, 0.1
    fall, k_hat = subject_arc(_ring(rho2, sigma2, k, tilt=3.0), rho2, sigma2)
    assert k_hat == pytest.approx(k, rel=1e-3)
    assert fall == pytest.approx(1.5 * rho2 / k / sigma2, rel=1e-3)


def test_sigma_fixed_whatever_rho_is_no_arc():
    """Negative control: a likelihood that fixes σ_m² apart from ρ² (no trade-off) has no fall, and its k is not
    finite or far above any arc's: below ARC_MIN, so the subject keeps its folded centred coordinates."""
    rho2, sigma2 = 0.1, 0.06

    def apart(s, v):
        return -0.5 * ((v - sigma2) / 0.002) ** 2 - 0.5 * 30.0 * np.log(s) ** 2

    fall, k_hat = subject_arc(apart, rho2, sigma2)
    assert abs(fall) < 1e-3 < ARC_MIN
    assert not np.isfinite(k_hat) or k_hat > 1e3


def test_a_bound_at_zero_motor_noise_stops_the_fall_at_sigma_squared():
    """Where ρ² doubled would need a negative σ_m², the search stops at 0: the fall is at most 1 + the rise at s = ½."""
    rho2, sigma2, k = 0.02, 0.01, 1.0
    fall, _ = subject_arc(_ring(rho2, sigma2, k), rho2, sigma2)
    assert fall == pytest.approx((0.5 * rho2 / k + sigma2) / sigma2, rel=1e-3)


def test_a_subject_without_estimates_for_every_unit_keeps_the_folded_centred_coordinates():
    """noise_arcs: a subject one of whose units has no ML estimate (or whose ρ or σ_m is 0) gets k NaN, not an error;
    nothing of its data is read."""
    import math
    from types import SimpleNamespace

    import pandas as pd

    from scioc.pipelines.fit.noise_arcs import noise_arcs

    design = SimpleNamespace(ordered_levels=("MC", "SC"), wheel=None)
    prepared = SimpleNamespace(units={("S1", "MC"): [0], ("S1", "SC"): [1], ("S2", "MC"): [2], ("S2", "SC"): [3]},
                               settings=SimpleNamespace(design=design), segments=None)
    est = pd.DataFrame({"subject": ["S1", "S2", "S2"], "condition": ["MC", "MC", "SC"], "theta1": 1.0,
                        "theta2": 0.1, "R": 5.0, "tau_nm": 0.05, "sigma_m": [0.2, 0.0, 0.0]})
    ks, record = noise_arcs(prepared, None, est, [10, 10, 10, 10], None, ["S1", "S2"])
    assert all(math.isnan(k) for k in ks)
    assert record == {"S1": {"fall": None, "k": None}, "S2": {"fall": None, "k": None}}
    with pytest.raises(ValueError, match="sigma_m"):
        noise_arcs(prepared, None, est.drop(columns="sigma_m"), [10] * 4, None, ["S1"])
