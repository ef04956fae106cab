"""The CUDA backend (``device="cuda"``, sweep/kernels/cuda.py) without a GPU.

* numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``, in a subprocess: numba reads it at
  import) runs the real kernel -- its indexing, chunking over two streams, pinned buffers
  and field mapping -- on a few hundred points: random points of every law and hard cases
  of ``tests/data/hard_cases.csv``. The simulator executes the kernel's Python with the
  CPU-compiled device functions, so there it must agree with the CPU backend bit for bit,
  and with the hard cases' extended-precision references as the CPU does.
* Without the simulator and without a GPU, ``device="cuda"`` is a one-line error, in the
  API and in ``sweep run`` (before anything is written).
* Where numba-cuda and its NVVM library are installed (``pip install ".[cuda]"``), the
  kernel with every shared device function is compiled to PTX (no GPU needed).
"""
from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
import textwrap
import types

import numpy as np
import pytest

import sweep
from sweep.kernels import cuda as kc

HERE = os.path.dirname(os.path.abspath(__file__))

SIM_SCRIPT = textwrap.dedent("""
    import csv, json, sys
    import numpy as np
    import sweep
    from sweep.kernels import cuda as kc
    from sweep.kernels.integrator import settings

    rng = np.random.default_rng(3)
    n = 240
    a = rng.choice([1.0, 1.5, 2.0, 2.5], n); a[:60] = rng.uniform(1, 4, 60)
    b = rng.choice([1.0, 1.25, 1.5, 2.5], n); b[:60] = rng.uniform(1, 4, 60)
    g = 10 ** rng.uniform(-5, 1.5, n)
    gt = np.where(rng.random(n) < 0.2, 0.0, 10 ** rng.uniform(-3, 2.5, n))
    rows = list(csv.DictReader(open(sys.argv[1])))
    pick = [rows[i] for i in np.random.default_rng(4).choice(len(rows), 120, replace=False)]
    hard = {k: np.array([float(r[k]) for r in pick]) for k in
            ("alpha", "beta", "gamma", "gtilde", "e_ref", "bound")}
    A = np.concatenate([a, hard["alpha"]]); B = np.concatenate([b, hard["beta"]])
    G = np.concatenate([g, hard["gamma"]]); GT = np.concatenate([gt, hard["gtilde"]])
    out = {"error": kc.device_error()}
    cpu = sweep.integrate(A, B, G, GT)
    gpu = sweep.integrate(A, B, G, GT, device="cuda")
    fields = ("e", "t_f", "u_max", "n_steps", "status", "e_err", "sticks")
    out["same"] = {f: bool(np.array_equal(np.asarray(getattr(cpu, f)),
                                          np.asarray(getattr(gpu, f)), equal_nan=True))
                   for f in fields}
    chunked = kc.integrate_arrays_cuda(A, B, G, GT, settings(tol=1e-8), chunk=37)
    ref = sweep.integrate(A, B, G, GT, tol=1e-8)
    out["chunked_same"] = all(np.array_equal(chunked[k], np.asarray(getattr(ref, k)),
                                             equal_nan=True) for k in chunked)
    err = np.abs(np.asarray(gpu.e)[n:] - hard["e_ref"]) - hard["bound"]
    out["hard_max_excess"] = float(np.max(err))
    out["scalar"] = sweep.cor(1.5, 1.5, 0.05, 1.0, device="cuda") == sweep.cor(1.5, 1.5, 0.05, 1.0)
    out["empty"] = sweep.integrate(1.5, 1.5, np.array([]), 0.1, device="cuda").e.shape == (0,)
    cfg = {"design": {"kind": "grid", "alpha": 1.5, "beta": 1.5,
                      "gamma": {"start": 1e-3, "stop": 1.0, "num": 7, "spacing": "log"},
                      "gtilde": [0.0, 0.5, 5.0]},
           "outputs": {"e": ["numeric", "auto"], "fields": ["e_err", "status"]}}
    ds_cpu = sweep.run(cfg, quiet=True)
    ds_gpu = sweep.run(dict(cfg, integrator={"device": "cuda"}), quiet=True)
    out["run_same"] = all(bool(np.array_equal(ds_cpu[v].values, ds_gpu[v].values, equal_nan=True))
                          for v in ("e_numeric", "e_auto", "e_err", "status"))
    out["run_device_attr"] = ds_gpu.attrs.get("integrator_device")
    print(json.dumps(out))
""")


