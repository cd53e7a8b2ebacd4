"""numba's cache is keyed by the code of the whole package, so a changed callee is never served stale; prose does
not key it; and what it serves computes the same bits as a fresh compile."""

import numba
import pytest

from scioc.models.runtime import numba_cache_dir


def test_the_cache_folder_changes_with_any_code_but_not_with_prose(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "a.py").write_text("x = 1\n")
    (pkg / "sub" / "b.py").write_text('"""A module."""\ndef f():\n    """Its doc."""\n    return 2  # why\n')
    first = numba_cache_dir(pkg, tmp_path / "cache")
    assert first.parent == tmp_path / "cache"
    assert numba_cache_dir(pkg, tmp_path / "cache") == first  # same sources, same folder
    (pkg / "sub" / "b.py").write_text('"""Another."""\n# a comment\ndef f():\n    """Other doc."""\n    return 2\n')
    assert numba_cache_dir(pkg, tmp_path / "cache") == first  # docstrings and comments do not key it
    (pkg / "sub" / "b.py").write_text('"""A module."""\ndef f():\n    """Its doc."""\n    return 3  # why\n')
    second = numba_cache_dir(pkg, tmp_path / "cache")
    assert second != first
    (pkg / "sub" / "b.py").rename(pkg / "b2.py")  # a move changes it too
    assert numba_cache_dir(pkg, tmp_path / "cache") not in (first, second)


def test_configure_points_numba_at_the_folder_of_this_code():
    from pathlib import Path

    from scioc.models.bayes.delayed_op import warm_samples  # a cache=True kernel

    assert Path(numba.config.CACHE_DIR).name == numba_cache_dir().name  # ~/.cache, or the temp dir if unwritable
    assert warm_samples(0.5, 0.1) > 0
    cached = [p.name for p in Path(numba.config.CACHE_DIR).rglob("*.nbi")]
    assert any(name.startswith("delayed_op.warm_samples") for name in cached), cached


#: Run in a fresh interpreter: the delayed and max-ent likelihoods with gradients, through the kernels and through
#: their PyTensor Ops compiled by numba, and a few seeded nutpie draws of each unit model; prints a digest of every
#: output's bits and the cache hits of the kernels it called.
PROBE = """
import scioc; scioc.configure()
import hashlib, json, warnings
import numba, numpy as np, pytensor, pytensor.tensor as pt
from scioc.models import delayed, maxent
from scioc.models.bayes.delayed_op import DelayedLoglikOp
from scioc.models.bayes.delayed_windows import delayed_windows
from scioc.models.bayes.op import MaxEntLoglikOp
from scioc.models.delayed.kernel import batch_kernel, batch_kernel_serial
from scioc.models.delayed.lag import Warmup
from scioc.models.plant import discretize
from scioc.models.segment import prepare_batch
warnings.simplefilter("ignore")
plant = discretize(0.01)
w = delayed_windows(3, np.random.default_rng(2), K=300, preview=50, delay=(0, 25))
batch = prepare_batch(plant, w.segments)
warm = [Warmup(np.random.default_rng(i).normal(0, 0.3, 60), 0.1) for i in range(batch.n)]
digest = lambda *xs: hashlib.sha256(b"".join(np.ascontiguousarray(x).tobytes() for x in xs)).hexdigest()
out = {}
for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):  # the serial kernel, then the parallel one
    numba.set_num_threads(threads)
    r = delayed.loglik_grad(w.theta, batch, plant, tau_nm=w.tau_nm, sigma_m=w.sigma_m, delay=w.delay, tau0=0.1)
    out[f"delayed kernel, {threads} threads"] = digest(r.loglik, r.grad)
r = maxent.loglik_grad(w.theta, batch, plant)
out["max-ent kernel"] = digest(r.loglik, r.grad)
th, tt, ss = pt.dmatrix(), pt.dvector(), pt.dvector()
logp = DelayedLoglikOp(batch, plant, delay=w.delay, tau0=warm)(th, tt, ss)[0].sum()
f = pytensor.function([th, tt, ss], [logp, *pytensor.grad(logp, [th, tt, ss])], mode="NUMBA")
out["delayed Op"] = digest(*f(w.theta, w.tau_nm, w.sigma_m))
logp = MaxEntLoglikOp(batch, plant)(th)[0].sum()
f = pytensor.function([th], [logp, pytensor.grad(logp, th)], mode="NUMBA")
out["max-ent Op"] = digest(*f(w.theta))
# The fit's path: PyMC model, PyTensor's graph compiled by numba (nutpie), a few seeded draws.
import nutpie
from scioc.models.bayes.unit_delayed import build_unit_delayed_model
from scioc.models.bayes.unit_model import build_unit_model
one = prepare_batch(plant, w.segments[:1])
for name, model in (("max-ent unit fit", build_unit_model(one, plant)),
                    ("delayed unit fit", build_unit_delayed_model(one, plant, delay=int(w.delay[0])))):
    trace = nutpie.sample(nutpie.compile_pymc_model(model, backend="numba"), chains=1, tune=30, draws=10, seed=1,
                          cores=1, progress_bar=False)
    post = trace["posterior"].to_dataset()
    out[name] = digest(*[post[v].values for v in sorted(post.data_vars)])
kernels = (batch_kernel, batch_kernel_serial, maxent.batch_kernel)
out["cache hits"] = sum(sum(k.stats.cache_hits.values()) for k in kernels)
print(json.dumps(out))
"""


