"""Chunked, resumable execution of a sweep.

The design is cut into chunks of ``chunk_size`` consecutive points (flat index). For each
chunk the runner generates the points (:mod:`sweep.sweeps.design`), computes exactly the requested
outputs (:func:`compute_chunk`, which calls :mod:`sweep.api`), saves the chunk for resuming
and writes it into the output being assembled (:mod:`sweep.store`). Memory is bounded by a
few chunks, whatever the design size.

Two executors:

* local (default): chunks are fed one after another, from the main thread, to the api
  functions, which already run on all cores (:mod:`sweep.kernels._parallel`). The netCDF
  writing (zlib compression where it pays) happens in one background thread, overlapping
  the next chunk (see :class:`_Behind`; on 2 cores it cut a 4e6-point run of cheap
  approximations from 25 s to 17 s). Saving a chunk for resume runs one chunk behind in a
  thread of its own too (:class:`_Behind`): an error or an interruption waits for the
  save in flight, so that every computed chunk is kept; only a hard kill can lose the one
  chunk in flight, as it loses the one being computed.
* distributed: ``scheduler="tcp://host:port"`` (or a ``distributed.Client``) submits chunks
  to a Dask cluster, keeping a bounded number in flight; results are written as they come
  back, in any order. Worker threads run the api's serial kernels unless numba's threading
  layer is thread-safe (decided by the api).

Every chunk's values depend only on its points, and point ``i`` of a design never depends on
the chunking, so results are identical for any chunk size, thread count or executor.

:func:`run` is a driver that reads as its steps: prepare (load the configuration, check
the output path, build the design and the :class:`ComputePlan`), preflight (refuse a design
above the limits unless forced, before anything is allocated), take the output's lock
(before touching anything, ``--restart`` included), check an existing output, connect to
the scheduler, plan the chunks (lazily), check the free disk, open the partial state,
stream the chunks (saved ones verified and copied, the others computed), finish (write the
timing attributes, commit atomically with signals held, clean up) and report.

Faults end in :class:`RunError` (or :class:`sweep.store.ResumeError`,
:class:`sweep.sweeps.config.ConfigError`) with a one-line message; the finished chunks are
kept and the previous output is only ever replaced by a complete new one.

Timing: before the first computed chunk, a warm-up call on a few of its points
(:data:`WARM_UP_POINTS`) loads or compiles the kernels, so that chunk times measure warm
kernels. The file records ``compile_time_s`` (that call), ``kernel_time_s`` (time inside
the api calls of every chunk, resumed ones included), ``run_time_s`` (the chunks' wall time:
kernels, design, saving, writing) and ``points_per_second`` = points / ``kernel_time_s``.
On a Dask cluster the kernels load on the workers: no warm-up runs, no ``compile_time_s``
is written, and kernel times include the workers' first loads.

In memory (:func:`run_in_memory`, behind ``sweep.run``): the same driver streams the chunks
into a :class:`sweep.store.MemoryWriter` instead of a netCDF file; there is no output path,
lock, partial directory, resume or commit, and the dataset is returned.

Floor 4: may import :mod:`sweep.api`, :mod:`sweep.registry`, :mod:`sweep.store`,
:mod:`sweep.sweeps.config`, :mod:`sweep.sweeps.design`, :mod:`sweep.sweeps.limits`,
:mod:`sweep.sweeps.preflight`, :mod:`sweep.sweeps.progress`, :mod:`sweep._format` and
:mod:`sweep._version` (and, lazily, Dask and numba's thread settings); nothing of the
reports or the command line.
"""
from __future__ import annotations

import collections
import concurrent.futures
import contextlib
import dataclasses
import datetime as _dt
import errno
import functools
import hashlib
import json
import importlib.metadata
import os
import platform
import shlex
import signal
import sys
import threading
import time
import traceback
import uuid
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from sweep import api, registry, store
from sweep._format import count, rate
from sweep._version import __version__
from sweep.kernels import vmath as _vmath
from sweep.sweeps import config as _config
from sweep.sweeps import design as _design
from sweep.sweeps import limits as _limits
from sweep.sweeps import preflight as _preflight_mod
from sweep.sweeps import progress as _progress_mod

__all__ = ["ComputePlan", "compute_chunk", "run", "run_in_memory", "RunResult", "RunError",
           "CaveatWarning", "STOP_SIGNALS", "signals_handled",
           "default_output", "source_sha256", "preflight", "refusal", "estimate_rate"]


# --------------------------------------------------------------------------- computing

@dataclasses.dataclass(frozen=True)
class ComputePlan:
    """What :func:`compute_chunk` computes: picklable, so it can travel to Dask workers.

    Attributes
    ----------
    integrate : bool
        Run :func:`sweep.api.integrate` (once per chunk; e_numeric, the integrator fields
        and every error field share it).
    integrator : dict
        Its keyword arguments (steps, rest_tol, max_steps).
    approximations : tuple of str
        Approximations evaluated by :func:`sweep.api.cor` (stored or needed by an error).
    options : dict
        Per-method keyword arguments of :func:`sweep.api.cor`.
    variables : tuple of str
        Variables returned, in storage order.
    composites : tuple of str
        Composite methods (``"auto"``) evaluated by :func:`sweep.api.cor_fields`: their e
        and their own fields (``method_used``).
    """

    integrate: bool
    integrator: dict
    approximations: tuple
    options: dict
    variables: tuple
    composites: tuple = ()

    @classmethod
    def from_config(cls, cfg: _config.Config) -> ComputePlan:
        """The plan of a validated configuration (its outputs, integrator and options)."""
        out = cfg.outputs
        options = {m: cfg.method_options(m) for m in out.approximations}
        for m in out.composites:
            # A composite method integrates some points: with [integrator]'s settings
            # unless its own options say otherwise.
            accepted = {opt.name for opt in registry.METHODS[m].options}
            options[m] = {**{k: v for k, v in cfg.integrator.kwargs().items()
                             if k in accepted}, **cfg.method_options(m)}
        return cls(integrate=out.needs_integration, integrator=cfg.integrator.kwargs(),
                   approximations=out.approximations, options=options,
                   variables=out.variables, composites=out.composites)


def compute_chunk(plan: ComputePlan, alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray,
                  gtilde: np.ndarray) -> tuple[dict[str, np.ndarray], float]:
    """Compute the requested outputs at a chunk of points.

    Parameters
    ----------
    plan : ComputePlan
    alpha, beta, gamma, gtilde : ndarray
        Flat float64 arrays of equal length (scaled parameters of eq. (2)).

    Returns
    -------
    arrays : dict of str -> ndarray
        One flat array per variable of ``plan.variables``, in the store's dtype.
    seconds : float
        Time spent inside the api calls (the kernels) [s].
    caveats : tuple of int
        Points whose e needs a caveat, whatever is stored
        (:data:`sweep.store.CAVEAT_ATTRS`).
    """
    t0 = time.perf_counter()
    res = None
    statuses = []
    if plan.integrate:
        res = api.integrate(alpha, beta, gamma, gtilde, **plan.integrator)
        statuses.append(res.status)
    approx = {m: api.cor(alpha, beta, gamma, gtilde, method=m, **plan.options.get(m, {}))
              for m in plan.approximations}
    own = {}  # the composite methods' e and fields
    missed = np.zeros(alpha.shape, dtype=bool)   # e may miss a composite's own tol
    for m in plan.composites:
        _, given = api.given_options(m, plan.options.get(m, {}))
        approx[m], status, fields, m_missed = api.method_arrays(m, alpha, beta, gamma,
                                                                gtilde, given)
        statuses.append(status)
        own.update(fields)
        missed |= m_missed
    seconds = time.perf_counter() - t0
    arrays = {}
    for name in plan.variables:
        if name == "e_numeric":
            value = res.e
        elif name.startswith("e_") and name[2:] in approx:
            value = approx[name[2:]]
        elif name.startswith("error_"):
            # The integration ran once above; every error field shares it.
            value = approx[name[6:]] - res.e
        else:
            value = own[name] if name in own else getattr(res, name)
        dtype, _ = store.variable_spec(name)
        arrays[name] = np.ascontiguousarray(value, dtype=dtype).reshape(-1)
    return arrays, seconds, _caveats(plan, res, statuses, missed)


