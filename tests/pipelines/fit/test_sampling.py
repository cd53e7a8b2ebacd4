"""The sampler's Ctrl-C guard: an interruption that compiled code swallows is not lost."""

import os
import signal
import time

import pytest

from pipelines.fit.sampling import interrupt_guard


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
