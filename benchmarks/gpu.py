"""The CUDA backend against the CPU on the same machine (issue 14, item 4).

    python benchmarks/gpu.py                 # 1 and 16 million points, under 5 minutes
    python benchmarks/gpu.py --quick         # machinery only (tiny sizes; also simulated:
                                             # NUMBA_ENABLE_CUDASIM=1)

Prints one JSON line per figure: the draw (the core KK draw of ``benchmarks/run_all.py``,
or its general exponents in [1, 3]), the size, the knob (``tol`` or ``steps``), points/s
on the GPU (compilation excluded: printed once as ``compile_s``), points/s of the CPU
backend on every core of the same machine (on the first ``--cpu-n`` points of the draw),
the max abs error of the GPU's e against DOP853 on 1,000 points of the draw (the test
suite's reference, cached in ``benchmarks/.cache``) and the largest difference between
the GPU's and the CPU's e on the CPU's points.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

import run_all  # noqa: E402 -- the draws and the cached DOP853 reference

import sweep  # noqa: E402
from sweep.kernels import cuda as kc  # noqa: E402

KNOBS = ({"tol": 1e-6}, {"tol": 1e-8}, {"tol": 1e-10}, {"steps": 32.0}, {"steps": 96.0})


def device_name() -> str:
    from numba import cuda  # noqa: PLC0415

    if os.environ.get("NUMBA_ENABLE_CUDASIM", "") not in ("", "0"):
        return "CUDA simulator"
    name = cuda.get_current_device().name
    return name.decode() if isinstance(name, bytes) else str(name)


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def figure(law, n, knob, args, machine):
    a, b, g, G = run_all.draw(n, law)
    gpu_s, gpu = timed(lambda: sweep.integrate(a, b, g, G, device="cuda", **knob))
    m = min(args.cpu_n, n)
    cpu_s, cpu = timed(lambda: sweep.integrate(a[:m], b[:m], g[:m], G[:m], **knob))
    idx = np.random.default_rng(1).choice(n, size=min(args.check, n), replace=False)
    ref = run_all.reference_e(np.column_stack([a[idx], b[idx], g[idx], G[idx]]),
                              args.cache_dir)
    err = np.abs(np.asarray(gpu.e)[idx] - ref)
    diff = np.abs(np.asarray(gpu.e)[:m] - np.asarray(cpu.e))
    return {"law": law, "n": n, **knob, "gpu_points_per_s": round(n / gpu_s),
            "cpu_points_per_s": round(m / cpu_s), "cpu_n": m,
            "max_abs_error": float(np.nanmax(err)), "median_abs_error": float(np.nanmedian(err)),
            "max_gpu_cpu_diff": float(np.nanmax(diff)),
            "gpu_cpu_identical": float(np.mean(diff == 0)),
            "mean_steps": float(np.mean(gpu.n_steps)), **machine}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[1_000_000, 16_000_000])
    p.add_argument("--cpu-n", type=int, default=500_000,
                   help="points the CPU backend integrates for its rate and the comparison")
    p.add_argument("--check", type=int, default=1000, help="points checked against DOP853")
    p.add_argument("--cache-dir", default=str(HERE / ".cache"))
    p.add_argument("--quick", action="store_true", help="tiny sizes: the machinery only")
    args = p.parse_args(argv)
    if args.quick:
        args.sizes, args.cpu_n, args.check = [512], 512, 20
    why = kc.device_error()
    if why is not None:
        print(f"gpu.py: {why}", file=sys.stderr)
        return 1
    import numba  # noqa: PLC0415

    machine = {"device": device_name(), "cpu": platform.processor() or platform.machine(),
               "cores": os.cpu_count(), "cpu_threads": numba.get_num_threads()}
    compile_s, _ = timed(lambda: sweep.integrate(1.5, 1.5, np.full(256, 0.1), 0.1,
                                                 device="cuda"))
    print(json.dumps({"compile_s": round(compile_s, 2), **machine}), flush=True)
    for law in ("kk", "general"):
        for n in args.sizes if law == "kk" else args.sizes[:1]:
            for knob in KNOBS if law == "kk" else KNOBS[:3]:
                print(json.dumps(figure(law, n, knob, args, machine)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