# Kept with every chunk, written as global attributes and warned of.
_CAVEATS = store.CAVEAT_ATTRS


class CaveatWarning(RuntimeWarning):
    """A run's file holds points whose e needs a caveat (:data:`sweep.store.CAVEAT_ATTRS`)."""


def _caveats(plan, res, statuses, missed):
    """(points out of step budget in any method, other points whose e may miss its tol:
    e_err above the integrator's ``tol``, or ``missed`` by a composite method at its own)
    of one chunk."""
    out = np.zeros(missed.shape, dtype=bool)
    for status in statuses:
        out |= status == registry.Status.BUDGET_EXHAUSTED
    tol = plan.integrator.get("tol")
    above = missed.copy()
    if res is not None and tol is not None:
        above |= registry.misses_tol(res.e_err, res.status, tol)
    return int(np.count_nonzero(out)), int(np.count_nonzero(above & ~out))


# --------------------------------------------------------------------------- running

@dataclasses.dataclass
class RunResult:
    """What a run did.

    Attributes
    ----------
    output : Path or None
        The file written; None for an in-memory run (:func:`run_in_memory`).
    n_points : int
        Size of the design.
    computed_points : int
        Points computed by this call (the rest were resumed from saved chunks).
    wall_seconds : float
        Duration of this call [s].
    kernel_seconds : float
        Time spent in the api kernels during this call [s].
    up_to_date : bool
        The output already existed with the same configuration: nothing was done.
    chunks : int
        Number of chunks of the design (set once the output is written).
    resumed_chunks : int
        Chunks copied from saved partial results instead of computed.
    recomputed_chunks : int
        Saved chunks that failed verification (unreadable, damaged, from another run) and
        were computed again.
    discarded_chunks : int
        Chunk files found without a valid manifest and deleted unread.
    committed : bool
        The output was published.
    cleanup_interrupted : bool
        A signal cut the removal of the partial directory short, after the output was
        published (the output is complete; the next run removes the leftovers).
    compile_seconds : float or None
        Duration of the warm-up call that loaded or compiled the kernels [s] (None: no
        warm-up ran, see the module docstring).
    caveats : dict of str -> int
        Points of the whole dataset whose e needs a caveat, by name of
        :data:`sweep.store.CAVEAT_ATTRS` (resumed chunks included; empty where nothing was
        computed or resumed).
    writer_wait_seconds : float
        Time the chunks and the file's completion waited for the background writer [s]:
        where it is a large share of ``wall_seconds``, the writer's zlib, one thread for
        every core, set the pace (the run says so, :data:`WRITER_HINT_SHARE`).
    """

    output: Path | None
    n_points: int
    computed_points: int = 0
    wall_seconds: float = 0.0
    kernel_seconds: float = 0.0
    up_to_date: bool = False
    chunks: int = 0
    resumed_chunks: int = 0
    recomputed_chunks: int = 0
    discarded_chunks: int = 0
    committed: bool = False
    cleanup_interrupted: bool = False
    compile_seconds: float | None = None
    caveats: dict = dataclasses.field(default_factory=dict)
    writer_wait_seconds: float = 0.0

    @property
    def points_per_second(self) -> float:
        """Points computed by this call per second of its wall time (NaN if no time)."""
        return self.computed_points / self.wall_seconds if self.wall_seconds > 0 else float("nan")

    @property
    def outside_fraction(self) -> float:
        """Fraction of the wall time spent outside the kernels (design, saving, writing)."""
        if self.wall_seconds <= 0:
            return float("nan")
        return 1.0 - self.kernel_seconds / self.wall_seconds


def default_output(cfg: _config.Config) -> Path:
    """``<config file stem>.nc`` in the current directory.

    Parameters
    ----------
    cfg : Config

    Returns
    -------
    Path

    Raises
    ------
    RunError
        For a configuration without a source file (given as text or a dict): a file name
        made up for it (a ``sweep.nc`` in whatever the current directory is) would be a
        file the caller never asked for.
    """
    if not cfg.source:
        raise RunError("this configuration was not read from a file, so no output name "
                       "follows from it: give the output file (output=, -o), or run it "
                       "in memory with sweep.run(config)")
    return Path(Path(cfg.source).stem + ".nc")


def _version(dist):
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:  # pragma: no cover
        return "unknown"


#: The package's files that results depend on: its code, and the data it reads (the error
#: model of method = "auto", which ``sweep report error-model`` rewrites in place).
SOURCE_PATTERNS = ("**/*.py", "data/*.npz")


def source_sha256() -> str:
    """Hash of the package's sources: its Python code and the data it ships.

    Two runs of one configuration give identical results only with identical code and
    data; the version number alone does not see a local edit or a rebuilt error model.
    Resuming, and reusing an existing output, therefore also require the same hash.

    Returns
    -------
    str
        Hex SHA-256 over the relative path and bytes of every file matching
        :data:`SOURCE_PATTERNS` under ``sweep/``.
    """
    package = Path(__file__).resolve().parents[1]
    files = {path for pattern in SOURCE_PATTERNS for path in package.glob(pattern)}
    h = hashlib.sha256()
    for path in sorted(files):
        h.update(path.relative_to(package).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def numerical_stack() -> str:
    """The libraries below sweep that its results depend on, to the last bit.

    numba and llvmlite compile the kernels, numpy and scipy make the designs and tables,
    and glibc's vector math library (its variant chosen per machine,
    :data:`sweep.kernels.vmath.VARIANT`) takes the general exponents' logs and exps: a
    chunk computed under other versions may differ in its last bits. Resuming, and a Dask
    worker's chunks, therefore also require the same stack.

    Returns
    -------
    str
        ``"numba X, llvmlite X, numpy X, scipy X, libmvec VARIANT (glibc X)"``.
    """
    libc = " ".join(platform.libc_ver()) or "unknown C library"
    return (f"numba {_version('numba')}, llvmlite {_version('llvmlite')}, numpy "
            f"{np.__version__}, scipy {_version('scipy')}, libmvec "
            f"{_vmath.VARIANT or 'unused'} ({libc})")


def _integrator_attrs(plan):
    """The integrator's global attributes: every option of the "numeric" method, defaults
    resolved, as e_numeric ran it, or else as a composite method integrated its points
    (its own tol among them: ``auto`` found in every file it served with the integrator
    "not run", with [integrator]'s steps or refine changing its e unrecorded)."""
    numeric = registry.METHODS["numeric"]
    if plan.integrate:
        used, what = api.integrator_settings(**plan.integrator), ""
    elif plan.composites:
        m = plan.composites[0]
        checked, given = api.given_options(m, plan.options.get(m, {}))
        used = api.composite_integrator_settings(checked["tol"], given)
        what = f", for the points {m} integrates (at its tol)"
    else:
        return {"integrator": "not run (no requested output needs the numerical integration)"}
    return {"integrator": "fixed-step Dormand-Prince 5(4), three phases of Algorithm 1" + what,
            **{numeric.attr_prefix + key: numeric.option(key).to_attr(value)
               for key, value in used.items()}}


def _static_attrs(cfg, design, plan, chunk_size):
    now = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()
    attrs = {
        "title": cfg.title,
        "summary": cfg.description or cfg.title,
        "Conventions": store.CONVENTIONS,
        "source": f"sweep {__version__} (numba {_version('numba')}, numpy {np.__version__})",
        "references": store.REPORT,
        "date_created": now,
        "sweep_version": __version__,
        "sweep_source_sha256": source_sha256(),
        "numba_version": _version("numba"),
        "numpy_version": np.__version__,
        "scipy_version": _version("scipy"),
        "numerical_stack": numerical_stack(),
        "python_version": platform.python_version(),
        "sweep_config": cfg.text,
        "sweep_config_source": cfg.source,
        "sweep_config_sha256": cfg.sha256,
        "design_kind": design.kind,
        "design": design.describe(),
        "n_points": design.size,
        "chunk_size": chunk_size,
        "outputs": " ".join(plan.variables),
    }
    attrs.update(_integrator_attrs(plan))
    for method, opts in plan.options.items():
        for key, value in opts.items():
            attrs[registry.method(method).attr_prefix + key] = value
    return attrs


def _scheduler_address(scheduler):
    """The address of a scheduler given as a string or a ``distributed.Client``."""
    if isinstance(scheduler, str):
        return scheduler
    address = getattr(getattr(scheduler, "scheduler", None), "address", None)
    return address or type(scheduler).__name__


def _command_line(job, scheduler):
    """The ``sweep run`` command that makes this file, with the defaults resolved; for an
    in-memory run, the ``sweep.run`` call."""
    if job.output is None:
        config = repr(job.cfg.source) if job.cfg.source else "<configuration, see sweep_config>"
        where = f", scheduler={_scheduler_address(scheduler)!r}" if scheduler is not None else ""
        return f"sweep.run({config}, chunk_size={job.chunk_size}{where})"
    config = (shlex.quote(job.cfg.source) if job.cfg.source
              else "<configuration text, see sweep_config>")
    words = ["-o", str(job.output), "--chunk-size", str(job.chunk_size)]
    if scheduler is not None:
        words += ["--scheduler", _scheduler_address(scheduler)]
    return f"sweep run {config} {shlex.join(words)}"


def _provenance_attrs(job, scheduler, now):
    """How the file is made: the command (also as a CF ``history`` line) and where the
    chunks are computed. ``now``: ISO 8601 time of the run's start."""
    command = _command_line(job, scheduler)
    if scheduler is None:
        executor = ("local: chunks in turn, each on every numba thread of this process"
                    + ("" if job.output is not None else ", assembled in memory"))
    else:
        executor = f"dask distributed, scheduler {_scheduler_address(scheduler)}"
    return {"history": f"{now}: {command}", "sweep_command": command, "executor": executor}


def _thread_attrs():
    """numba's thread count and threading layer in this process (after the kernels ran)."""
    import numba

    try:
        layer = numba.threading_layer()
    except ValueError:  # raised until a parallel kernel has run in this process
        layer = "none (no parallel kernel ran)"
    return {"numba_num_threads": numba.get_num_threads(), "numba_threading_layer": layer}


def _local_executor(plan, tasks):
    for index, start, stop, points in tasks:
        arrays, seconds, caveats = compute_chunk(plan,
                                                 *(points[k] for k in _config.PARAMETERS))
        yield index, start, stop, points, arrays, seconds, caveats


def _connect(scheduler, timeout):
    """A Dask client for ``scheduler`` (an address or a client), connected now, before
    any file is touched; returns ``(client, own)``. An address that does not answer
    within ``timeout`` seconds is a :class:`RunError` naming it."""
    if scheduler is None:
        return None, False
    try:
        from distributed import Client
    except ImportError:
        raise RunError("--scheduler needs Dask: pip install 'sweep[dask]'") from None
    if isinstance(scheduler, Client):
        return scheduler, False
    timeout = _limits.SCHEDULER_TIMEOUT_S if timeout is None else timeout
    try:
        # Never the process's default client: the runner submits to it explicitly, and
        # distributed makes a client the default (dask's scheduler) before it connects, so
        # that one which failed to connect, kept alive by its exception, served every later
        # dask compute of the process, which then waited on it for ever.
        return Client(scheduler, timeout=timeout, set_as_default=False), True
    except (OSError, ValueError, TypeError) as exc:  # timeouts are OSErrors in distributed
        _close_unconnected(exc, Client)
        raise RunError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}") from exc


