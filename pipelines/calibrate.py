"""``scioc calibrate``: simulation-based calibration, locally or on a Dask cluster.

Every replication i draws its own child seed ``SeedSequence(seed, spawn_key=(i,))``
(the i-th child of ``SeedSequence(seed).spawn``), so its result depends on neither the
worker nor the order it ran in. Replications are grouped into tasks of ``batch_size``
so that one compiled model serves several fits (workers cache compiled models). Each
finished replication is written at once to ``OUT/reps/rep_NNNNN.json`` (temporary file
and rename) by the worker, and again by the client from the task's result if the
worker's file system is not the client's; a rerun skips every replication whose file
exists, so an interrupted run resumes and a worker that dies costs only the
replications it had not finished.

The statistics (ranks, PIT, uniformity tests, coverage, contraction) are computed from
the replication files by :func:`summarize`, in replication order. ``OUT/summary.json``
names how many replications it summarizes; a rerun with fewer replications into a folder
holding a larger summary is refused rather than replacing it.

An existing scheduler is first asked who it is (:func:`check_scheduler`), under one hard
deadline: distributed's connect timeout stops applying once TCP connects, so an address
that accepts connections but is no scheduler would otherwise hang the client for good.
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from pipelines.io import InputDataError, write_text_atomic

#: Family-wise false-failure rate of the uniformity tests of one calibration run
#: (Bonferroni over the parameters tested).
FAMILY_ALPHA = 0.01


#: Version of how replications simulate and fit; part of every fingerprint. Bump it when
#: the data-generating process or the fitted likelihood changes.
GENERATOR = "2: SC human plans with the assistant's feedback law; assistant re-solves every sample"


@dataclass(frozen=True)
class CalibrationConfig:
    """What to calibrate and how.

    Attributes
    ----------
    level : {"unit", "study"}
    replications : int
    seed : int
    L : int
        Posterior draws per rank after thinning (ranks take L + 1 values).
    chains, tune, draws : int
        Sampler settings per fit.
    K : int
        Samples per segment (window length × 100 Hz).
    n_subjects : int
        Subjects per simulated study (study level only).
    negative_control : str or None
        ``None`` for the correct model; ``"inertia"`` fits with the wheel inertia 10 %
        too high; ``"ignore-uA"`` fits a likelihood that attributes the assistant's
        torque to the human.
    batch_size : int
        Replications per Dask task.
    """

    level: str = "unit"
    replications: int = 1000
    seed: int = 2018
    L: int = 99
    chains: int = 2
    tune: int = 500
    draws: int = 500
    K: int = 1500
    n_subjects: int = 8
    negative_control: str | None = None
    batch_size: int = 10
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.level not in ("unit", "study"):
            raise ValueError(f"level must be 'unit' or 'study'; got {self.level!r}")
        for name in ("replications", "L", "chains", "tune", "draws", "K", "n_subjects", "batch_size"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{name} must be a positive integer; got {value!r}")
        if self.seed < 0:
            raise ValueError(f"seed must be >= 0; got {self.seed!r}")
        if self.negative_control not in (None, "inertia", "ignore-uA"):
            raise ValueError(f"negative_control must be None, 'inertia' or 'ignore-uA'; got {self.negative_control!r}")
        if self.chains * self.draws < self.L:
            raise ValueError(f"chains × draws = {self.chains * self.draws} cannot give L = {self.L} draws")

    def fingerprint(self) -> str:
        """Hash of everything that changes a replication's result.

        Not ``batch_size`` (how work is grouped) nor ``replications`` (replication i is the
        same in a run of 100 or of 1000, so a run can be extended).
        """
        d = asdict(self)
        d.pop("batch_size")
        d.pop("replications")
        d["generator"] = GENERATOR  # results of an older simulator must not be resumed
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


def replication_seed(seed: int, i: int) -> np.random.SeedSequence:
    """The i-th child of ``SeedSequence(seed)``, without spawning the others."""
    return np.random.SeedSequence(entropy=int(seed), spawn_key=(int(i),))


def rep_path(out_dir, i: int) -> Path:
    return Path(out_dir) / "reps" / f"rep_{i:05d}.json"


def read_json(path, what: str = "replication") -> dict:
    """Read one of the calibration's JSON files; a damaged one is named, with the way out."""
    try:
        return json.loads(Path(path).read_text())
    except (ValueError, UnicodeDecodeError) as exc:  # JSONDecodeError is a ValueError
        raise InputDataError(f"{path}: damaged {what} file ({exc}); delete it and rerun to recompute it") from None


