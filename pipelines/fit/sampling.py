"""Sampling a PyMC model for ``scioc fit`` (nutpie; PyMC's compound step for a sampled delay): seeds, stdout kept
clean, Ctrl-C honoured."""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time

import numpy as np


def child_seeds(seed: int) -> dict:
    """The fit's four seeds from ``SeedSequence(seed).spawn(4)``: both samplers, the predictive draws, LOSO."""
    sampler, pooled, ppc, loso = np.random.SeedSequence(int(seed)).spawn(4)
    return {"condition": int(sampler.generate_state(1)[0]), "pooled": int(pooled.generate_state(1)[0]),
            "ppc": int(ppc.generate_state(1)[0]), "loso": int(loso.generate_state(1)[0])}


def sample_model(model, *, seed: int, chains: int, draws: int, tune: int, cores: int | None = None,
                 show_progress: bool = False, log_likelihood: bool = True, nuts: dict | None = None, steps=None,
                 initvals: dict | None = None, target_accept: float | None = None):
    """Sample ``model`` with nutpie (through ``pm.sample``) and add the pointwise log-likelihood.

    ``log_likelihood=False`` skips the pointwise log-likelihood (for timing the fit alone).
    ``nuts``: nutpie's own options (e.g. ``{"adaptation": "low_rank"}``), passed on only
    when given, so that a fit without them is exactly as before.
    ``cores`` (chains run in parallel) defaults to ``os.cpu_count()``. It is passed
    explicitly because PyMC's own default halves the CPU count (it assumes hardware
    threads): on a 2-core machine nutpie then ran the chains one at a time, measured
    2.0× slower sampling on the default study.

    ``steps``: step methods for some of the model's variables (e.g. a sampled delay, which
    nutpie cannot update): the model is then sampled by PyMC's compound step, ``steps`` for
    their variables and PyMC's own NUTS (diagonal mass matrix) for the rest, compiled by numba.

    With nutpie the warm-up's leapfrog steps are counted and its draws dropped
    (:func:`keep_tuning_steps`).

    ``target_accept``: the NUTS target acceptance rate (nutpie's, or PyMC's NUTS's beside ``steps``),
    over any in ``nuts``; None leaves the sampler's own (nutpie's 0.8, or ``nuts``'s).

    ``initvals``: where the chains start (RV name -> value; :func:`scioc.pipelines.fit.start.start_point`),
    jittered per chain as PyMC's own start is; passed on only when given.

    Returns
    -------
    idata : DataTree
    seconds : dict
        ``compile_and_sample`` (wall time of ``pm.sample``), ``sample`` (nutpie's own
        sampling time, tuning included, compilation excluded) and ``log_likelihood``.
    """
    import pymc as pm  # lazy: PyMC takes seconds to import

    if target_accept is not None:
        nuts = {**(nuts or {}), "target_accept": float(target_accept)}
    t0 = time.perf_counter()
    # On a terminal the sampler's own table; in a log file (not a terminal) a line a minute instead, as the
    # table would appear only when the fit has ended.
    lines = show_progress and not steps and not sys.stderr.isatty()
    with stdout_to_stderr(), interrupt_guard() as interrupted, progress_lines(lines):
        sampler = ({"step": list(steps), "compute_convergence_checks": False, "compile_kwargs": {"mode": "NUMBA"}}
                   if steps else {"nuts_sampler": "nutpie", "discard_tuned_samples": False})
        if nuts:
            sampler["nuts"] = dict(nuts)
        try:
            idata = pm.sample(draws=draws, tune=tune, chains=chains, cores=cores or os.cpu_count() or 1,
                              random_seed=seed, progressbar=show_progress and not lines,
                              quiet=not show_progress, model=model, **sampler,
                              **({"initvals": dict(initvals)} if initvals else {}))
        except BaseException as exc:
            if interrupted():  # a Ctrl-C inside nutpie's Rust code comes out as a PanicException, say
                raise KeyboardInterrupt from exc
            raise
    if interrupted():
        # nutpie stops on Ctrl-C and returns the draws so far; a partial posterior is not a result.
        raise KeyboardInterrupt
    keep_tuning_steps(idata)
    t1 = time.perf_counter()
    if log_likelihood:
        add_log_likelihood(idata, model)
    t2 = time.perf_counter()
    attrs = idata["sample_stats" if steps else "posterior"].attrs  # PyMC's own sampler records it there
    return idata, {"compile_and_sample": t1 - t0, "sample": float(attrs.get("sampling_time", t1 - t0)),
                   "log_likelihood": t2 - t1}


def add_log_likelihood(idata, model) -> None:
    """Add the pointwise log-likelihood of ``model`` at ``idata``'s posterior draws (group ``log_likelihood``)."""
    import pymc as pm

    # PyMC cannot rebuild a model with initial values (the folded ρ's of delayed_blocks.py) for the
    # log-likelihood; they only chose where the chains started, so they are left out for it and put back.
    initvals = dict(model.rvs_to_initial_values)
    model.rvs_to_initial_values.update(dict.fromkeys(initvals))
    try:
        pm.compute_log_likelihood(idata, model=model, progressbar=False)
    finally:
        model.rvs_to_initial_values.update(initvals)