def _close_unconnected(exc, client_type):
    """Close the client that a failed ``Client(...)`` left half built, reachable only from
    the frames of ``exc``. Left to the garbage collector, its close ran in whatever thread
    collected it; run in the thread that starts another client's event loop, it waited
    for distributed's loop-runner lock, which that start holds while it waits for the
    thread, so the start failed after 10 s (an AssertionError out of ``Client``)."""
    for frame, _ in traceback.walk_tb(exc.__traceback__):
        client = frame.f_locals.get("self")
        if isinstance(client, client_type):
            with contextlib.suppress(Exception):
                client.close()
            return


class WorkerMismatch(RuntimeError):
    """A Dask worker runs another sweep (code or data) than the process writing the file."""


@functools.lru_cache(maxsize=1)
def _loaded_source():
    """:func:`source_sha256` and :func:`numerical_stack` of this process, taken once, at
    its first chunk: a worker imports the sweep's modules then (unpickling the task), so a
    sweep installed after that is seen as another one. A worker that imported them earlier
    by another route and had the package replaced before its first chunk is not caught."""
    return source_sha256(), numerical_stack()


def _compute_on_worker(source, plan, *points):
    """:func:`compute_chunk` on a Dask worker whose ``(source_sha256, numerical_stack)``
    is ``source``.

    A worker imports its own sweep: one left with another version computed chunks with
    its code while the file recorded the hash of the process that wrote it (exit 0)."""
    here = _loaded_source()
    if here != source:
        from distributed import get_worker  # noqa: PLC0415 -- only on a worker

        what = (f"source sha256 {here[0][:12]}... there, {source[0][:12]}... here"
                if here[0] != source[0] else f"{here[1]} there, {source[1]} here")
        raise WorkerMismatch(
            f"the Dask worker {get_worker().address} runs another sweep than this process "
            f"({what}); install the same sweep and libraries on every worker")
    return compute_chunk(plan, *points)


def _chunk_result(fut, index, start, stop):
    """What the future of chunk ``index`` (points ``start .. stop-1``) holds; a chunk the
    cluster could not compute (a worker with another sweep, one killed while computing,
    a task the scheduler could not load) is a :class:`ChunkFailed` naming it."""
    try:
        return fut.result()
    except WorkerMismatch as exc:
        raise ChunkFailed(str(exc)) from exc
    except Exception as exc:  # noqa: BLE001 - whatever the worker raised, one line
        raise ChunkFailed(f"chunk {index} (points {start:,} to {stop - 1:,}) failed on the "
                          f"Dask cluster: {type(exc).__name__}: {exc}") from exc


def _say_if_no_workers(client, log):
    """A cluster without workers holds the submitted chunks until one joins (an adaptive
    cluster starts its workers for them): say so, not wait in silence."""
    if not client.scheduler_info().get("workers"):
        log(f"dask: the scheduler at {client.scheduler.address} has no workers yet; the "
            "chunks wait for one (interrupt to stop: finished chunks are kept)")


def _dask_executor(plan, tasks, client, log):
    from distributed import as_completed

    # A bounded number of chunks in flight keeps memory bounded on both sides.
    window = max(2, 2 * sum(client.nthreads().values()))
    futures = as_completed(loop=client.loop)   # not the default client's: ours is none
    meta = {}
    token = uuid.uuid4().hex  # task keys unique to this run on a shared scheduler
    tasks = iter(tasks)
    source = source_sha256(), numerical_stack()

    def submit_next():
        for index, start, stop, points in tasks:
            fut = client.submit(_compute_on_worker, source, plan,
                                *(points[k] for k in _config.PARAMETERS),
                                pure=False, key=f"sweep-chunk-{index}-{token}")
            meta[fut.key] = (index, start, stop, points)
            futures.add(fut)
            return True
        return False

    for _ in range(window):
        if not submit_next():
            break
    _say_if_no_workers(client, log)
    for fut in futures:
        index, start, stop, points = meta.pop(fut.key)
        arrays, seconds, caveats = _chunk_result(fut, index, start, stop)
        fut.release()
        yield index, start, stop, points, arrays, seconds, caveats
        submit_next()


#: Chunks allowed to wait for the background writer (0: write in the main thread).
WRITE_BEHIND = 2
#: Chunks whose resume save may still run while the next one computes (0: saved in the main
#: thread before the run goes on).
SAVE_BEHIND = 1


