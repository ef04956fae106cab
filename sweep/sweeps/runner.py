"""Chunked, resumable execution of a sweep.

The design is cut into chunks of ``chunk_size`` consecutive points (flat index). For each
chunk the runner generates the points (:mod:`sweep.sweeps.design`), computes exactly the requested
outputs (:func:`compute_chunk`, which calls :mod:`sweep.api`), saves the chunk for resuming
and writes it into the output being assembled (:mod:`sweep.store`). Memory is bounded by a
few chunks, whatever the design size.

Two executors:

* local (default): chunks are fed one after another, from the main thread, to the api
  functions, which already run in parallel on all cores (numba ``prange``). The netCDF
  writing (zlib compression) happens in one background thread, overlapping the next chunk
  (see :class:`_WriteBehind`; on 2 cores it cut a 4e6-point run of cheap approximations
  from 25 s to 17 s). Saving a chunk for resume stays synchronous: a chunk is reported done
  only once it is on disk.
* distributed: ``scheduler="tcp://host:port"`` (or a ``distributed.Client``) submits chunks
  to a Dask cluster, keeping a bounded number in flight; results are written as they come
  back, in any order. Worker threads run the api's serial kernels unless numba's threading
  layer is thread-safe (decided by the api).

Every chunk's values depend only on its points, and point ``i`` of a design never depends on
the chunking, so results are identical for any chunk size, thread count or executor.

:func:`run` is a driver that reads as its steps: prepare (load the configuration, build
the design and the :class:`ComputePlan`), check an existing output, plan the chunks, open
the partial state, stream the chunks (resumed ones copied, the others computed), finish
(write the timing attributes, commit atomically) and report.

Floor 4: may import :mod:`sweep.api`, :mod:`sweep.registry`, :mod:`sweep.store`,
:mod:`sweep.sweeps.config`, :mod:`sweep.sweeps.design` and :mod:`sweep._version` (and,
lazily, tqdm and Dask); nothing of the reports or the command line.
"""
from __future__ import annotations

import collections
import concurrent.futures
import dataclasses
import datetime as _dt
import hashlib
import importlib.metadata
import platform
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from sweep import api, registry, store
from sweep._version import __version__
from sweep.sweeps import config as _config
from sweep.sweeps import design as _design

__all__ = ["ComputePlan", "compute_chunk", "run", "RunResult", "default_output",
           "source_sha256"]


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
    """
    t0 = time.perf_counter()
    res = None
    if plan.integrate:
        res = api.integrate(alpha, beta, gamma, gtilde, **plan.integrator)
    approx = {m: api.cor(alpha, beta, gamma, gtilde, method=m, **plan.options.get(m, {}))
              for m in plan.approximations}
    own = {}  # the composite methods' e and fields
    for m in plan.composites:
        out = api.cor_fields(alpha, beta, gamma, gtilde, method=m, **plan.options.get(m, {}))
        approx[m] = out.pop("e")
        own.update({name: value for name, value in out.items() if name != "status"})
    seconds = time.perf_counter() - t0
    arrays = {}
    for name in plan.variables:
        if name == "e_numeric":
            value = res.e
        elif name.startswith("e_"):
            value = approx[name[2:]]
        elif name.startswith("error_"):
            # The integration ran once above; every error field shares it.
            value = approx[name[6:]] - res.e
        else:
            value = own[name] if name in own else getattr(res, name)
        dtype, _ = store.variable_spec(name)
        arrays[name] = np.ascontiguousarray(value, dtype=dtype).reshape(-1)
    return arrays, seconds


# --------------------------------------------------------------------------- running

@dataclasses.dataclass
class RunResult:
    """What a run did.

    Attributes
    ----------
    output : Path
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
    """

    output: Path
    n_points: int
    computed_points: int = 0
    wall_seconds: float = 0.0
    kernel_seconds: float = 0.0
    up_to_date: bool = False
    chunks: int = 0
    resumed_chunks: int = 0

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
        ``sweep.nc`` for a configuration without a source file.
    """
    stem = Path(cfg.source).stem if cfg.source else "sweep"
    return Path(stem + ".nc")


def _version(dist):
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:  # pragma: no cover
        return "unknown"


