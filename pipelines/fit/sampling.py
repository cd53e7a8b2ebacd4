"""Sampling a PyMC model for ``scioc fit`` with nutpie: seeds, stdout kept clean, Ctrl-C honoured."""

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

    Parameters
    ----------
    cores : int, optional
        Chains run in parallel; default ``os.cpu_count()``, as PyMC's default halves it (it assumes hardware threads).
    nuts, target_accept : dict, float, optional
        nutpie's own options (e.g. ``{"adaptation": "low_rank"}``); the target acceptance rate over them.
    steps : list, optional
        Step methods for variables nutpie cannot update (a sampled delay): PyMC's compound step then samples the
        model, its own NUTS (numba-compiled) for the rest.
    initvals : dict, optional
        Where the chains start (:func:`scioc.pipelines.fit.start.start_point`), jittered per chain.

    Returns
    -------
    idata : DataTree
        The warm-up's leapfrog steps counted, its draws dropped (:func:`keep_tuning_steps`).
    seconds : dict
        ``compile_and_sample`` (wall time), ``sample`` (the sampler's own, warm-up included) and ``log_likelihood``.
    """
    import pymc as pm  # lazy: PyMC takes seconds to import

    if target_accept is not None:
        nuts = {**(nuts or {}), "target_accept": float(target_accept)}
    t0 = time.perf_counter()
    # In a log file the sampler's table would appear only when the fit has ended: a line a minute instead.
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

    # PyMC cannot rebuild a model with initial values (delayed_blocks.py's folded ρ) for the log-likelihood;
    # they only chose where the chains started, so they are left out for it and put back.
    initvals = dict(model.rvs_to_initial_values)
    model.rvs_to_initial_values.update(dict.fromkeys(initvals))
    try:
        pm.compute_log_likelihood(idata, model=model, progressbar=False)
    finally:
        model.rvs_to_initial_values.update(initvals)


def keep_tuning_steps(idata) -> None:
    """Record the warm-up's leapfrog steps in ``sample_stats.attrs`` (all chains, per chain, and the mean per draw in
    each tenth of the warm-up: which phase of the adaptation took them) and drop nutpie's warm-up groups."""
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
    """While sampling with nutpie through PyMC, write :func:`progress_line` to stderr every ``every`` seconds (through
    PyMC's ``NutpieProgressBarManager``; nothing if ``on`` is False or PyMC has no such class)."""
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
    """Send everything written to standard output, by Python or compiled code, to standard error: the sampler's
    progress tables are not results."""
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

    The previous handler still runs, and the caller can refuse a result the interruption cut short. Compiled code's
    callbacks (llvmlite's object cache, ctypes) print and drop a KeyboardInterrupt, so the signal is sent again every
    ``redeliver_every`` seconds until the code inside stops; inside llvmlite it is not raised at all, as that can crash.
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
