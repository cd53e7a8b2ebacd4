"""The fit's HDIs are ArviZ's; the difference to scioc's former interval is pinned here."""

import numpy as np
import pytest
import xarray as xr
from arviz_stats import hdi as az_hdi

from scioc.pipelines.fit.contrasts import HDI_PROB, condition_change, contrasts, hdi


def _former_hdi(x, prob=HDI_PROB):
    """scioc's interval until the switch to ArviZ: the shortest one holding ceil(prob · n) draws."""
    s = np.sort(np.ravel(x))
    n = s.shape[0]
    m = int(np.ceil(prob * n))
    i = int(np.argmin(s[m - 1:] - s[: n - m + 1]))
    return [float(s[i]), float(s[i + m - 1])]


def _inside(x, iv):
    return int(((x >= iv[0]) & (x <= iv[1])).sum())


@pytest.mark.parametrize("n", [4000, 400, 999, 1001])
def test_hdi_is_arviz_and_differs_from_the_former_one_only_when_prob_n_is_an_integer(n):
    x = np.random.default_rng(n).gamma(3.0, size=n)
    assert hdi(x) == [float(v) for v in az_hdi(x, prob=HDI_PROB)]
    k = HDI_PROB * n
    assert _inside(x, hdi(x)) == int(np.floor(k)) + 1
    assert _inside(x, _former_hdi(x)) == int(np.ceil(k))
    if k != int(k):
        assert hdi(x) == _former_hdi(x)
    else:  # 4000 draws (the default fit) and 400: ArviZ's interval holds one draw more
        assert _inside(x, hdi(x)) == _inside(x, _former_hdi(x)) + 1


def test_contrasts_summarize_beta_and_the_per_subject_changes():
    rng = np.random.default_rng(1)
    beta = rng.normal(-0.7, 0.05, (2, 300))
    lt1 = rng.normal(3.0, 0.1, (2, 300, 3, 2))
    lt1[..., 1] += beta[..., None]
    post = xr.Dataset({"beta": (("chain", "draw"), beta), "sigma_beta": (("chain", "draw"), np.abs(beta) / 7),
                       "beta_log_R": (("chain", "draw"), beta / 10),
                       "log_theta1": (("chain", "draw", "subject", "condition"), lt1)},
                      coords={"subject": ["S1", "S2", "S3"], "condition": ["MC", "SC"]})
    res = contrasts({"posterior": post})
    assert res["beta"]["mean"] == pytest.approx(beta.mean()) and res["beta"]["hdi"] == hdi(beta)
    assert res["ratio"]["hdi"] == hdi(np.exp(beta))
    change = condition_change(post)
    assert change.dims == ("chain", "draw", "subject")
    assert [s["subject"] for s in res["subjects"]] == ["S1", "S2", "S3"]
    assert res["subjects"][1]["hdi"] == hdi(change.sel(subject="S2").values)