def _run_one(config: CalibrationConfig, i: int) -> dict:
    from pipelines import sbc_replications

    t0 = time.perf_counter()
    res = sbc_replications.run(config, i, replication_seed(config.seed, i))
    res["index"] = i
    res["seconds"] = time.perf_counter() - t0
    res["worker_pid"] = os.getpid()
    return res


def run_batch(indices, config_dict: dict, out_dir: str) -> list[dict]:
    """A Dask task: run (or read back) several replications, writing each as it finishes."""
    config = CalibrationConfig(**config_dict)
    out = []
    for i in indices:
        path = rep_path(out_dir, i)
        if path.exists():
            out.append(read_json(path))
            continue
        res = _run_one(config, i)
        write_text_atomic(path, json.dumps(res) + "\n")
        out.append(res)
    return out


async def _identity(address: str, timeout: float):
    from distributed.comm import connect

    comm = await connect(address, timeout=timeout)
    try:
        await comm.write({"op": "identity"})
        return await comm.read()
    finally:
        comm.abort()


def check_scheduler(address: str, timeout: float) -> None:
    """Return within ``timeout`` s if ``address`` answers as a Dask scheduler, else raise OSError.

    Connecting, distributed's handshake and the reply to an ``identity`` request share
    one deadline, so a server that accepts and never answers (an HTTP server) or answers
    garbage (which distributed reads as a frame of exabytes) fails quickly and clearly.
    """
    try:
        reply = asyncio.run(asyncio.wait_for(_identity(address, timeout), timeout))
    except (OSError, TimeoutError) as exc:
        raise OSError(f"cannot reach the Dask scheduler at {address} within {timeout:g} s: "
                      f"{str(exc) or 'no answer (is it a Dask scheduler?)'}") from None
    except Exception as exc:  # e.g. MemoryError: distributed took an HTTP reply for a frame length
        raise OSError(f"{address} is not a Dask scheduler: it answered what distributed cannot read "
                      f"({type(exc).__name__})") from None
    if not (isinstance(reply, dict) and reply.get("type") == "Scheduler"):
        raise OSError(f"{address} is not a Dask scheduler: it answered as {str(reply)[:80]!r}")


def _connect(scheduler: str | None, n_workers: int, timeout: float):
    from dask.distributed import Client, LocalCluster

    if scheduler:
        check_scheduler(scheduler, timeout)
        try:
            return Client(scheduler, timeout=timeout), None
        except (OSError, TimeoutError) as exc:
            raise OSError(f"cannot reach the Dask scheduler at {scheduler} within {timeout:g} s: {exc}") from None
    cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None)
    return Client(cluster), cluster


def _prepare_out(config: CalibrationConfig, out_dir: Path) -> None:
    cfg_path = out_dir / "config.json"
    d = asdict(config)
    if cfg_path.exists():
        old = read_json(cfg_path, "configuration")
        old_fp = old.get("fingerprint")
        if old_fp != config.fingerprint():
            raise ValueError(
                f"{cfg_path}: this folder holds replications of a different configuration "
                f"(fingerprint {old_fp} vs {config.fingerprint()}); use another --out"
            )
        return
    write_text_atomic(cfg_path, json.dumps({**d, "fingerprint": config.fingerprint()}, indent=2) + "\n")


def earlier_summary(config: CalibrationConfig, out_dir) -> dict:
    """The summary already in ``out_dir`` ({} if none); refuses a run smaller than it.

    Raises
    ------
    ValueError
        If the folder's summary covers more replications than ``config`` asks for.
    """
    path = Path(out_dir) / "summary.json"
    earlier = read_json(path, "summary") if path.exists() else {}
    if earlier.get("replications", 0) > config.replications:
        raise ValueError(
            f"{path} summarizes {earlier['replications']} replications; this run asks for "
            f"{config.replications} and would replace it: use --replications {earlier['replications']} "
            "(or more), or another --out")
    return earlier