class _Behind:
    """``call(*args)`` for chunk after chunk from one background thread, at most ``depth``
    calls behind the main thread (0: in the main thread, at once).

    Two run so: the netCDF writer's writes and the partial store's saves for resume. The
    writer's zlib runs inside HDF5 with the GIL released, so it overlaps the next chunk's
    kernels (fully with serial kernels, which leave cores idle), and only its thread touches
    the file while it runs (HDF5 builds are usually not thread-safe). Hashing, writing and
    syncing a chunk for resume (0.1 s of CPU a million points of configs/sobol_1m.toml, most
    of a run's serial part, which the cores do not shorten) overlaps them too. The depth
    bounds memory; an error in a call is raised in the main thread at the next
    :meth:`submit` or at :meth:`drain`, and :meth:`settle` waits without raising, so that a
    failed or interrupted run keeps, and counts, every chunk saved.
    """

    def __init__(self, call: Callable[..., None], depth: int, name: str) -> None:
        self._call = call
        self._depth = depth
        self._pending = collections.deque()
        self._pool = concurrent.futures.ThreadPoolExecutor(max_workers=1,
                                                           thread_name_prefix=name)
        #: Seconds :meth:`submit` and :meth:`drain` waited for the thread.
        self.waited = 0.0

    def submit(self, *args) -> None:
        if self._depth == 0:
            self._call(*args)
            return
        if len(self._pending) >= self._depth:
            t0 = time.perf_counter()
            while len(self._pending) >= self._depth:
                self._pending.popleft().result()
            self.waited += time.perf_counter() - t0
        self._pending.append(self._pool.submit(self._call, *args))

    def drain(self) -> None:
        """Wait until every submitted call is done (re-raising its error)."""
        t0 = time.perf_counter()
        while self._pending:
            self._pending.popleft().result()
        self.waited += time.perf_counter() - t0

    def settle(self) -> None:
        """Wait for the calls in flight; their errors are not this caller's to report."""
        with contextlib.suppress(Exception):
            self.drain()

    def shutdown(self, cancel: bool = True) -> None:
        """Stop the thread, the calls not yet started cancelled (``cancel``) or done."""
        if cancel:
            for fut in self._pending:
                fut.cancel()
        self._pool.shutdown(wait=True)
        self._pending.clear()


# --------------------------------------------------------------------------- the driver's steps

class RunError(RuntimeError):
    """A run cannot start or go on: refused by the preflight, a bad output path, a full
    disk, an unreachable scheduler. The message is one line naming the file, value or
    address and the cause."""


class ChunkFailed(RunError):
    """A chunk the Dask cluster could not compute (the finished ones are kept)."""


@dataclasses.dataclass
class _Job:
    """What the steps of one :func:`run` call share."""

    cfg: _config.Config
    design: Any
    plan: ComputePlan
    layout: store.Layout
    output: Path | None  # None: an in-memory run
    chunk_size: int
    log: Callable[[str], None]
    result: RunResult
    chunks: Any = ()
    pre: Any = None
    progress_interval: float | None = None
    restart: bool = False
    stream: Any = None  # of the progress (a DroppingStream on stderr)

    @property
    def resume_advice(self) -> str:
        """How to resume from the finished chunks: the same command, but not with
        --restart, which would discard them."""
        return ("rerun without --restart to resume" if self.restart
                else "rerun the same command to resume")

    @property
    def label(self) -> str:
        """What progress and messages call the run: the output's name, or "in memory"."""
        return self.output.name if self.output is not None else "in memory"


@dataclasses.dataclass
class _Totals:
    """Wall and kernel time and the caveats' counts (:data:`sweep.store.CAVEAT_ATTRS`) of
    every chunk of the dataset, this session's and resumed."""

    wall: float = 0.0
    kernel: float = 0.0
    caveats: tuple = (0,) * len(_CAVEATS)

    def add(self, wall, kernel, caveats):
        self.wall += wall
        self.kernel += kernel
        self.caveats = tuple(a + int(b) for a, b in zip(self.caveats, caveats))


def _output_path(output):
    """The output as a Path; an empty name is refused (``Path("")`` would be ".")."""
    if isinstance(output, (str, bytes)) and not output.strip():
        raise RunError(f"the output file name is empty ({output!r}); give a netCDF file "
                       "name with -o, e.g. -o out.nc")
    return Path(os.fsdecode(output))


