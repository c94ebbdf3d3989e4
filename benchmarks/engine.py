"""Where a benchmark's runs execute: in this process, on a local process pool, or on a Ray cluster — the same results either way.

A sweep is a list of jobs, each a tuple of plain arguments (world,
strategy, seed…) for one module-level function. :func:`run_jobs` runs them
with the chosen engine and returns one :class:`Outcome` per job **in job
order** (not in the order they finished), so a sweep's JSON is the same on
every engine for the same seeds. As each run finishes, ``on_done`` is told
(progress); a run that raises is reported with its job's arguments (its
seed among them) as a failed outcome, and the sweep goes on.

Engines:

- ``local``: one after another in this process (``--workers 1``);
- ``pool``: a ``concurrent.futures`` process pool of ``--workers`` processes
  (spawned, so the simulator's state never leaks between runs);
- ``ray``: `Ray <https://www.ray.io>`_ tasks, one CPU each, on the cluster at
  ``--address`` (``auto``, ``ray://host:10001``…) or, without it, on a Ray
  started here for the sweep. Ray is the optional extra ``homing[ray]``;
  every node of a cluster needs homing installed (or a ``runtime_env``).

A stopped sweep (Ctrl-C, SIGTERM) starts no more runs and stops those in
flight, on every engine: the pool's workers are terminated, Ray's tasks
cancelled (their workers killed) before it returns.

A module adds the flags with :func:`add_engine_arguments` and reads them
with :func:`engine_from_args`.
"""

from __future__ import annotations

import argparse
import os
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from homing.errors import UserError

ENGINES = ("local", "pool", "ray")
CANCEL_WAIT = 30.0  # [s] a stopped Ray sweep waits this long at most for its cancelled runs' workers to be killed


@dataclass(frozen=True)
class Outcome:
    """One job's result, or the error it raised (``error`` set, ``result`` None)."""

    job: tuple[Any, ...]
    result: Any = None
    error: str | None = None

    @property
    def ok(self) -> bool:
        return self.error is None


@dataclass(frozen=True)
class Engine:
    """Which engine, how many workers (pool; a local Ray's CPUs) and which Ray cluster (None: start one)."""

    name: str = "pool"
    workers: int = 1
    address: str | None = None


def add_engine_arguments(parser: argparse.ArgumentParser, workers: int | None = None) -> None:
    """``--engine``, ``--workers`` and ``--address`` on a benchmark's parser."""
    default = workers if workers is not None else max(1, (os.cpu_count() or 1) - 1)
    parser.add_argument("--engine", choices=ENGINES, default="pool",
                        help="where runs execute: this process, a local process pool, or a Ray cluster "
                             "(pip install homing[ray]); results are the same for the same seeds")
    parser.add_argument("--workers", type=int, default=default, help="worker processes (pool) or CPUs (local Ray)")
    parser.add_argument("--address", metavar="ADDR",
                        help="Ray cluster to join (e.g. auto, ray://head:10001); default: start Ray here")


def engine_from_args(args: argparse.Namespace) -> Engine:
    """The :class:`Engine` the flags ask for; a bad combination is a UserError."""
    if args.workers < 1:
        raise UserError(f"--workers must be ≥ 1, not {args.workers}")
    if args.address and args.engine != "ray":
        raise UserError("--address names a Ray cluster: use it with --engine ray")
    name = "local" if args.engine == "pool" and args.workers == 1 else args.engine
    return Engine(name, args.workers, args.address)