def _run_simulated(script, *args, timeout=600):
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    proc = subprocess.run([sys.executable, "-c", script, *args], capture_output=True,
                          text=True, env=env, timeout=timeout)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def simulated():
    """The simulator run (one subprocess: compiling the device function once)."""
    return _run_simulated(SIM_SCRIPT, os.path.join(HERE, "data", "hard_cases.csv"))


def test_simulator_is_usable(simulated):
    assert simulated["error"] is None


def test_simulated_kernel_equals_the_cpu_kernel(simulated):
    assert all(simulated["same"].values()), simulated["same"]
    assert simulated["scalar"] and simulated["empty"]


def test_a_sweep_on_the_device_equals_the_cpu_sweep(simulated):
    # integrator.device = "cuda" reaches the integrated points of "numeric" and "auto",
    # and the dataset says where it ran.
    assert simulated["run_same"] and simulated["run_device_attr"] == "cuda"


def test_chunks_over_two_streams_equal_one_cpu_call(simulated):
    # 360 points in chunks of 37: ten chunks, the two streams alternating, a short last one.
    assert simulated["chunked_same"]


def test_hard_cases_on_the_device_within_the_target(simulated):
    # The hard cases' own extended-precision references, as tests/test_hard_cases.py.
    assert simulated["hard_max_excess"] <= 1e-9


def _naive_work_order(a, b, g, gt):
    """work_order's documented rule spelled out with numpy: a stable sort by the buckets
    of gamma, g~, alpha, beta; a bucket is 0 for zero, else 1 + floor((code - lowest) * n
    / (highest - lowest + 1)), the code being a double's exponent and four leading mantissa
    bits."""
    keys = []
    for x, nb in zip((g, gt, a, b), kc.ORDER_BUCKETS):
        pos = x > 0
        code = x.view(np.int64) >> 48
        lo, hi = code[pos].min(), code[pos].max()
        keys.append(np.where(pos, 1 + np.floor((code - lo) * (nb / (hi - lo + 1.0))), 0))
    return np.lexsort(keys[::-1])


@pytest.mark.parametrize("seed", [0, 1])
def test_work_order_groups_points_of_similar_parameters(seed):
    rng = np.random.default_rng(seed)
    n = 20_000
    a, b = rng.choice([1.5, 2.0], n), rng.uniform(1, 3, n)
    g, gt = 10 ** rng.uniform(-4, -0.5, n), 10 ** rng.uniform(-3, 1, n)
    gt[rng.random(n) < 0.1] = 0.0
    order = kc.work_order(a, b, g, gt)
    assert order.dtype == np.int32 and np.array_equal(np.sort(order), np.arange(n))
    assert np.array_equal(order, _naive_work_order(a, b, g, gt))
    # Neighbours in the order are close in gamma: 64 buckets over 3.5 decades.
    assert np.mean(np.abs(np.diff(np.log10(g[order]))) < 0.06) > 0.99


def test_work_order_refuses_what_it_would_write_or_read_past():
    a = np.full(5, 1.5)
    with pytest.raises(ValueError, match="out must be an int32 array of shape"):
        kc.work_order(a, a, a, a, out=np.zeros(3, np.int32))
    with pytest.raises(ValueError, match="out must be an int32"):
        kc.work_order(a, a, a, a, out=np.zeros(5, np.int64))
    with pytest.raises(ValueError, match=r"beta\) \[5, 5, 5, 4\]"):
        kc.work_order(a, a[:4], a, a)