def calibrate(config: CalibrationConfig, out_dir, *, scheduler: str | None = None, n_workers: int = 2,
              show_progress: bool = True, timeout: float = 5.0) -> dict:
    """Run every missing replication on Dask and summarize all of them.

    Parameters
    ----------
    config : CalibrationConfig
    out_dir : str or Path
    scheduler : str, optional
        ``tcp://HOST:PORT`` of an existing scheduler; default an in-process local cluster.
    n_workers : int
        Workers of the local cluster (one thread each).
    show_progress : bool
    timeout : float
        Seconds to wait for a scheduler before giving up with a clear error.

    Returns
    -------
    dict
        The summary (also written to ``OUT/summary.json``).
    """
    from dask.distributed import as_completed

    from pipelines.progress import progress

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    _prepare_out(config, out_dir)
    earlier = earlier_summary(config, out_dir)
    todo = [i for i in range(config.replications) if not rep_path(out_dir, i).exists()]
    t0 = time.perf_counter()
    if todo:
        client, cluster = _connect(scheduler, n_workers, timeout)
        try:
            chunks = [todo[j : j + config.batch_size] for j in range(0, len(todo), config.batch_size)]
            cfg = asdict(config)
            futures = [client.submit(run_batch, chunk, cfg, str(out_dir), key=f"sbc-{config.fingerprint()}-{chunk[0]}",
                                     retries=3) for chunk in chunks]
            bar = progress(as_completed(futures), desc=f"SBC {config.level}", total=len(futures), enabled=show_progress)
            for fut in bar:
                for res in fut.result():
                    path = rep_path(out_dir, res["index"])
                    if not path.exists():  # worker on another file system
                        write_text_atomic(path, json.dumps(res) + "\n")
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    wall = time.perf_counter() - t0
    total = earlier.get("wall_seconds_total", 0.0)
    summary = summarize(out_dir, config)
    summary["wall_seconds_this_run"] = wall
    # Wall time of every invocation that ran replications (a resume adds to it).
    summary["wall_seconds_total"] = total + (wall if todo else 0.0)
    summary["replications_run_now"] = len(todo)
    write_text_atomic(out_dir / "summary.json", json.dumps(summary, indent=2) + "\n")
    return summary


def load_replications(out_dir, n: int) -> list[dict]:
    missing = [i for i in range(n) if not rep_path(out_dir, i).exists()]
    if missing:
        raise FileNotFoundError(f"{out_dir}: {len(missing)} replications missing (first {missing[0]}); rerun to resume")
    reps = [read_json(rep_path(out_dir, i)) for i in range(n)]
    for i, rep in enumerate(reps):
        if not (isinstance(rep, dict) and {"ranks", "pit_u", "ess", "contraction", "seconds"} <= rep.keys()):
            raise InputDataError(f"{rep_path(out_dir, i)}: damaged replication file (fields missing); "
                                 "delete it and rerun to recompute it")
    return reps


def summarize(out_dir, config: CalibrationConfig) -> dict:
    """Uniformity tests, coverage and contraction over all replications, per parameter."""
    from models.sbc import COVERAGE_LEVELS, pit_from_rank, uniformity_test

    reps = load_replications(out_dir, config.replications)
    names = list(reps[0]["ranks"].keys())
    alpha = FAMILY_ALPHA / len(names)
    params = {}
    for name in names:
        r = np.array([rep["ranks"][name] for rep in reps])
        u = np.array([rep["pit_u"][name] for rep in reps])
        pit = pit_from_rank(r, config.L, u)
        test = uniformity_test(pit, alpha)
        # Coverage of central intervals from the PIT (as ArviZ does): the truth is inside the
        # central `level` interval iff |PIT - 1/2| <= level/2. Exact under calibration, unlike
        # quantiles of only L thinned draws, whose intervals are too narrow for small L.
        cov = np.array([np.mean(np.abs(pit - 0.5) <= lv / 2) for lv in COVERAGE_LEVELS])
        params[name] = {
            "ks_statistic": test.statistic,
            "p_value": test.p_value,
            "alpha": alpha,
            "passed": test.passed,
            "coverage": dict(zip([str(lv) for lv in COVERAGE_LEVELS], cov.tolist())),
            "contraction": float(np.mean([rep["contraction"][name] for rep in reps])),
            "low_ess": int(sum(rep["ess"][name] < config.L for rep in reps)),
        }
    return {
        "level": config.level,
        "negative_control": config.negative_control,
        "replications": config.replications,
        "L": config.L,
        "family_alpha": FAMILY_ALPHA,
        "passed": all(p["passed"] for p in params.values()),
        "parameters": params,
        "divergences": int(sum(rep.get("divergences", 0) for rep in reps)),
        "fit_seconds_total": float(sum(rep["seconds"] for rep in reps)),
        "config": asdict(config),
    }