def _call(fn: Callable[..., Any], job: tuple[Any, ...]) -> Outcome:
    """Run one job, turning its exception into a failed Outcome (its last traceback line kept)."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    try:
        return Outcome(job, fn(*job))
    except Exception as err:  # a failed run is reported with its job, the sweep goes on
        where = traceback.extract_tb(err.__traceback__)[-1]
        return Outcome(job, None, f"{type(err).__name__}: {err} ({os.path.basename(where.filename)}:{where.lineno})")


def run_jobs(fn: Callable[..., Any], jobs: Sequence[tuple[Any, ...]], engine: Engine,
             on_done: Callable[[Outcome], None] | None = None) -> list[Outcome]:
    """``fn(*job)`` for every job on ``engine``; outcomes in job order; ``on_done`` called as each finishes.

    ``fn`` must be a module-level function (pickled by reference) whose
    result pickles.
    """
    done: list[Outcome | None] = [None] * len(jobs)

    def finished(i: int, out: Outcome) -> None:
        done[i] = out
        if on_done is not None:
            on_done(out)

    if engine.name == "local":
        for i, job in enumerate(jobs):
            finished(i, _call(fn, job))
    elif engine.name == "pool":
        _pool(fn, jobs, engine.workers, finished)
    elif engine.name == "ray":
        _ray(fn, jobs, engine, finished)
    else:
        raise UserError(f"unknown engine '{engine.name}' (known: {', '.join(ENGINES)})")
    return [o for o in done if o is not None]


def _pool(fn: Callable[..., Any], jobs: Sequence[tuple[Any, ...]], workers: int,
          finished: Callable[[int, Outcome], None]) -> None:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        futures = {pool.submit(_call, fn, job): i for i, job in enumerate(jobs)}
        try:
            for fut in as_completed(futures):
                i = futures[fut]
                try:
                    out = fut.result()
                except Exception as err:  # the worker process itself died (killed, out of memory)
                    out = Outcome(jobs[i], None, f"{type(err).__name__}: {err}")
                finished(i, out)
        except BaseException:
            # Stopped (Ctrl-C, SIGTERM: KeyboardInterrupt): leaving the block would wait for every queued run.
            # A signal sent to this process alone never reaches the workers, so stop them here; a run cut
            # short is no result anyway. (Python 3.14's terminate_workers does this; before it, _processes.)
            procs = list((getattr(pool, "_processes", None) or {}).values())  # shutdown forgets them
            pool.shutdown(wait=False, cancel_futures=True)
            for proc in procs:
                proc.terminate()
            for proc in procs:
                proc.join()
            raise


def _ray(fn: Callable[..., Any], jobs: Sequence[tuple[Any, ...]], engine: Engine,
         finished: Callable[[int, Outcome], None]) -> None:
    try:
        import ray
    except ImportError:
        raise UserError("--engine ray needs Ray: pip install 'homing[ray]'") from None
    started = not ray.is_initialized()
    if started:
        try:
            if engine.address:
                ray.init(address=engine.address, include_dashboard=False, log_to_driver=False)
            else:
                ray.init(num_cpus=engine.workers, include_dashboard=False, log_to_driver=False)
        except (ConnectionError, RuntimeError, ValueError) as err:
            raise UserError(f"--engine ray: cannot reach a Ray cluster at {engine.address or 'a new local one'}: "
                            f"{str(err).splitlines()[0] if str(err) else type(err).__name__}") from None
    pending: dict[Any, int] = {}
    try:
        task = ray.remote(num_cpus=1, max_retries=0)(_call)
        pending = {task.remote(fn, job): i for i, job in enumerate(jobs)}
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                i = pending.pop(ref)
                try:
                    out = ray.get(ref)
                except Exception as err:  # the task's worker died (node lost, out of memory)
                    out = Outcome(jobs[i], None, f"{type(err).__name__}: {str(err).splitlines()[0]}")
                finished(i, out)
    except BaseException:
        # Stopped (Ctrl-C, SIGTERM: KeyboardInterrupt). Left to the shutdown, a run in flight goes on until Ray
        # tears its worker down in the background (a local Ray: still alive when the shutdown returned, in one
        # stop of five here; a cluster: once it notices the driver gone). Cancel every run, killing the workers of
        # those in flight, and wait until they are.
        for ref in pending:
            ray.cancel(ref, force=True)
        if pending:
            ray.wait(list(pending), num_returns=len(pending), timeout=CANCEL_WAIT)
        raise
    finally:
        if started:
            ray.shutdown()


def failures_table(outcomes: Sequence[Outcome]) -> list[dict[str, Any]]:
    """The failed runs as JSON rows: the job's arguments and the error."""
    return [{"job": list(o.job), "error": o.error} for o in outcomes if not o.ok]