def _check_output_path(output):
    """Refuse, before anything is computed, an output the run could not publish."""
    if output.name in ("", ".", ".."):
        # "." or "/" (with_suffix below would raise on them): say what is wrong instead.
        what = "is a directory" if output.is_dir() else "names a directory, not a file"
        raise RunError(f"{output} {what}; give the output .nc file name with -o, e.g. "
                       f"-o {output / 'out.nc'}")
    if output.suffix.lower() not in store.SUFFIXES:
        raise RunError(
            f"{output}: unknown output format {output.suffix or '(no suffix)'!r}; sweep "
            f"writes netCDF4 files ({', '.join(store.SUFFIXES)}); Zarr and other formats "
            f"are not written: use e.g. -o {output.with_suffix('.nc').name}")
    if output.is_dir():
        raise RunError(f"{output} is a directory; give the output file name with -o")
    try:
        str(output).encode("utf-8")
    except UnicodeEncodeError:
        # netCDF-C takes UTF-8 names: it raised past the lock and the partial directory.
        raise RunError(f"{ascii(str(output))}: the output path is not valid UTF-8; "
                       "rename it or choose another -o") from None
    if output.exists() and not output.is_file():
        raise RunError(f"{output} exists and is not a regular file; choose another -o")
    _check_parent_is_a_directory(output)
    longest = len(os.fsencode(store.partial_dir(output).name))
    try:
        name_max = os.pathconf(_existing_ancestor(output.parent), "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    if longest > name_max:
        raise RunError(f"output name too long: {output.name[:40]}... makes a "
                       f"{longest}-byte file name ({store.partial_dir(output).name[-20:]} "
                       f"included); the file system allows {name_max}")


def _check_parent_is_a_directory(output):
    """Refuse an output under a file (``-o c.toml/out.nc``): creating its directory said
    "File exists" or "Not a directory" of a path the user never named as a directory."""
    ancestor = _existing_ancestor(output.parent)
    if not ancestor.is_dir():
        raise RunError(f"{ancestor} is not a directory, so {output} cannot be written "
                       "under it; choose another -o")


def _check_not_the_config(output, source):
    """Refuse an output that is the configuration file itself (``sweep run x.nc`` writes
    x.nc by default): with --restart the run replaced the configuration by its output."""
    if source and output.exists() and store.same_file(output, source):
        raise RunError(f"the output {output} is the configuration file itself; give "
                       "another -o")


def _existing_ancestor(path):
    path = Path(path).absolute()
    return next((p for p in (path, *path.parents) if p.exists()), Path("/"))


def _prepare(cfg, output, chunk_size, quiet, log, in_memory=False):
    """Step 1: load the configuration, resolve and check the output (none for an
    in-memory run), build the design."""
    if not isinstance(cfg, _config.Config):
        cfg = _config.load(cfg)
    # Messages and progress share one stream that a failure silences (not the run).
    stream = _progress_mod.DroppingStream(sys.stderr)
    if log is None:
        log = (lambda msg: None) if quiet else (lambda msg: print(msg, file=stream))
    if in_memory:
        output = None
    else:
        output = _output_path(output) if output is not None else default_output(cfg)
        _check_output_path(output)
        _check_not_the_config(output, cfg.source)
    if chunk_size is None:
        chunk_size = cfg.chunk_size
    elif not _config.is_chunk_size(chunk_size):
        raise RunError(f"chunk size must be {_config.CHUNK_SIZE_RULE}, got {chunk_size!r}")
    design = _design.build(cfg.design, cfg.source)
    job = _Job(cfg=cfg, design=design, plan=ComputePlan.from_config(cfg),
               layout=design.layout(), output=output, chunk_size=int(chunk_size), log=log,
               result=RunResult(output=output, n_points=design.size), stream=stream)
    job.pre = _preflight_mod.preflight(job.layout, job.plan.variables, job.chunk_size,
                                       job.output)
    return job


def preflight(cfg: _config.Config | str | Path, output: str | Path | None = None,
              chunk_size: int | None = None) -> _preflight_mod.Preflight:
    """What :func:`run` with these arguments would cost; nothing is computed or written.

    Parameters
    ----------
    cfg, output, chunk_size
        As for :func:`run`.

    Returns
    -------
    sweep.sweeps.preflight.Preflight

    Raises
    ------
    sweep.sweeps.config.ConfigError, RunError
        As :func:`run` would before starting (configuration, output path, chunk size).
    """
    return _prepare(cfg, output, chunk_size, True, None).pre


def estimate_rate(cfg: _config.Config | str | Path,
                  output: str | Path | None = None) -> tuple[float, str, list[str]]:
    """Points per second :func:`run` can expect, where the figure comes from, and the
    caveats met on the way.

    The rate of the last run of this configuration into ``output`` if there is one, else
    a short calibration (:func:`sweep.sweeps.preflight.calibrate`; the kernels are
    compiled or loaded first, untimed). The calibration's largest sample is also judged as
    a run judges its points (:func:`caveat_messages`): a step budget too small for the
    resolution shows here, before the run, not at its end.

    Returns
    -------
    (float, str, list of str)
        Points per second, its source, and one sentence per caveat of the calibration's
        largest sample (none after a last run: ``sweep info`` lists its caveats).

    Raises
    ------
    sweep.sweeps.config.ConfigError, RunError
        As :func:`preflight`; RunError also for ``integrator.device = "cuda"`` without a
        usable GPU, as :func:`run` refuses it.
    """
    job = _prepare(cfg, output, None, True, None)
    _check_device(job)  # a missing GPU named as the run names it, not from the kernels
    sample = {}

    def compute(*points):
        arrays, seconds, caveats = compute_chunk(job.plan, *points)
        sample.update(n=len(points[0]), counts=dict(zip(_CAVEATS, caveats)))
        return arrays, seconds, caveats
    rate_, source = _preflight_mod.estimate_rate(job.design, compute, job.output,
                                                 job.cfg.sha256)
    if not sample:
        return rate_, source, []
    lines = caveat_messages(_applicable(job.plan, sample["counts"]),
                            count(sample["n"], "sample point"), _tols(job.plan))
    return rate_, source, lines


def _preflight(job, force, limits):
    """Step 2: size the run from the layout alone (done by :func:`_prepare`); refuse it
    above the limits unless ``force`` -- before anything is allocated or written."""
    if limits is not None and not isinstance(limits, _preflight_mod.Limits):
        # Read attribute by attribute below: anything else was an AttributeError.
        raise TypeError(f"limits must be a sweep.sweeps.preflight.Limits, got "
                        f"{type(limits).__name__} {limits!r:.60}")
    _refuse_unless_forced(job, job.pre.refusal(limits or _preflight_mod.Limits()), force)
    if job.output is not None:      # in memory: the dataset's own check comes first
        _refuse_unless_forced(job, job.pre.chunk_memory_refusal(), force)
    _check_device(job)


def _refuse_unless_forced(job, refusal, force, flag="--force"):
    """Raise ``refusal`` (a RunError) unless ``force``, which only logs it."""
    if refusal is None:
        return
    if not force:
        raise RunError(refusal)
    job.log(f"{flag}: {refusal.split(';')[0]}")


def _check_device(job):
    """A run on the GPU needs one: refused before anything is written (no CPU fallback, so
    that a file never silently comes from another device than its configuration says)."""
    if job.plan.integrator.get("device", "cpu") != "cuda":
        return
    from sweep.kernels.cuda import device_error  # noqa: PLC0415 -- optional numba-cuda

    why = device_error()
    if why is not None:
        raise RunError(f'integrator.device = "cuda": {why}')


def _take_lock(job):
    """Step 3: own the output before touching anything (``--restart`` included)."""
    try:
        job.output.parent.mkdir(parents=True, exist_ok=True)
        return store.OutputLock(job.output).acquire()
    except OSError as exc:
        raise RunError(f"cannot write in {job.output.parent.absolute()}: "
                       f"{exc.filename or job.output}: {exc.strerror or exc}") from exc


def _drop_untrusted(job):
    """A partial directory without a valid manifest (e.g. a clean-up cut by kill -9) is
    never resumed: it is removed, saying how many chunk files it held."""
    n = store.remove_untrusted(job.output)
    if n is not None:
        job.result.discarded_chunks = n
        job.log(f"removed {store.partial_dir(job.output)}: {count(n, 'chunk file')} without a "
                "valid manifest (left over by an interrupted run or clean-up; never resumed)")


def _existing_output_is_current(job, restart):
    """Step 4: True if the output already holds this configuration's results (see
    :func:`_output_is_current`); never with ``restart``, which overwrites it."""
    if restart:
        return False
    _drop_untrusted(job)
    if not _output_is_current(job):
        return False
    job.log(f"{job.output} is up to date (same configuration and version); nothing to do. "
            "Use --restart to recompute it.")
    return True


def _output_is_current(job):
    """True if the output holds this configuration's results; False if there is none or
    saved partial results take precedence over it (e.g. of an interrupted --restart). Any
    other existing file is refused rather than overwritten. Reads only.
    """
    output = job.output
    if not output.exists() or store.partial_dir(output).exists():
        return False
    attrs = store.read_global_attrs(output)
    if (attrs and attrs.get("sweep_config_sha256") == job.cfg.sha256
            and attrs.get("sweep_version") == __version__
            and attrs.get("sweep_source_sha256") == source_sha256()):
        _check_intact(output)
        return True
    what = ("was made by a different configuration or version of sweep" if attrs
            else "is not a sweep output" if attrs is not None
            else "cannot be read as netCDF (damaged, truncated or not a netCDF file)")
    # Worded for both fronts: sweep.run(out=...) meets these too.
    raise store.ResumeError(f"{output} exists and {what}; use --restart (restart=True) to "
                            "overwrite it, or choose another output with -o (out=)")


def _check_intact(output):
    """Refuse to call a damaged output up to date: its attributes match, but its values
    must read back too (bytes overwritten in the middle of the file left the attributes
    readable; see :func:`sweep.store.check_readable` for why reading is the check)."""
    try:
        store.check_readable(output)
    except OSError as exc:
        raise store.ResumeError(
            f"{output} has this configuration's attributes but cannot be read "
            f"({exc.strerror or exc}): it is damaged; use --restart (restart=True) to "
            "recompute it, or choose another output with -o (out=)") from exc


def _plan_chunks(job):
    """Step 6: cut the design into chunks (lazily); return the manifest the results
    depend on."""
    job.chunks = _design.Chunks(job.design.size, job.chunk_size)
    return {
        # What the values depend on (not the title nor the [run] table: the chunk size
        # is checked below), and its keys, which a refusal names where they differ.
        "config_sha256": job.cfg.values_sha256,
        "config": json.loads(job.cfg.computed) if job.cfg.computed else None,
        "sweep_version": __version__,
        "sweep_source_sha256": source_sha256(),
        "numerical_stack": numerical_stack(),
        "output": job.output.name,
        "n_points": job.design.size,
        "chunk_size": job.chunk_size,
        "variables": list(job.plan.variables),
        "design": job.design.describe(),
    }


def _check_disk(job, force):
    """Step 7: enough free disk for the chunk files and the assembled output?"""
    refusal = job.pre.disk_refusal(saved=store.partial_bytes(job.output))
    if refusal is not None:
        if not force:
            raise RunError(refusal)
        job.log(f"--force: {refusal.split(';')[0]}")


def _open_partial(job, manifest, restart, lock):
    """Step 8: create or reopen the resumable state; return it and the finished chunks."""
    partial = store.PartialStore(job.output, manifest, lock=lock)
    return partial, partial.open(restart=restart)


def _report(job, t_start):
    """Step 11: time the call and say what it did."""
    result = job.result
    result.wall_seconds = time.perf_counter() - t_start
    what = f"wrote {job.output}" if job.output is not None else "computed in memory"
    # The progress line's rate counts the chunks alone: say what this one counts besides.
    loading = ("" if result.compile_seconds is None else
               f" ({result.compile_seconds:.1f} s of it loading or compiling the kernels)")
    job.log(f"{what}: {count(job.design.size, 'point')} ({result.computed_points:,} "
            f"computed) in {result.wall_seconds:.1f} s{loading}, "
            f"{rate(result.points_per_second)}")
    _say_if_writer_bound(job)
    _warn_caveats(job)
    return result


#: A run that waited for its compressing background writer more than this share of its wall
#: time, and at least WRITER_HINT_SECONDS, says that the writer's zlib set its pace.
WRITER_HINT_SHARE = 0.1
WRITER_HINT_SECONDS = 1.0


def _say_if_writer_bound(job):
    """Name ``run.compress`` where the chunks waited long for a compressing writer: its
    zlib runs in one thread, however many cores compute (registry.COMPRESSION). Not after
    a resume, whose copied chunks wait for the writer by nature (and a changed
    configuration would not resume)."""
    result = job.result
    waited = result.writer_wait_seconds
    if not (job.cfg.compress != "none" and not result.resumed_chunks
            and waited >= WRITER_HINT_SECONDS
            and waited > WRITER_HINT_SHARE * result.wall_seconds):
        return
    share = registry.COMPRESSION[job.cfg.compress]
    lighter = " or ".join(f'"{c}"' for c, s in registry.COMPRESSION.items()
                          if s is None or s > share)
    job.log(f"the chunks waited {result.writer_wait_seconds:.1f} s of "
            f"{result.wall_seconds:.1f} s for the writer, whose compression runs in one "
            f"thread: compress = {lighter} in the configuration's [run] table deflates "
            "less (a larger file, written faster)")


def _applicable(plan, counts):
    """The counts of :data:`sweep.store.CAVEAT_ATTRS` that apply to the configuration."""
    names = [_CAVEATS[0]] if plan.integrate or plan.composites else []
    if _tols(plan):
        names.append(_CAVEATS[1])
    return {name: int(counts[name]) for name in names}


def _tols(plan):
    """The tols a point's e may miss, as the configuration names them: the integrator's
    (where set and it runs) and each composite method's own ("" where none)."""
    tols = []
    if plan.integrate and plan.integrator.get("tol") is not None:
        tols.append(f"integrator.tol = {plan.integrator['tol']:g}")
    for m in plan.composites:
        tol = api.given_options(m, plan.options.get(m, {}))[0].get("tol")
        if tol is not None:
            tols.append(f"options.{m}.tol = {tol:g}")
    return " or ".join(tols)


def caveat_messages(counts: dict, n: str, tol: str) -> list[str]:
    """One sentence for each count of :data:`sweep.store.CAVEAT_ATTRS` above 0.

    Parameters
    ----------
    counts : dict of str -> int
        The counts, by attribute name (those that apply to the configuration).
    n : str
        The points they are counted in, spelt out ("1,000 points").
    tol : str
        The tols a point may miss, named (``"integrator.tol = 1e-08"``).
    """
    lines = []
    if counts.get(_CAVEATS[0]):
        lines.append(f"{counts[_CAVEATS[0]]:,} of {n} ran out of the step budget: their e is "
                     "an upper bound, not a value (status BUDGET_EXHAUSTED; store status in "
                     "outputs.fields to see which, or raise integrator.max_steps)")
    if counts.get(_CAVEATS[1]):
        lines.append(f"{counts[_CAVEATS[1]]:,} of {n} may miss {tol}: their error "
                     "estimate e_err is above it (near grazing, or below e's rounding floor, "
                     "about 1e-13; e_numeric's e_err in outputs.fields says which)")
    return lines


def _warn_caveats(job):
    """Step 11a: a :class:`CaveatWarning` for each count of
    :data:`sweep.store.CAVEAT_ATTRS` above 0 (the file records them too; a point's
    ``status`` and ``e_err`` say which only where stored)."""
    for line in caveat_messages(job.result.caveats, count(job.design.size, "point"),
                                _tols(job.plan)):
        warnings.warn(line, CaveatWarning, stacklevel=4)


def _chunk_points(job, start, stop):
    return dict(zip(_config.PARAMETERS, job.design.points(start, stop)))


#: Points of the warm-up call (the first ones of the first chunk to compute): compiles or
#: loads the kernels the chunk will run.
WARM_UP_POINTS = 256


def _warm_up(job, done, scheduler):
    """Step 5a: load (or compile) the kernels on a few points before the timed chunks.

    Returns
    -------
    float or None
        Its duration [s]; None if nothing is computed in this process (every chunk is
        saved, or a Dask cluster computes them).
    """
    todo = [bounds for index, bounds in enumerate(job.chunks) if index not in done]
    if scheduler is not None or not todo:
        return None
    start, stop = todo[0]
    points = _chunk_points(job, start, min(stop, start + WARM_UP_POINTS))
    t0 = time.perf_counter()
    compute_chunk(job.plan, *(points[k] for k in _config.PARAMETERS))
    return time.perf_counter() - t0


def _tasks(job, partial, done, behind, totals, bar) -> Iterator[tuple]:
    """Chunks to compute, in order; saved chunks are verified and copied into the output
    on the way (in order, so storage chunks are written sequentially). A saved chunk that
    fails verification is recomputed."""
    for index, (start, stop) in enumerate(job.chunks):
        # Saved chunks too: they must have been computed at these very points.
        points = _chunk_points(job, start, stop)
        if index in done:
            loaded = partial.load_chunk(index, start, stop, points)
            if loaded is not None:
                arrays, (wall, kernel, *caveats) = loaded
                behind.submit(start, stop, arrays, points)
                totals.add(wall, kernel, caveats)
                job.result.resumed_chunks += 1
                continue
            done.discard(index)
            job.result.recomputed_chunks += 1
            bar.update(-(stop - start))  # it was counted as done at the start
        yield index, start, stop, points


def _log_plan(job, done):
    pre = job.pre
    free = _preflight_mod.free_disk(pre.directory)
    job.log(f"sweep: {job.design.describe()}; {count(len(job.chunks), 'chunk')} of <= "
            f"{count(job.chunk_size, 'point')}; "
            f"{'output' if job.output is not None else 'in memory'} <= "
            f"{_preflight_mod.format_bytes(pre.output_bytes)} uncompressed"
            + (f", {_preflight_mod.format_bytes(free)} free disk" if free is not None else "")
            + (f"; resuming, {count(len(done), 'chunk')} already done" if done else ""))


def _log_rejected(job, partial):
    if not job.result.recomputed_chunks:
        return
    why = ", ".join(f"{n} {reason}" for reason, n in sorted(partial.rejected.items()))
    job.log(f"resume: recomputed {count(job.result.recomputed_chunks, 'saved chunk')} that "
            f"failed verification ({why})")


def _stream_chunks(job, partial, done, behind, quiet, client, save=None):
    """Step 9: compute the missing chunks, saving (``save``, by default ``partial``'s) and
    writing each as it finishes.

    Returns the :class:`_Totals` of the whole dataset (resumed chunks included).
    """
    save = partial.save_chunk if save is None else save
    done = {i for i in done if i < len(job.chunks)}
    done_points = sum(job.chunks[i][1] - job.chunks[i][0] for i in done)
    _log_plan(job, done)
    totals, result = _Totals(), job.result
    last = time.perf_counter()
    with _progress_mod.progress(job.design.size, done_points, quiet=quiet, desc=job.label,
                                interval=job.progress_interval, stream=job.stream) as bar:
        tasks = _tasks(job, partial, done, behind, totals, bar)
        executor = (_local_executor(job.plan, tasks) if client is None
                    else _dask_executor(job.plan, tasks, client, job.log))
        for index, start, stop, points, arrays, kernel, caveats in executor:
            # A chunk's wall time runs from the end of the previous one's computation
            # (so its own saving and writing count towards the next chunk).
            now = time.perf_counter()
            wall, last = now - last, now
            save(index, start, stop, arrays, [wall, kernel, *caveats], points)
            behind.submit(start, stop, arrays, points)
            totals.add(wall, kernel, caveats)
            result.computed_points += stop - start
            result.kernel_seconds += kernel
            bar.update(stop - start)
    _log_rejected(job, partial)
    result.caveats = _applicable(job.plan, dict(zip(_CAVEATS, totals.caveats)))
    return totals


#: Signals that stop a run as Ctrl-C does, each with the word the command line says as it
#: stops (SIGHUP where the platform has it): ``sweep run`` unwinds from them, and the runner
#: holds them, with SIGINT, while it publishes its output (:func:`_signals_deferred`).
STOP_SIGNALS = {signal.SIGTERM: "terminated",
                **({signal.SIGHUP: "hung up"} if hasattr(signal, "SIGHUP") else {})}


@contextlib.contextmanager
def signals_handled(handler: Callable, signals) -> Iterator[None]:
    """Run the block with ``handler`` for each of ``signals``, then restore the handlers.

    A signal the process ignores stays ignored (under nohup a closed terminal must not stop
    a run). Off the main thread, where Python cannot set handlers (embedded use), the
    signals are left alone.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, handler) for s in signals
                if signal.getsignal(s) is not signal.SIG_IGN}
    try:
        yield
    finally:
        for s, old in previous.items():
            # None: a handler not set from Python, which signal() cannot take back.
            signal.signal(s, signal.SIG_DFL if old is None else old)


@contextlib.contextmanager
def _signals_deferred():
    """Hold SIGINT and :data:`STOP_SIGNALS` until the block ends, then deliver them as usual.

    The publication of the output and the invalidation of the partial state must not be
    cut in half by a signal: an interruption there would report a complete output as
    interrupted. Blocking the signals with a thread mask is not enough (numba's and the
    writer's threads would receive them); Python runs signal handlers in the main thread
    only, so a handler that just records them holds them there.
    """
    pending = []
    try:
        with signals_handled(lambda signum, frame: pending.append(signum),
                             (signal.SIGINT, *STOP_SIGNALS)):
            yield
    finally:
        for s in pending:
            signal.raise_signal(s)


#: Global attributes that differ between two runs of one configuration (when, how long,
#: how it was invoked, on how many threads); everything else is a function of the
#: configuration and the code.
VOLATILE_ATTRS = ("run_time_s", "kernel_time_s", "points_per_second", "compile_time_s",
                  "date_created", "history", "sweep_command", "executor",
                  "numba_num_threads", "numba_threading_layer")


def _timing_attrs(job, totals, scheduler):
    """Times of the whole dataset (see the module docstring) and the threads that ran it."""
    attrs = {  # times to the microsecond: a small run's kernels take milliseconds
        "run_time_s": round(totals.wall, 6),
        "kernel_time_s": round(totals.kernel, 6),
        "points_per_second": (round(job.design.size / totals.kernel, 1) if totals.kernel > 0
                              else -1.0),
    }
    if job.result.compile_seconds is not None:
        attrs["compile_time_s"] = round(job.result.compile_seconds, 6)
    if scheduler is None:
        attrs.update(_thread_attrs())
    return attrs


def _check_still_locked(job, partial):
    """Refuse to publish when the output's lock file was removed during the run: another
    run may have taken the output since, deleting this one's assembled file and starting
    its own, which a commit would then have published half-written, exit 0 (audit F)."""
    if not _still_ours(partial):
        raise RunError(f"{partial.lock.path} was removed during the run (a running sweep's "
                       f"lock is never stale: do not delete it), so another run may be "
                       f"writing {job.output}; not published: rerun the same command to "
                       "resume")


def _finish(job, partial, writer, behind, totals, scheduler):
    """Step 6: complete the file (timing attributes), publish it atomically, clean up."""
    behind.drain()
    job.result.writer_wait_seconds = behind.waited
    job.result.chunks = len(job.chunks)
    writer.set_attrs({**_timing_attrs(job, totals, scheduler), **job.result.caveats})
    writer.close()
    _check_still_locked(job, partial)
    try:
        with _signals_deferred():
            store.commit(partial.assembling, job.output)
            partial.invalidate()
            job.result.committed = True
        partial.remove()
    except KeyboardInterrupt:
        if not job.result.committed:
            raise
        # The output is complete: this is not an interrupted run. What is left of the
        # partial directory has no manifest, and the next run removes it.
        job.result.cleanup_interrupted = True
        job.log(f"clean-up of {partial.dir} interrupted; {job.output} is complete (the "
                "next run removes the leftovers)")


def _disk_is_full(exc, directory):
    if isinstance(exc, OSError):
        return exc.errno in (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC))
    # HDF5 reports a full disk as "NetCDF: HDF error", without errno: look at the disk.
    free = _preflight_mod.free_disk(directory)
    return (isinstance(exc, RuntimeError) and free is not None
            and free < _limits.DISK_FULL_MARGIN)


def _full_disk_text(exc, directory):
    """What ran out where ``directory`` is, in the words of the error: bytes, inodes (a
    file system can have bytes free and no file left to create) or a quota."""
    free = _preflight_mod.format_bytes(_preflight_mod.free_disk(directory) or 0)
    if isinstance(exc, OSError) and exc.errno != errno.ENOSPC:  # EDQUOT: over a quota
        return f"cannot write {exc.filename or directory}: {exc.strerror} ({free} free)"
    if _preflight_mod.free_inodes(directory) == 0:
        return (f"no free inodes left on the device of {directory}: no file can be "
                f"created ({free} free)")
    return f"no space left on the device of {directory} ({free} free)"


def _write_failure(job, partial, exc):
    """The one-line error for a failure while chunks are saved or written, or None to
    let ``exc`` through. Finished chunks are kept either way."""
    saved = len(partial.finished())
    keep = (f"the {count(saved, 'finished chunk')} {'is' if saved == 1 else 'are'} kept in "
            f"{partial.dir}: {job.resume_advice}")
    if isinstance(exc, ChunkFailed):
        return RunError(f"{exc}; {keep}")
    if _disk_is_full(exc, partial.dir):
        return RunError(f"{_full_disk_text(exc, partial.dir)}; {keep} once space is freed")
    if isinstance(exc, OSError):
        # A rename's second name is where it failed to put the file (the output itself,
        # on another file system or in a read-only directory).
        return RunError(f"cannot write {exc.filename2 or exc.filename or partial.dir}: "
                        f"{exc.strerror or exc}; {keep}")
    if isinstance(exc, RuntimeError) and str(exc).startswith("NetCDF"):
        return RunError(f"cannot write {partial.assembling}: {exc}{_size_limit_text()}; "
                        f"{keep}")
    return None


def _size_limit_text():
    """Where this process has a file size limit (``ulimit -f``), which HDF5 reports only
    as "HDF error", a clause naming it; else ""."""
    try:
        import resource
    except ImportError:  # pragma: no cover - not on POSIX
        return ""
    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    if soft == resource.RLIM_INFINITY:
        return ""
    return f" (this process may write files of at most {soft:,} bytes: ulimit -f)"


def _write_output(job, partial, done, quiet, client, scheduler):
    """Steps 9 and 10 around one writer; whatever happens, the file is closed and a
    half-assembled one deleted (it is rebuilt from the chunk files; deleting it gives a
    full disk its space back)."""
    writer = behind = None
    saver = _Behind(partial.save_chunk, SAVE_BEHIND, "sweep-saver")
    try:
        attrs = _static_attrs(job.cfg, job.design, job.plan, job.chunk_size)
        attrs.update(_provenance_attrs(job, scheduler, attrs["date_created"]))
        writer = store.NetCDFWriter(partial.assembling, job.layout, job.plan.variables, attrs,
                                    compress=job.cfg.compress)
        behind = _Behind(writer.write, WRITE_BEHIND, "sweep-writer")
        job.result.compile_seconds = _warm_up(job, done, client)
        totals = _stream_chunks(job, partial, done, behind, quiet, client, saver.submit)
        saver.drain()
        _finish(job, partial, writer, behind, totals, client)
    except KeyboardInterrupt:
        saver.settle()
        n_saved = len(partial.finished())
        job.log(f"\ninterrupted: {n_saved:,} of {count(len(job.chunks), 'chunk')} saved in "
                f"{partial.dir}; {job.resume_advice}")
        raise
    except Exception as exc:
        saver.settle()
        failure = _write_failure(job, partial, exc)
        if failure is None:
            raise
        raise failure from exc
    finally:
        saver.settle()
        saver.shutdown(cancel=False)     # every save handed over is kept
        if behind is not None:
            behind.shutdown()
        if writer is not None:
            with contextlib.suppress(Exception):  # a full disk also fails the close
                writer.close()
        if not job.result.committed and _still_ours(partial):
            with contextlib.suppress(OSError):
                partial.assembling.unlink()


def _still_ours(partial):
    """Whether the partial directory is still this run's: not where its lock file was
    removed, and another run may have taken the output and its own assembled file."""
    return partial.lock is None or not partial.lock.held or partial.lock.still_held()


def _run_locked(job, restart, quiet, force, scheduler, scheduler_timeout, lock):
    """Steps 4 to 10, holding the output's lock."""
    if _existing_output_is_current(job, restart):
        job.result.up_to_date = True
        return
    client, own = _connect(scheduler, scheduler_timeout)
    try:
        manifest = _plan_chunks(job)
        _check_disk(job, force)
        partial, done = _open_partial(job, manifest, restart, lock)
        job.result.discarded_chunks += partial.discarded
        _write_output(job, partial, done, quiet, client, scheduler)
    finally:
        if own:
            client.close()


def run(cfg: _config.Config | str | Path, output: str | Path | None = None, *,
        restart: bool = False, quiet: bool = False, chunk_size: int | None = None,
        scheduler: Any = None, log: Callable[[str], None] | None = None,
        force: bool = False, limits: _preflight_mod.Limits | None = None,
        scheduler_timeout: float | None = None,
        progress_interval: float | None = None) -> RunResult:
    """Run a sweep and write its dataset.

    Parameters
    ----------
    cfg : Config or path-like
        A validated configuration, or the path of a TOML configuration file.
    output : path-like, optional
        Output netCDF file (default :func:`default_output`); its suffix must be one of
        :data:`sweep.store.SUFFIXES`.
    restart : bool
        Discard saved partial results (and overwrite an existing output) instead of
        resuming.
    quiet : bool
        No progress bar, no messages.
    chunk_size : int, optional
        Points per chunk, 1 to :data:`sweep.sweeps.limits.MAX_CHUNK_SIZE` (default: the
        configuration's ``run.chunk_size``).
    scheduler : str or distributed.Client, optional
        Address of a Dask scheduler (``tcp://host:port``): run the chunks on that cluster.
    log : callable, optional
        Receives progress messages (default: print to stderr unless quiet).
    force : bool
        Run although the preflight finds the design above ``limits`` or the free disk
        short.
    limits : sweep.sweeps.preflight.Limits, optional
        Largest run started without ``force`` (default: :mod:`sweep.sweeps.limits`).
    scheduler_timeout : float, optional
        Seconds to wait for the scheduler to answer [s] (default
        :data:`sweep.sweeps.limits.SCHEDULER_TIMEOUT_S`).
    progress_interval : float, optional
        Seconds between two progress lines when stderr is not a terminal [s] (default
        :data:`sweep.sweeps.limits.PROGRESS_INTERVAL_S`; see :mod:`sweep.sweeps.progress`).

    Returns
    -------
    RunResult

    Raises
    ------
    sweep.sweeps.config.ConfigError
        Invalid configuration.
    sweep.store.ResumeError
        Saved partial results or an existing output do not match this configuration;
        :class:`sweep.store.LockError` (a subclass) if another process writes the output.
    RunError
        Refused by the preflight, an output path that cannot be written, a full disk, an
        unreachable scheduler. Finished chunks are kept and the previous output is never
        touched.
    """
    t_start = time.perf_counter()
    job = _prepare(cfg, output, chunk_size, quiet, log)
    job.progress_interval, job.restart = progress_interval, restart
    _preflight(job, force, limits)
    lock = _take_lock(job)
    try:
        _run_locked(job, restart, quiet, force, scheduler, scheduler_timeout, lock)
    finally:
        lock.release()
    if job.result.up_to_date:
        return job.result
    return _report(job, t_start)


def refusal(cfg: _config.Config | str | Path, output: str | Path | None = None,
            chunk_size: int | None = None, *, force: bool = False,
            limits: _preflight_mod.Limits | None = None) -> str | None:
    """Why :func:`run` with these arguments would refuse to start, or None: its own checks
    in its order, reading only -- nothing is computed, locked, written or deleted.

    The checks: the limits and a chunk's memory (unless ``force``), the device, an existing
    output that is not this configuration's, the free disk (unless ``force``), and saved
    partial results that cannot be resumed.

    Parameters
    ----------
    cfg, output, chunk_size, force, limits
        As for :func:`run`.

    Returns
    -------
    str or None
        The one-line message :func:`run` would raise.

    Raises
    ------
    sweep.sweeps.config.ConfigError, RunError
        As :func:`preflight` (configuration, output path, chunk size).
    """
    job = _prepare(cfg, output, chunk_size, True, None)
    try:
        _preflight(job, force, limits)
        if not _output_is_current(job):
            manifest = _plan_chunks(job)
            _check_disk(job, force)
            store.PartialStore(job.output, manifest).check()
    except (RunError, store.ResumeError) as exc:
        return str(exc)
    return None


# --------------------------------------------------------------------------- in memory

class _NoPartial:
    """The partial state of an in-memory run: there is none (nothing is saved, so nothing
    resumes), and the chunk streaming step needs no other case."""

    rejected: dict = {}

    def save_chunk(self, *args) -> None:
        pass


def _compute_in_memory(job, quiet, client, scheduler):
    """Steps 5 to 10 of an in-memory run: the chunks streamed into a
    :class:`sweep.store.MemoryWriter`; returns it, closed."""
    job.chunks = _design.Chunks(job.design.size, job.chunk_size)
    attrs = _static_attrs(job.cfg, job.design, job.plan, job.chunk_size)
    attrs.update(_provenance_attrs(job, scheduler, attrs["date_created"]))
    writer = store.MemoryWriter(job.layout, job.plan.variables, attrs)
    # Copying a chunk into memory is cheap: no background writer.
    behind = _Behind(writer.write, 0, "sweep-writer")
    try:
        job.result.compile_seconds = _warm_up(job, set(), client)
        totals = _stream_chunks(job, _NoPartial(), set(), behind, quiet, client)
    finally:
        behind.shutdown()
    job.result.chunks = len(job.chunks)
    writer.set_attrs({**_timing_attrs(job, totals, client), **job.result.caveats})
    writer.close()
    return writer


def run_in_memory(cfg: _config.Config | str | Path, *, quiet: bool = False,
                  chunk_size: int | None = None, scheduler: Any = None,
                  log: Callable[[str], None] | None = None, force: bool = False,
                  limits: _preflight_mod.Limits | None = None,
                  scheduler_timeout: float | None = None,
                  progress_interval: float | None = None) -> tuple[Any, RunResult]:
    """Run a sweep in memory: the dataset :func:`run` would write, as an xarray.Dataset.

    The same driver as :func:`run` (kernels, chunks, warm-up, timing, attributes,
    progress, local or Dask executor) with a :class:`sweep.store.MemoryWriter` in place of
    the netCDF file: no file, no lock, no partial directory and therefore no resume (an
    interrupted in-memory run starts again from the beginning). Memory is the size of the
    dataset (plus one variable while it is decoded).

    Parameters
    ----------
    cfg : Config or path-like
        As for :func:`run`.
    quiet, chunk_size, scheduler, log, limits, scheduler_timeout, progress_interval
        As for :func:`run`.
    force : bool
        Run although the design is above ``limits`` or larger than this machine's memory.

    Returns
    -------
    (xarray.Dataset, RunResult)
        The dataset, identical to the file :func:`run` writes read back by
        ``xarray.open_dataset`` but for :data:`VOLATILE_ATTRS`; the result's ``output`` is
        None.

    Raises
    ------
    sweep.sweeps.config.ConfigError, RunError
        As :func:`run`; also a design too large for this machine's memory (a RunError).
    """
    t_start = time.perf_counter()
    job = _prepare(cfg, None, chunk_size, quiet, log, in_memory=True)
    job.progress_interval = progress_interval
    _preflight(job, force, limits)
    refusal = job.pre.memory_refusal() or job.pre.chunk_memory_refusal()
    _refuse_unless_forced(job, refusal, force, flag="force")
    client, own = _connect(scheduler, scheduler_timeout)
    try:
        writer = _compute_in_memory(job, quiet, client, scheduler)
    finally:
        if own:
            client.close()
    return writer.dataset(), _report(job, t_start)