def source_sha256() -> str:
    """Hash of the package's Python sources.

    Two runs of one configuration give identical results only with identical code; the
    version number alone does not see a local edit. Resuming, and reusing an existing
    output, therefore also require the same source hash.

    Returns
    -------
    str
        Hex SHA-256 over the relative path and bytes of every ``sweep/**/*.py``.
    """
    package = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        h.update(path.relative_to(package).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def _integrator_attrs(plan):
    if not plan.integrate:
        return {"integrator": "not run (no requested output needs the numerical integration)"}
    s = plan.integrator
    return {
        "integrator": "fixed-step Dormand-Prince 5(4), three phases of Algorithm 1",
        "integrator_steps": float(api.DEFAULT_STEPS if s["steps"] is None else s["steps"]),
        "integrator_rest_tol": float(s["rest_tol"]),
        "integrator_max_steps": int(api.DEFAULT_MAX_STEPS if s["max_steps"] is None
                                    else s["max_steps"]),
    }


def _static_attrs(cfg, design, plan, chunk_size):
    now = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()
    attrs = {
        "title": cfg.title,
        "summary": cfg.description or cfg.title,
        "Conventions": "CF-1.10",
        "source": f"sweep {__version__} (numba {_version('numba')}, numpy {np.__version__})",
        "references": store.REPORT,
        "history": f"{now} sweep run {cfg.source or '<text>'}",
        "date_created": now,
        "sweep_version": __version__,
        "sweep_source_sha256": source_sha256(),
        "numba_version": _version("numba"),
        "numpy_version": np.__version__,
        "scipy_version": _version("scipy"),
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
            attrs[f"options_{method}_{key}"] = value
    return attrs


def _progress(total, initial, quiet, desc):
    from tqdm.auto import tqdm

    disable = quiet or not sys.stderr.isatty()
    return tqdm(total=total, initial=initial, unit="pt", unit_scale=True, desc=desc,
                disable=disable, dynamic_ncols=True, smoothing=0.1)


def _local_executor(plan, tasks):
    for index, start, stop, points in tasks:
        arrays, seconds = compute_chunk(plan, *(points[k] for k in _config.PARAMETERS))
        yield index, start, stop, points, arrays, seconds


def _dask_executor(plan, tasks, scheduler):
    from distributed import Client, as_completed

    own = not isinstance(scheduler, Client)
    client = Client(scheduler) if own else scheduler
    try:
        # A bounded number of chunks in flight keeps memory bounded on both sides.
        window = max(2, 2 * sum(client.nthreads().values()))
        futures = as_completed()
        meta = {}
        token = uuid.uuid4().hex  # task keys unique to this run on a shared scheduler
        tasks = iter(tasks)

        def submit_next():
            for index, start, stop, points in tasks:
                fut = client.submit(compute_chunk, plan,
                                    *(points[k] for k in _config.PARAMETERS),
                                    pure=False, key=f"sweep-chunk-{index}-{token}")
                meta[fut.key] = (index, start, stop, points)
                futures.add(fut)
                return True
            return False

        for _ in range(window):
            if not submit_next():
                break
        for fut in futures:
            arrays, seconds = fut.result()
            index, start, stop, points = meta.pop(fut.key)
            fut.release()
            yield index, start, stop, points, arrays, seconds
            submit_next()
    finally:
        if own:
            client.close()


#: Chunks allowed to wait for the background writer (0: write in the main thread).
WRITE_BEHIND = 2


class _WriteBehind:
    """Write chunks into the netCDF file from one background thread.

    zlib compression runs inside HDF5 with the GIL released, so it overlaps the next
    chunk's kernels (fully with serial kernels, which leave cores idle). At most ``depth``
    chunks wait to be written, which bounds memory; only this thread touches the file while
    it runs (HDF5 builds are usually not thread-safe), and an error in it is raised in the
    main thread at the next :meth:`write` or at :meth:`drain`.
    """

    def __init__(self, writer: store.Writer, depth: int = 2) -> None:
        self._writer = writer
        self._depth = depth
        self._pending = collections.deque()
        self._pool = concurrent.futures.ThreadPoolExecutor(
            max_workers=1, thread_name_prefix="sweep-writer")

    def write(self, *args):
        if self._depth == 0:
            self._writer.write(*args)
            return
        while len(self._pending) >= self._depth:
            self._pending.popleft().result()
        self._pending.append(self._pool.submit(self._writer.write, *args))

    def drain(self):
        """Wait until every submitted chunk is written (re-raising a writer error)."""
        while self._pending:
            self._pending.popleft().result()

    def shutdown(self):
        for fut in self._pending:
            fut.cancel()
        self._pool.shutdown(wait=True)
        self._pending.clear()


# --------------------------------------------------------------------------- the driver's steps

@dataclasses.dataclass
class _Job:
    """What the steps of one :func:`run` call share."""

    cfg: _config.Config
    design: Any
    plan: ComputePlan
    layout: store.Layout
    output: Path
    chunk_size: int
    log: Callable[[str], None]
    result: RunResult
    chunks: list = dataclasses.field(default_factory=list)


@dataclasses.dataclass
class _Totals:
    """Wall and kernel time of every chunk of the dataset, this session's and resumed."""

    wall: float = 0.0
    kernel: float = 0.0

    def add(self, wall, kernel):
        self.wall += wall
        self.kernel += kernel


def _prepare(cfg, output, chunk_size, quiet, log):
    """Step 1: load the configuration, resolve the output, build the design and plan."""
    if not isinstance(cfg, _config.Config):
        cfg = _config.load(cfg)
    if log is None:
        log = (lambda msg: None) if quiet else (lambda msg: print(msg, file=sys.stderr))
    output = Path(output) if output is not None else default_output(cfg)
    chunk_size = int(chunk_size or cfg.chunk_size)
    design = _design.build(cfg.design)
    return _Job(cfg=cfg, design=design, plan=ComputePlan.from_config(cfg),
                layout=design.layout(), output=output, chunk_size=chunk_size, log=log,
                result=RunResult(output=output, n_points=design.size))


def _existing_output_is_current(job, restart):
    """Step 2: True if the output already holds this configuration's results.

    An existing output is reused only if it is what this configuration would produce;
    saved partial results (e.g. of an interrupted --restart) take precedence over it, and
    any other existing file is refused rather than overwritten.
    """
    output = job.output
    if not output.exists() or restart or store.partial_dir(output).exists():
        return False
    attrs = store.read_global_attrs(output)
    if (attrs and attrs.get("sweep_config_sha256") == job.cfg.sha256
            and attrs.get("sweep_version") == __version__
            and attrs.get("sweep_source_sha256") == source_sha256()):
        job.log(f"{output} is up to date (same configuration and version); nothing to do. "
                "Use --restart to recompute it.")
        return True
    what = ("was made by a different configuration or version of sweep" if attrs
            else "is not a sweep output")
    raise store.ResumeError(f"{output} exists and {what}; use --restart to overwrite "
                            "it, or choose another output with -o")


def _plan_chunks(job):
    """Step 3: cut the design into chunks; return the manifest the results depend on."""
    job.chunks = _design.chunk_bounds(job.design.size, job.chunk_size)
    return {
        "config_sha256": job.cfg.sha256,
        "sweep_version": __version__,
        "sweep_source_sha256": source_sha256(),
        "output": job.output.name,
        "n_points": job.design.size,
        "chunk_size": job.chunk_size,
        "variables": list(job.plan.variables),
        "design": job.design.describe(),
    }


def _open_partial(job, manifest, restart):
    """Step 4: create or reopen the resumable state; return it and the finished chunks."""
    partial = store.PartialStore(job.output, manifest)
    return partial, partial.open(restart=restart)


def _report(job, t_start):
    """Step 7: time the call and say what it did."""
    result = job.result
    result.wall_seconds = time.perf_counter() - t_start
    job.log(f"wrote {job.output}: {job.design.size} points ({result.computed_points} "
            f"computed) in {result.wall_seconds:.1f} s, {result.points_per_second:.4g} pt/s")
    return result


def _chunk_points(job, start, stop):
    return dict(zip(_config.PARAMETERS, job.design.points(start, stop)))


def _tasks(job, partial, done, behind, totals, bar) -> Iterator[tuple]:
    """Chunks to compute, in order; saved chunks are copied into the output on the way
    (in order, so storage chunks are written sequentially)."""
    for index, (start, stop) in enumerate(job.chunks):
        need_points = index not in done or job.layout.per_point
        points = _chunk_points(job, start, stop) if need_points else None
        if index in done:
            loaded = partial.load_chunk(index, start, stop)
            if loaded is not None:
                arrays, (wall, kernel) = loaded
                behind.write(start, stop, arrays, points)
                totals.add(wall, kernel)
                job.result.resumed_chunks += 1
                continue
            job.log(f"chunk {index}: saved file unreadable, recomputing it")
            done.discard(index)
            bar.update(-(stop - start))  # it was counted as done at the start
            if points is None:
                points = _chunk_points(job, start, stop)
        yield index, start, stop, points


def _stream_chunks(job, partial, done, behind, quiet, scheduler):
    """Step 5: compute the missing chunks, saving and writing each as it finishes.

    Returns the :class:`_Totals` of the whole dataset (resumed chunks included).
    """
    done = {i for i in done if i < len(job.chunks)}
    done_points = sum(job.chunks[i][1] - job.chunks[i][0] for i in done)
    job.log(f"sweep: {job.design.describe()}; {len(job.chunks)} chunks of <= "
            f"{job.chunk_size} points"
            + (f"; resuming, {len(done)} chunks already done" if done else ""))
    totals, result = _Totals(), job.result
    last = time.perf_counter()
    with _progress(job.design.size, done_points, quiet, job.output.name) as bar:
        tasks = _tasks(job, partial, done, behind, totals, bar)
        executor = (_local_executor(job.plan, tasks) if scheduler is None
                    else _dask_executor(job.plan, tasks, scheduler))
        for index, start, stop, points, arrays, kernel in executor:
            # A chunk's wall time runs from the end of the previous one's computation
            # (so its own saving and writing count towards the next chunk).
            now = time.perf_counter()
            wall, last = now - last, now
            partial.save_chunk(index, start, stop, arrays, [wall, kernel])
            behind.write(start, stop, arrays, points)
            totals.add(wall, kernel)
            result.computed_points += stop - start
            result.kernel_seconds += kernel
            bar.update(stop - start)
    return totals


def _finish(job, partial, writer, behind, totals):
    """Step 6: complete the file (timing attributes), publish it atomically, clean up."""
    behind.drain()
    job.result.chunks = len(job.chunks)
    run_time = totals.wall
    writer.set_attrs({
        "run_time_s": round(run_time, 3),
        "kernel_time_s": round(totals.kernel, 3),
        "points_per_second": (round(job.design.size / run_time, 1) if run_time > 0
                              else -1.0),
    })
    writer.close()
    store.commit(partial.assembling, job.output)
    partial.remove()


def _write_output(job, partial, done, quiet, scheduler):
    """Steps 5 and 6 around one writer; whatever happens, the file and lock are released."""
    writer = behind = None
    try:
        writer = store.NetCDFWriter(partial.assembling, job.layout, job.plan.variables,
                                    _static_attrs(job.cfg, job.design, job.plan,
                                                  job.chunk_size))
        behind = _WriteBehind(writer, depth=WRITE_BEHIND)
        totals = _stream_chunks(job, partial, done, behind, quiet, scheduler)
        _finish(job, partial, writer, behind, totals)
    except KeyboardInterrupt:
        n_saved = len(partial.finished())
        job.log(f"\ninterrupted: {n_saved} of {len(job.chunks)} chunks are saved in "
                f"{partial.dir}; rerun the same command to resume")
        raise
    finally:
        if behind is not None:
            behind.shutdown()
        if writer is not None:
            writer.close()
        partial.release()


def run(cfg: _config.Config | str | Path, output: str | Path | None = None, *,
        restart: bool = False, quiet: bool = False, chunk_size: int | None = None,
        scheduler: Any = None, log: Callable[[str], None] | None = None) -> RunResult:
    """Run a sweep and write its dataset.

    Parameters
    ----------
    cfg : Config or path-like
        A validated configuration, or the path of a TOML configuration file.
    output : path-like, optional
        Output netCDF file (default :func:`default_output`).
    restart : bool
        Discard saved partial results (and overwrite an existing output) instead of
        resuming.
    quiet : bool
        No progress bar, no messages.
    chunk_size : int, optional
        Points per chunk (default: the configuration's ``run.chunk_size``).
    scheduler : str or distributed.Client, optional
        Address of a Dask scheduler (``tcp://host:port``): run the chunks on that cluster.
    log : callable, optional
        Receives progress messages (default: print to stderr unless quiet).

    Returns
    -------
    RunResult

    Raises
    ------
    sweep.sweeps.config.ConfigError
        Invalid configuration.
    sweep.store.ResumeError
        Saved partial results or an existing output do not match this configuration.
    """
    t_start = time.perf_counter()
    job = _prepare(cfg, output, chunk_size, quiet, log)
    if _existing_output_is_current(job, restart):
        job.result.up_to_date = True
        return job.result
    manifest = _plan_chunks(job)
    partial, done = _open_partial(job, manifest, restart)
    _write_output(job, partial, done, quiet, scheduler)
    return _report(job, t_start)
