"""``scioc calibrate``: simulation-based calibration run on a Dask cluster, resumable.

Replication i draws the child seed ``SeedSequence(seed, spawn_key=(i,))``, so its result depends on
neither the worker nor the order. Tasks group ``batch_size`` replications so that one compiled model
serves several fits. The worker writes each finished replication at once (the client writes it again if
their file systems differ); a rerun skips those already written (:mod:`scioc.pipelines.calibrate.store`),
so a dead worker costs only its unfinished replications. An existing scheduler is first asked who it is
under one hard deadline (:func:`check_scheduler`): distributed's connect timeout ends once TCP connects.
"""

from __future__ import annotations

import asyncio
import json
import os
import time
from dataclasses import asdict
from pathlib import Path

from scioc.models.runtime import configure
from scioc.pipelines.calibrate.config import CalibrationConfig, replication_seed
from scioc.pipelines.calibrate.store import earlier_summary, prepare_out, read_json, rep_path, write_replication
from scioc.pipelines.calibrate.summary import sbc_tree, summarize
from scioc.pipelines.human_model.registry import get
from scioc.pipelines.progress import progress
from scioc.pipelines.storage import atomic_path, refuse_file_on_path, write_text_atomic


def run_replication(config: CalibrationConfig, i: int) -> dict:
    """Replication ``i`` of ``config`` (its level's), with its index, wall time and worker."""
    t0 = time.perf_counter()
    replicate = get(config.human_model).calibration_replication(config.level)
    res = replicate(config, i, replication_seed(config.seed, i))
    res["index"] = i
    res["fingerprint"] = config.fingerprint()  # which calibration it belongs to (the summary checks it)
    res["seconds"] = time.perf_counter() - t0
    res["worker_pid"] = os.getpid()
    return res


def run_batch(indices, config_dict: dict, out_dir: str) -> list[dict]:
    """A Dask task: run (or read back) several replications, writing each as it finishes."""
    configure()  # a worker process: numba's cache, PyTensor's fast-math off
    config = CalibrationConfig(**config_dict)
    out = []
    for i in indices:
        path = rep_path(out_dir, i)
        if path.exists():
            out.append(read_json(path))
            continue
        res = run_replication(config, i)
        write_replication(out_dir, res)
        out.append(res)
    return out


async def _identity(address: str, timeout: float):
    from distributed.comm import connect  # lazy: Dask takes seconds to import

    comm = await connect(address, timeout=timeout)
    try:
        await comm.write({"op": "identity"})
        return await comm.read()
    finally:
        comm.abort()


def check_scheduler(address: str, timeout: float) -> None:
    """Return within ``timeout`` s if ``address`` answers as a Dask scheduler, else raise OSError.

    Connect, handshake and ``identity`` reply share one deadline, so a server that never answers or
    answers garbage (read by distributed as a frame of exabytes) fails quickly and clearly.
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
    from dask.distributed import Client, LocalCluster  # lazy: Dask takes seconds to import

    if scheduler:
        check_scheduler(scheduler, timeout)
        try:
            return Client(scheduler, timeout=timeout), None
        except (OSError, TimeoutError) as exc:
            raise OSError(f"cannot reach the Dask scheduler at {scheduler} within {timeout:g} s: {exc}") from None
    cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None)
    return Client(cluster), cluster


def calibrate(config: CalibrationConfig, out_dir, *, scheduler: str | None = None, n_workers: int = 2,
              show_progress: bool = True, timeout: float = 5.0) -> dict:
    """Run every missing replication on Dask and summarize all of them.

    ``scheduler``: ``tcp://HOST:PORT`` of an existing scheduler (waited for ``timeout`` s), else a local
    cluster of ``n_workers`` single-threaded workers. Returns the summary, also written to
    ``OUT/summary.json``; all replications go to ``OUT/sbc.nc`` (:func:`scioc.pipelines.calibrate.summary.sbc_tree`).
    """
    from dask.distributed import as_completed  # lazy: Dask takes seconds to import

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    prepare_out(config, out_dir)
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
                    if not rep_path(out_dir, res["index"]).exists():  # worker on another file system
                        write_replication(out_dir, res)
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
    with atomic_path(out_dir / "sbc.nc") as tmp:
        sbc_tree(out_dir, config).to_netcdf(tmp, engine="h5netcdf")
    return summary


def calibrate_runs(runs, out, *, scheduler: str | None = None, n_workers: int = 2) -> list[dict]:
    """``scioc calibrate``: each (name, config) of ``runs`` (:func:`scioc.pipelines.calibrate.config.level_configs`)
    into ``out/NAME``; every folder is checked before anything runs."""
    for name, cfg in runs:
        refuse_file_on_path(Path(out) / name)
        earlier_summary(cfg, Path(out) / name)
    return [calibrate(cfg, Path(out) / name, scheduler=scheduler, n_workers=n_workers) for name, cfg in runs]
