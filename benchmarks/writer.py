"""CPU time and file size of the netCDF writer on a sweep's real values.

    python benchmarks/writer.py [--n 131072] [--config configs/sobol_1m.toml] [--repeat 3]
        [--compress fast|small|none]

Computes the configuration's design cut to its first ``n`` points in memory (``sweep.run``),
then writes those values with :class:`sweep.store.NetCDFWriter` in the configuration's
chunks, one core, ``repeat`` times, deflating as ``--compress`` says (``run.compress``;
default the configuration's). Prints the writer's CPU seconds per million points
(best of ``repeat``; zlib runs inside HDF5 in this thread), the file's size against the raw
values', and each variable's compression as xarray reads it back; then the CPU seconds of
saving the same chunks for resume (:meth:`sweep.store.PartialStore.save_chunk`, a run's
saver thread). On the Sobol design both are taken from the kernels' cores in a run on
every core (``docs/speed``).
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import xarray as xr

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import sweep  # noqa: E402
from sweep import store  # noqa: E402
from sweep.sweeps import config  # noqa: E402

COORDS = ("alpha", "beta", "gamma", "gtilde")


def values(path: Path, n: int):
    """The run's per-point values and coordinates (a scattered design), and its chunk."""
    cfg = config.loads(path.read_text().replace("n = 1_000_000", f"n = {n}"),
                       source=str(path))
    ds = sweep.run(cfg, quiet=True)
    names = [k for k in ds.data_vars if ds[k].dims == ("point",)]
    return ({k: ds[k].values for k in names}, {k: ds[k].values for k in COORDS},
            cfg.chunk_size, cfg.compress)


def write(path, data, points, chunk, compress):
    """Write ``data`` chunk by chunk; return the CPU seconds it took."""
    n = len(next(iter(points.values())))
    layout = store.Layout(dims=("point",), shape=(n,), axes={}, point_coords=COORDS)
    t = time.process_time()
    w = store.NetCDFWriter(path, layout, list(data), compress=compress)
    for s in range(0, n, chunk):
        e = min(n, s + chunk)
        w.write(s, e, {k: v[s:e] for k, v in data.items()},
                {k: v[s:e] for k, v in points.items()})
    w.close()
    return time.process_time() - t


def save(path, data, points, chunk):
    """Save ``data`` chunk by chunk for resume (:class:`sweep.store.PartialStore`, as a
    run's saver thread does); return the CPU seconds it took."""
    n = len(next(iter(points.values())))
    partial = store.PartialStore(path, {"config_sha256": "benchmark", "variables": list(data)})
    partial.open()
    t = time.process_time()
    for i, s in enumerate(range(0, n, chunk)):
        e = min(n, s + chunk)
        partial.save_chunk(i, s, e, {k: v[s:e] for k, v in data.items()}, (0.0,),
                           {k: v[s:e] for k, v in points.items()})
    cpu = time.process_time() - t
    partial.remove()
    return cpu


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--n", type=int, default=131072)
    p.add_argument("--config", type=Path, default=ROOT / "configs" / "sobol_1m.toml")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--compress", choices=list(sweep.registry.COMPRESSION))
    args = p.parse_args()
    data, points, chunk, compress = values(args.config, args.n)
    compress = args.compress or compress
    raw = sum(v.nbytes for v in data.values()) + sum(v.nbytes for v in points.values())
    with tempfile.TemporaryDirectory(prefix="sweep-writer-") as tmp:
        out = Path(tmp) / "w.nc"
        cpu = min(write(out, data, points, chunk, compress) for _ in range(args.repeat))
        size = os.path.getsize(out)
        with xr.open_dataset(out) as ds:
            enc = {k: ds[k].encoding for k in list(data) + list(COORDS)}
        saves = min(save(Path(tmp) / "s.nc", data, points, chunk) for _ in range(args.repeat))
    print(f"writer, compress = {compress!r}: {cpu / args.n * 1e6:.2f} s of CPU a million "
          f"points ({args.n:,} points, "
          f"chunks of {chunk:,}); file {size / 1e6:.2f} MB of {raw / 1e6:.2f} MB raw")
    print(f"resume saves: {saves / args.n * 1e6:.2f} s of CPU a million points (the chunk files "
          f"a run keeps until it completes, written by its saver thread)")
    for k, e in enc.items():
        how = ("deflate" + (" + shuffle" if e.get("shuffle") else "")) if e.get("zlib") \
            else "stored"
        print(f"  {k:20s} {how}")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
