"""End-to-end benchmark of ``sweep run``: throughput, peak memory, overhead outside kernels.

Default: the bundled 1,000,000-point Sobol' design (configs/sobol_1m.toml: numerical CoR,
four approximations, their errors and every integrator field), run exactly as
``sweep run`` does, into a temporary directory::

    python benchmarks/end_to_end.py                  # the whole 1e6-point design
    python benchmarks/end_to_end.py --n 100000       # its first 1e5 points (quick look)
    python benchmarks/end_to_end.py --memory 100000000

``--memory N`` is the memory test of a huge design: an N-point Sobol' design over the same
box storing the cheap closed-form approximations only (no integration, so that 1e8 points
take minutes, not hours); memory does not depend on how long a kernel takes, only on what
is held per chunk and on the output's size, which this exercises fully (five stored
variables plus four per-point coordinates: 7.2 GB of results for 1e8 points).

Printed: points/s (whole run, wall clock), peak resident memory of the process
(``getrusage`` ``ru_maxrss``: the high-water mark, JIT compiler included), the fraction of the
wall time spent outside the api kernels, and where that time went (design generation,
waiting for the background netCDF writer and resume saver, the final atomic commit).
The kernels are compiled (or loaded from numba's cache) before the clock starts.
"""
from __future__ import annotations

import argparse
import functools
import os
import resource
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sweep import api, store  # noqa: E402
from sweep.sweeps import config, design, runner  # noqa: E402

MEMORY_CONFIG = """
title = "memory test: {n} points, approximations only"
[design]
kind = "doe"
sampler = "sobol"
n = {n}
seed = 1
alpha = {{min = 1.0, max = 3.0}}
beta = {{min = 1.0, max = 3.0}}
gamma = {{min = 1e-4, max = 1.0, scale = "log"}}
gtilde = {{min = 0.0, max = 10.0}}
[outputs]
e = ["ord1", "sp", "large_gtilde", "ord2_numint", "ord2_approx"]
[run]
chunk_size = {chunk}
"""


def timed(table, key, func):
    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return func(*args, **kwargs)
        finally:
            table[key] += time.perf_counter() - t0
    return wrapper


def instrument(table, background):
    """Time the non-kernel stages of a run by wrapping them (the runner is unchanged)."""
    for cls in (design.GridDesign, design.DoEDesign):
        cls.points = timed(table, "design points", cls.points)
    # The netCDF writing and the saves for resume run in background threads: what the main
    # thread loses is the time it waits for them (queue full, final drain), timed apart.
    store.PartialStore.save_chunk = timed(background, "save chunk for resume (background "
                                          "thread)", store.PartialStore.save_chunk)
    runner._Behind.submit = timed(table, "wait for background", runner._Behind.submit)
    runner._Behind.drain = timed(table, "wait for background", runner._Behind.drain)
    store.NetCDFWriter.write = timed(background, "netCDF writing (background thread)",
                                     store.NetCDFWriter.write)
    store.NetCDFWriter.close = timed(table, "close netCDF", store.NetCDFWriter.close)
    store.commit = timed(table, "commit (fsync, rename)", store.commit)


def warm_up(cfg):
    """Compile (or load) every kernel the run needs, outside the timed region."""
    d = design.build(cfg.design)
    n = min(d.size, 256)
    points = d.points(0, n)
    runner.compute_chunk(runner.ComputePlan.from_config(cfg), *points)


def _integrator_line(cfg) -> str:
    """The integrator options the configuration gives (tol, steps, ...), or the default."""
    if not cfg.outputs.needs_integration:
        return "not run"
    given = cfg.integrator.kwargs()
    if not given:
        return f"steps={api.DEFAULT_STEPS} (default)"
    return ", ".join(f"{name}={value}" for name, value in sorted(given.items()))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", default=str(ROOT / "configs" / "sobol_1m.toml"))
    parser.add_argument("--n", type=int, help="run only the first N points of the design")
    parser.add_argument("--memory", type=int, metavar="N",
                        help="memory test: an N-point design of approximations only")
    parser.add_argument("--chunk-size", type=int)
    parser.add_argument("--dir", help="where to write the output (default: a temp dir)")
    parser.add_argument("--keep", action="store_true", help="keep the output file")
    args = parser.parse_args(argv)

    if args.memory:
        cfg = config.loads(MEMORY_CONFIG.format(n=args.memory,
                                                chunk=args.chunk_size or 2 ** 18),
                           source="memory_test.toml")
    else:
        text = Path(args.config).read_text()
        if args.n:
            text = text.replace("n = 1_000_000", f"n = {args.n}")
        cfg = config.loads(text, source=args.config)
    warm_up(cfg)
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    table, background = defaultdict(float), defaultdict(float)
    instrument(table, background)

    workdir = Path(args.dir) if args.dir else Path(tempfile.mkdtemp(prefix="sweep-bench-"))
    out = workdir / "bench.nc"
    try:
        res = runner.run(cfg, out, restart=True, quiet=True, chunk_size=args.chunk_size)
        size = out.stat().st_size
    finally:
        if not args.keep:
            for p in (out, store.partial_dir(out)):
                if p.is_dir():
                    import shutil
                    shutil.rmtree(p, ignore_errors=True)
                elif p.exists():
                    p.unlink()
            if not args.dir:
                os.rmdir(workdir)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    outside = res.wall_seconds - res.kernel_seconds
    print(f"design            : {design.build(cfg.design).describe()}")
    print(f"stored variables  : {', '.join(cfg.outputs.variables)}")
    print(f"integrator        : {_integrator_line(cfg)}")
    print(f"points            : {res.n_points} in {res.chunks} chunks")
    print(f"wall time         : {res.wall_seconds:.2f} s")
    print(f"points/s          : {res.points_per_second:,.0f}")
    print(f"kernel time       : {res.kernel_seconds:.2f} s")
    print(f"outside kernels   : {outside:.2f} s = {100 * res.outside_fraction:.2f}% of wall time")
    for key, value in sorted(table.items(), key=lambda kv: -kv[1]):
        print(f"  {key:<22}: {value:.3f} s")
    rest = outside - sum(table.values())
    print(f"  {'other (runner, tqdm)':<22}: {rest:.3f} s")
    for key, value in background.items():
        print(f"  [{key}: {value:.3f} s, overlapping the kernels]")
    print(f"output size       : {size / 2 ** 20:.1f} MiB")
    print(f"peak RSS          : {peak:.0f} MiB (after warm-up, before the run: "
          f"{rss_before:.0f} MiB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
