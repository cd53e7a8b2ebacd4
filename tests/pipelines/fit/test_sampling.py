"""The sampler's Ctrl-C guard: an interruption that compiled code swallows is not lost; progress in a log file."""

import os
import signal
import time

import pytest

from scioc.pipelines.fit.sampling import interrupt_guard


def _swallow_one_ctrl_c_then_wait(seconds: float) -> None:
    """Like numba compiling under llvmlite: a Ctrl-C inside a callback is printed and dropped; then work goes on."""
    try:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(5)
    except KeyboardInterrupt:
        pass
    deadline = time.perf_counter() + seconds
    while time.perf_counter() < deadline:
        time.sleep(0.01)


def test_a_swallowed_ctrl_c_is_sent_again_until_the_code_stops():
    before = signal.getsignal(signal.SIGINT)
    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        with interrupt_guard(redeliver_every=0.05) as interrupted:
            _swallow_one_ctrl_c_then_wait(20.0)
    assert time.perf_counter() - t0 < 5
    assert interrupted()
    assert signal.getsignal(signal.SIGINT) is before  # the guard's handler is gone


def test_negative_control_without_redelivery_the_swallowed_ctrl_c_is_lost():
    """The failure the guard exists for: sent once, the interruption is dropped and the work runs to its end."""
    t0 = time.perf_counter()
    with interrupt_guard(redeliver_every=3600.0) as interrupted:
        _swallow_one_ctrl_c_then_wait(0.5)
    assert time.perf_counter() - t0 >= 0.5
    assert interrupted()


def test_progress_lines_report_draws_divergences_and_steps_and_leave_the_draws_alone(capsys):
    # In a log file (not a terminal) nutpie's table would appear only at the end: scioc fit writes a line instead.
    # The same seed gives the same draws with and without the lines.
    import numpy as np
    import pymc as pm
    import pymc.sampling.mcmc as mcmc

    from scioc.pipelines.fit.sampling import progress_lines

    with pm.Model() as model:
        pm.Normal("x", 0.0, 1.0, shape=2)
    kw = {"draws": 30, "tune": 30, "chains": 2, "cores": 1, "random_seed": 3, "nuts_sampler": "nutpie",
          "progressbar": False, "model": model}
    base = mcmc.NutpieProgressBarManager
    with progress_lines(True, every=0.0):
        a = pm.sample(**kw)
    assert mcmc.NutpieProgressBarManager is base  # put back
    err = capsys.readouterr().err
    last = [line for line in err.splitlines() if line.startswith("sampling: ")][-1]
    assert last.startswith("sampling: 120 of 120 draws of 2 chains, 0 divergent, ") and "leapfrog steps per draw" in last
    with progress_lines(False, every=0.0):
        b = pm.sample(**kw)
    assert "sampling: " not in capsys.readouterr().err
    np.testing.assert_array_equal(a["posterior"]["x"].values, b["posterior"]["x"].values)


def test_the_warm_up_steps_are_counted_and_its_draws_dropped_without_changing_the_kept_draws():
    """The diagnostics report the warm-up's steps per draw (where the delayed fit's time goes); the kept draws
    are those of PyMC's default, which discards the warm-up."""
    import numpy as np
    import pymc as pm

    from scioc.pipelines.fit.diagnostics import diagnostics
    from scioc.pipelines.fit.sampling import sample_model

    with pm.Model() as model:
        mu = pm.Normal("mu_log_theta1", 0.0, 1.0)
        pm.Normal("y", mu, pm.HalfNormal("sigma_log_theta1", 1.0), observed=np.array([0.1, 0.3, -0.5]))
    idata, sec = sample_model(model, seed=3, chains=2, draws=40, tune=30, cores=1)
    assert not [g for g in idata.children if g.startswith("warmup")]
    sampler = diagnostics(idata, sec["sample"], ["mu_log_theta1"], [])["sampler"]
    assert sampler["tuning_mean_steps_per_draw"] >= 1.0
    assert idata["sample_stats"].attrs["tuning_draws"] == 30
    # by tenth of the warm-up (3 draws each here): their mean over the tenths is the warm-up's mean
    tenths = sampler["tuning_steps_by_tenth"]
    assert len(tenths) == 10 and min(tenths) >= 1.0
    assert np.mean(tenths) == pytest.approx(sampler["tuning_mean_steps_per_draw"], abs=0.06)
    plain = pm.sample(draws=40, tune=30, chains=2, cores=1, random_seed=3, nuts_sampler="nutpie", progressbar=False,
                      model=model)
    np.testing.assert_array_equal(idata["posterior"]["mu_log_theta1"].values, plain["posterior"]["mu_log_theta1"].values)


def test_target_accept_reaches_the_sampler_and_changes_its_step_size():
    """``target_accept`` is nutpie's: a higher rate adapts a smaller step size (the same seed otherwise);
    merged over the other nutpie options given."""
    import numpy as np
    import pymc as pm

    from scioc.pipelines.fit.sampling import sample_model

    with pm.Model() as model:
        mu = pm.Normal("mu", 0.0, 1.0)
        pm.Normal("y", mu, pm.HalfNormal("s", 1.0), observed=np.array([0.1, 0.3, -0.5]))
    step = {}
    for ta in (None, 0.8, 0.99):
        idata, _ = sample_model(model, seed=3, chains=1, draws=30, tune=200, cores=1, target_accept=ta,
                                nuts={"adaptation": "diag"})
        step[ta] = float(idata["sample_stats"]["step_size"].values[0, -1])
    assert step[None] == step[0.8]  # nutpie's default is 0.8
    assert step[0.99] < 0.7 * step[0.8]