#: Default designs. The study level is reduced (documented in the README): 6 subjects,
#: 2-s windows, 2 chains × 200 draws ranked against L = 39, so that 200 replications fit
#: in well under an hour on two cores; σ_β mixes slowest (about 0.15 effective draws per
#: draw), hence the smaller L.
DEFAULTS = {
    "unit": {"replications": 1000, "K": 1500, "chains": 2, "tune": 500, "draws": 500, "batch_size": 10, "L": 99},
    "study": {"replications": 200, "K": 200, "n_subjects": 6, "chains": 2, "tune": 300, "draws": 200, "batch_size": 3,
              "L": 39},
}
#: Default negative control per level: the unit level must catch a 10 % inertia error, the
#: study level a likelihood that gives the assistant's torque to the human.
NEGATIVE_DEFAULT = {"unit": "inertia", "study": "ignore-uA"}


def config_from_args(args, negative_control=None) -> CalibrationConfig:
    """Build a validated configuration from CLI arguments (with level defaults)."""
    d = dict(DEFAULTS[args.level])
    if args.replications is not None:
        d["replications"] = args.replications
    if args.batch_size is not None:
        d["batch_size"] = args.batch_size
    if getattr(args, "subjects", None) is not None:
        d["n_subjects"] = args.subjects
    if getattr(args, "seconds", None) is not None:
        d["K"] = int(round(args.seconds / 0.01))
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be a positive integer; got {args.workers}")
    return CalibrationConfig(level=args.level, seed=args.seed, negative_control=negative_control, **d)


def calibrate_level(args) -> list[dict]:
    """``scioc calibrate``: the calibration of one level and, by default, its negative control."""
    runs = [(args.level, None)]
    nc = NEGATIVE_DEFAULT[args.level] if args.negative_control is None else args.negative_control
    if nc != "none":
        runs.append((f"{args.level}-negative", nc))
    configs = [(name, config_from_args(args, nc)) for name, nc in runs]  # validate all before running
    for name, cfg in configs:
        earlier_summary(cfg, Path(args.out) / name)
    out = []
    for name, cfg in configs:
        out.append(calibrate(cfg, Path(args.out) / name, scheduler=args.scheduler, n_workers=args.workers))
    return out


def as_expected(summary: dict) -> bool:
    """Did the check come out as it must: passed for the correct model, failed for a negative control?"""
    return summary["passed"] == (summary["negative_control"] is None)


def format_summary(summary: dict) -> str:
    nc = summary["negative_control"]
    head = f"SBC {summary['level']} level" + (f", negative control '{nc}'" if nc else "")
    verdict = "PASSED" if summary["passed"] else "FAILED (non-uniform ranks)"
    if nc and summary["passed"]:
        verdict += " -- but a negative control must fail: at this size the check cannot tell the wrong model"
    elif nc:
        verdict += ", as a negative control must"
    lines = [f"{head}: {summary['replications']} replications, L = {summary['L']}, "
             f"family false-failure rate {summary['family_alpha']:g} -> {verdict}"]
    for name, p in summary["parameters"].items():
        cov = ", ".join(f"{k}: {v:.2f}" for k, v in p["coverage"].items())
        lines.append(f"  {name:>18}: KS p = {p['p_value']:.3g} (alpha {p['alpha']:.3g}) "
                     f"{'ok' if p['passed'] else 'NOT UNIFORM'}; coverage {cov}; contraction {p['contraction']:.3f}")
    lines.append(f"  wall time {summary['wall_seconds_this_run']:.0f} s this run, {summary['wall_seconds_total']:.0f} s in all; "
                 f"divergences {summary['divergences']}")
    return "\n".join(lines)