def keep_tuning_steps(idata) -> None:
    """Record the warm-up's leapfrog steps in ``sample_stats.attrs`` and drop nutpie's warm-up groups.

    ``tuning_leapfrog_steps`` (all chains) and ``tuning_draws`` (per chain), so that
    :func:`scioc.pipelines.fit.diagnostics.diagnostics` can say where the sampling time went: the
    kept draws' steps alone do not (the delayed fit's warm-up took most of it). And
    ``tuning_steps_by_tenth``: the mean steps per draw (all chains) in each tenth of the
    warm-up, in order, which says which phase of nutpie's adaptation the steps went to. The
    warm-up draws themselves are not kept (nutpie hands them back only so that this can be counted).
    """
    names = [g for g in list(idata.children) if g.startswith("warmup_")]
    if "warmup_sample_stats" in names:
        n = idata["warmup_sample_stats"]["n_steps"].values
        idata["sample_stats"].attrs["tuning_leapfrog_steps"] = int(n.sum())
        idata["sample_stats"].attrs["tuning_draws"] = int(n.shape[1])
        idata["sample_stats"].attrs["tuning_steps_by_tenth"] = np.array(
            [float(part.mean()) for part in np.array_split(n, 10, axis=1) if part.size])
    for g in names:
        del idata[g]


def progress_line(chain_progresses, seconds: float) -> str:
    """One line of nutpie's progress (a list of ``nutpie.ChainProgress``): draws done, divergences, steps per draw."""
    done = sum(cp.finished_draws for cp in chain_progresses)
    total = sum(cp.total_draws for cp in chain_progresses)
    tuning = sum(bool(cp.tuning) and bool(cp.started) for cp in chain_progresses)
    steps = sum(cp.total_num_steps for cp in chain_progresses)
    divergent = sum(cp.divergences for cp in chain_progresses)
    return (f"sampling: {done} of {total} draws of {len(chain_progresses)} chains"
            + (f" ({tuning} tuning)" if tuning else "") + f", {divergent} divergent, "
            + (f"{steps / done:.1f} leapfrog steps per draw, " if done else "") + f"{seconds / 60:.1f} min")


@contextlib.contextmanager
def progress_lines(on: bool, every: float = 60.0):
    """While sampling with nutpie through PyMC, write :func:`progress_line` to stderr every ``every`` seconds.

    PyMC hands nutpie's progress to its ``NutpieProgressBarManager``; inside this context that
    class also writes the lines (the draws do not change). Nothing happens when ``on`` is False
    or PyMC no longer has that class.
    """
    import pymc.sampling.mcmc as mcmc

    base = getattr(mcmc, "NutpieProgressBarManager", None)
    if not on or base is None:
        yield
        return
    start = time.monotonic()

    class WithLines(base):
        _last = start

        def update(self, chain_progresses) -> None:
            super().update(chain_progresses)
            now = time.monotonic()
            if now - self._last >= every:
                type(self)._last = now
                print(progress_line(chain_progresses, now - start), file=sys.stderr, flush=True)

    mcmc.NutpieProgressBarManager = WithLines
    try:
        yield
    finally:
        mcmc.NutpieProgressBarManager = base


@contextlib.contextmanager
def stdout_to_stderr():
    """Send everything written to standard output, by Python or by compiled code, to standard error.

    The sampler's progress tables are progress, not results: results go to stdout.
    """
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


@contextlib.contextmanager
def interrupt_guard(redeliver_every: float = 1.0):
    """Note a Ctrl-C (SIGINT) even if the code inside catches it; yields a function that tells.

    The previous handler still runs (Python's raises KeyboardInterrupt), so the code inside
    stops as it would; afterwards the caller can refuse a result the interruption cut short.

    A KeyboardInterrupt raised inside a callback from compiled code (llvmlite's object cache
    while numba compiles, a ctypes callback) is printed and dropped, and the sampler would go
    on for hours. So after the first Ctrl-C the signal is sent again every ``redeliver_every``
    seconds until the code inside has stopped; nutpie returns at the first one it sees. Inside
    llvmlite's callbacks it is not raised at all (measured: once in 12 tries the process then
    died of a segmentation fault instead of exiting 130); the next one is.
    """
    seen = []
    if threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return
    previous = signal.getsignal(signal.SIGINT)
    stopped = threading.Event()

    def redeliver():
        while not stopped.wait(redeliver_every):
            os.kill(os.getpid(), signal.SIGINT)

    resender = threading.Thread(target=redeliver, name="scioc-interrupt", daemon=True)

    def handler(signum, frame):
        if not seen:
            resender.start()
        seen.append(signum)
        if frame is not None and "llvmlite" in frame.f_code.co_filename:
            return  # inside a callback from LLVM, which would drop it and may crash: the next one comes in a second
        if callable(previous):
            previous(signum, frame)
        else:
            raise KeyboardInterrupt

    signal.signal(signal.SIGINT, handler)
    try:
        yield lambda: bool(seen)
    finally:
        stopped.set()
        if resender.is_alive():
            resender.join()
        signal.signal(signal.SIGINT, previous)