def test_work_order_of_no_and_of_equal_points():
    assert kc.work_order(*(np.empty(0),) * 4).size == 0
    same = np.full(5, 1.5)
    assert list(kc.work_order(same, same, np.zeros(5), same)) == [0, 1, 2, 3, 4]


def _has_gpu():
    return kc.device_error() is None


@pytest.mark.skipif(os.environ.get("NUMBA_ENABLE_CUDASIM", "") not in ("", "0"),
                    reason="the simulator stands in for a GPU")
def test_no_gpu_is_a_one_line_error():
    if _has_gpu():
        pytest.skip("a CUDA GPU is present")
    with pytest.raises(RuntimeError) as info:
        sweep.integrate(1.5, 1.5, 0.1, 0.1, device="cuda")
    msg = str(info.value)
    assert msg.startswith("device='cuda': ") and "\n" not in msg


def test_device_is_validated():
    with pytest.raises(ValueError, match="device must be .*'gpu'"):
        sweep.integrate(1.5, 1.5, 0.1, 0.1, device="gpu")
    with pytest.raises(ValueError, match="device"):
        sweep.cor(1.5, 1.5, 0.1, 0.1, device=3)


def test_sweep_run_on_a_missing_gpu_is_refused_before_writing(tmp_path):
    if _has_gpu():
        pytest.skip("a CUDA GPU is present")
    cfg = tmp_path / "gpu.toml"
    cfg.write_text('[design]\nkind = "grid"\nalpha = 1.5\nbeta = 1.5\ngamma = [0.01, 0.1]\n'
                   'gtilde = 0.1\n[outputs]\ne = ["numeric"]\n[integrator]\ndevice = "cuda"\n')
    out = tmp_path / "gpu.nc"
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    proc = subprocess.run([sys.executable, "-m", "sweep", "run", str(cfg), "-o", str(out)],
                          capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert 'integrator.device = "cuda"' in lines[-1] and "Traceback" not in proc.stderr
    assert not out.exists() and list(tmp_path.iterdir()) == [cfg]


def _real_gpu():
    return os.environ.get("NUMBA_ENABLE_CUDASIM", "") in ("", "0") and _has_gpu()


def _agreement_points(n=2000):
    """Random points of every law (as SIM_SCRIPT, larger) and every hard case."""
    rng = np.random.default_rng(5)
    a = rng.choice([1.0, 1.5, 2.0, 2.5], n); a[:n // 4] = rng.uniform(1, 4, n // 4)
    b = rng.choice([1.0, 1.25, 1.5, 2.5], n); b[:n // 4] = rng.uniform(1, 4, n // 4)
    g = 10 ** rng.uniform(-5, 1.5, n)
    gt = np.where(rng.random(n) < 0.2, 0.0, 10 ** rng.uniform(-3, 2.5, n))
    with open(os.path.join(HERE, "data", "hard_cases.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    hard = [np.array([float(r[k]) for r in rows]) for k in ("alpha", "beta", "gamma", "gtilde")]
    return [np.concatenate([x, y]) for x, y in zip((a, b, g, gt), hard)], n


@pytest.mark.skipif(not _real_gpu(), reason="needs a CUDA GPU (the simulator is bit-identical)")
@pytest.mark.parametrize("knob", [{}, {"tol": 1e-8}])
def test_a_real_gpu_agrees_with_the_cpu(knob):
    """On hardware e agrees with the CPU's to 1e-12, except where the integrator amplifies
    rounding: there (a few points at most) the difference stays within the points' e_err
    (sweep/kernels/cuda.py says why the two cannot be bit-identical)."""
    params, n = _agreement_points()
    cpu = sweep.integrate(*params, **knob)
    gpu = sweep.integrate(*params, device="cuda", **knob)
    ec, eg = np.asarray(cpu.e), np.asarray(gpu.e)
    diff = np.where(ec == eg, 0.0, np.abs(eg - ec))
    bound = np.maximum(1e-12, np.maximum(np.asarray(cpu.e_err), np.asarray(gpu.e_err)))
    assert np.all(diff <= bound), np.flatnonzero(~(diff <= bound))[:5]
    close = diff <= 1e-12
    # H200: 100% of the random points, 95.7-97.1% of the hard cases (docs/speed/gpu.md)
    assert np.mean(close[:n]) >= 0.99 and np.mean(close[n:]) >= 0.9
    assert np.mean(np.asarray(cpu.status) == np.asarray(gpu.status)) >= 0.99


def test_kernel_compiles_to_ptx(monkeypatch):
    """Every device function the kernel shares with the CPU compiles for the GPU."""
    pytest.importorskip("numba_cuda", reason="numba-cuda not installed (pip install '.[cuda]')")
    from numba.cuda import dispatcher  # noqa: PLC0415
    try:
        from numba.cuda.cudadrv.libs import get_libdevice  # noqa: PLC0415
        get_libdevice()
    except Exception as exc:  # noqa: BLE001 -- no NVVM / libdevice: nothing to compile with
        pytest.skip(f"no CUDA NVVM library: {exc}")
    if not _has_gpu():
        # numba-cuda asks the current device for its compute capability when it compiles
        # a device function: answer for it.
        monkeypatch.setattr(dispatcher, "get_current_device",
                            lambda: types.SimpleNamespace(compute_capability=(8, 0)))
    code = kc.ptx((8, 0))
    assert ".entry" in code and "_solve" in code
    # Thread-local stage arrays (2 x 7 x 3 + 2 x 5 doubles), not global memory.
    assert ".local" in code


def test_gpu_benchmark_machinery_in_the_simulator(tmp_path):
    """benchmarks/gpu.py --quick: one JSON line per figure, errors against DOP853 sane,
    the simulated device agreeing with the CPU exactly (the values of a quick run mean
    nothing else)."""
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    proc = subprocess.run([sys.executable, os.path.join(HERE, "..", "benchmarks", "gpu.py"),
                           "--quick", "--cache-dir", str(tmp_path)], capture_output=True,
                          text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = [json.loads(x) for x in proc.stdout.splitlines()]
    assert "compile_s" in lines[0] and lines[0]["device"] == "CUDA simulator"
    checks = [x for x in lines[1:] if "agreement" in x]
    assert [(x["agreement"], x.get("tol")) for x in checks] == [
        ("random", None), ("random", 1e-8), ("hard_cases", None), ("hard_cases", 1e-8)]
    for x in checks:    # the simulator runs the CPU's compiled device functions
        assert x["n"] == 40 and x["all_fields_identical"] == 1.0 and x["worst"] == []
    figures = [x for x in lines[1:] if "law" in x]
    assert [(x["law"], x.get("tol", x.get("steps"))) for x in figures] == (
        [("kk", k) for k in (1e-6, 1e-8, 1e-10, 32.0, 96.0)]
        + [("general", k) for k in (1e-6, 1e-8, 1e-10)])
    for x in figures:
        assert x["max_gpu_cpu_diff"] == 0.0 and x["gpu_points_per_s"] > 0
        if "tol" in x:
            assert x["max_abs_error"] <= x["tol"]


def test_device_kernel_cache_is_keyed_on_the_kernel_sources():
    """numba-cuda keeps its own cache configuration: the kernel's cache must still live
    under the source-hash directory (numba's own check sees only cuda.py's time stamp)."""
    pytest.importorskip("numba_cuda", reason="numba-cuda not installed (pip install '.[cuda]')")
    if os.environ.get("NUMBA_ENABLE_CUDASIM", "") not in ("", "0"):
        pytest.skip("the simulator does not cache")
    from sweep.kernels import _jit  # noqa: PLC0415

    kernel = kc._kernel()
    assert str(kernel._cache._cache_path).startswith(str(_jit.cache_dir()))