@pytest.mark.validation  # two fresh interpreters, the first compiling every kernel: about 2.5 minutes
def test_the_likelihoods_bits_do_not_depend_on_whether_numba_compiled_them_or_loaded_them(tmp_path):
    # Same seed, same bits must hold in the first process on a new machine (empty caches) as in every later one.
    # Negative controls (measured when this test was written): with the "contract" fast-math flag in the kernels
    # (models.maxent, models.delayed), the first process's kernel outputs differed from the second's; with
    # PyTensor's default fast-math (models.bayes sets it off), its Ops' and unit fits' did.
    import json
    import os
    import subprocess
    import sys

    # Both caches start empty: numba's (the kernels) and PyTensor's (its compiled graph functions).
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "PYTHONHASHSEED": "0",
           "PYTENSOR_FLAGS": f"base_compiledir={tmp_path / 'pytensor'}"}
    runs = []
    for _ in range(2):
        done = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=1800)
        assert done.returncode == 0, done.stderr[-3000:]
        runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    first, second = runs
    assert first.pop("cache hits") == 0  # the first process compiled every kernel
    assert second.pop("cache hits") > 0  # the second loaded them
    assert first == second


#: Run in a fresh interpreter: with argument "likelihood", print a digest of the delayed likelihood's bits; with
#: "arm torque first", only compile (and cache) the arm torque's recursion from Python, as ``arm_torque`` does.
LIKELIHOOD = """
import scioc; scioc.configure()
import hashlib, sys, warnings
import numpy as np
from scioc.models import delayed
from scioc.models.bayes.delayed_windows import delayed_windows
from scioc.models.delayed.lag import arm_torque
from scioc.models.plant import discretize
from scioc.models.segment import prepare_batch
warnings.simplefilter("ignore")
if sys.argv[1] == "arm torque first":
    print(arm_torque(np.random.default_rng(0).normal(size=200), 0.9, 0.3).tau[-1])
    sys.exit(0)
plant = discretize(0.01)
w = delayed_windows(6, np.random.default_rng(2), K=600, preview=50, delay=(0, 25))
r = delayed.loglik_grad(w.theta, prepare_batch(plant, w.segments), plant, tau_nm=w.tau_nm, sigma_m=w.sigma_m,
                        delay=w.delay, tau0=0.1)
print(hashlib.sha256(r.loglik.tobytes() + r.grad.tobytes()).hexdigest())
"""


@pytest.mark.validation  # three fresh interpreters, two compiling the delayed kernel: about a minute
def test_the_kernels_bits_do_not_depend_on_which_caller_compiled_a_callee_first(tmp_path):
    # Negative control (measured 2026-12-06, before every njit stated fastmath and error_model): the arm torque's
    # recursion, compiled first from Python and cached without the kernel's reassociation, made the kernel
    # compiled against it in the next interpreter compute other last bits of the same likelihood.
    import os
    import subprocess
    import sys

    def run(cache, what):
        env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / cache), "PYTHONHASHSEED": "0"}
        done = subprocess.run([sys.executable, "-c", LIKELIHOOD, what], env=env, capture_output=True, text=True,
                              timeout=1800)
        assert done.returncode == 0, done.stderr[-3000:]
        return done.stdout.strip().splitlines()[-1]

    run("callee first", "arm torque first")
    assert run("callee first", "likelihood") == run("kernel first", "likelihood")


#: Run in a fresh interpreter: import kernels and Ops, read the process settings, then configure and read again.
IMPORT_ONLY = """
import json, os, sys
import numba
before = numba.config.CACHE_DIR
import scioc.models.maxent, scioc.models.delayed.kernel, scioc.models.bayes.op, scioc.pipelines.fit
import pytensor
out = {"cache dir unchanged": numba.config.CACHE_DIR == before, "pytensor fastmath": pytensor.config.numba__fastmath,
       "caching": not isinstance(scioc.models.maxent.batch_kernel._cache, numba.core.caching.NullCache)}
import scioc
scioc.configure(); scioc.configure()
out["after: pytensor fastmath"] = pytensor.config.numba__fastmath
out["after: cache dir"] = numba.config.CACHE_DIR
out["after: caching"] = scioc.models.maxent.batch_kernel._cache.cache_path
print(json.dumps(out))
"""


def test_importing_changes_no_process_setting_and_configure_applies_them(tmp_path):
    import json
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("PYTENSOR_FLAGS", "NUMBA_CACHE_DIR")}
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")
    done = subprocess.run([sys.executable, "-c", IMPORT_ONLY], env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["cache dir unchanged"] and out["pytensor fastmath"] is True and out["caching"] is False
    assert out["after: pytensor fastmath"] is False
    assert out["after: cache dir"].startswith(str(tmp_path / "numba"))
    assert out["after: caching"].startswith(out["after: cache dir"])  # a kernel imported before configure caches
