"""The numerical CoR on one CUDA device: the CPU's per-point solve, compiled for the GPU.

One source of truth: the kernel below is a thin loop body around
:func:`sweep.kernels.integrator.solve_point` -- the same tableau, contact law, step-size
rule, events, energy-balance decision, creep rules and refinement as the CPU kernels.
numba-cuda compiles every ``@jit`` function that a CUDA kernel calls as a device function
(with the same inlining options), so no line of the physics is written twice. One thread
integrates one point; its stage arrays live in thread-local memory.

Runs larger than a chunk (:data:`CHUNK`, fewer where the device has less free memory) are
split; each chunk's inputs are copied to the device, integrated and copied back on one of
two CUDA streams, through pinned host buffers, so that one chunk's transfers overlap the
other's compute.

**Work order.** A warp runs as long as its slowest thread and serialises the branches its
threads take apart, and the work of a point follows its parameters (damping, load,
exponents). Each chunk is therefore integrated in an order that puts points of similar
parameters side by side (:func:`work_order`, a counting sort on coarse log buckets, on the
host while the other stream computes); the kernel reads and writes each point at its own
index, so the order changes no result (measured in docs/speed/gpu.md: 2.6 times the
points/s on 4,000,000 KK points when the order costs nothing).

**Agreement with the CPU.** The arithmetic is the same; the results are not bit-identical,
for two reasons that no option of numba-cuda removes: NVVM contracts ``a * b + c`` into
fused multiply-adds where LLVM on the CPU may pick other pairs or none (the CPU kernels
allow contraction too, :data:`sweep.kernels._jit.FLAGS`), and CUDA's libdevice
``pow``/``exp``/``log`` may differ from the C library's in the last bit, and from glibc's
vector functions (libmvec, within 4 ulp), which the CPU takes for general exponents'
stages and the second-order quadrature (:mod:`sweep.kernels.vmath`; ``sqrt`` and
division are correctly rounded on both). Both change e by a few ulp on ordinary points;
where the integrator amplifies rounding (near the stick/rebound boundary, by about 1/e)
the difference stays within ``e_err``, and a point whose indicator sits right at the
refinement target may be refined on one device and not the other. How far apart the two
are on hardware, point by point, is measured in docs/speed/gpu.md (``python
benchmarks/gpu.py``'s agreement lines).

Without a GPU, ``NUMBA_ENABLE_CUDASIM=1`` runs the same kernel in numba's CUDA simulator
(slowly; the tests use it).

Owns: the CUDA kernel, the device check, chunked transfers, the work order. May import:
integrator, stepper, registry, _jit (numba-cuda only when called).
"""
from __future__ import annotations

import functools
import math
import os

import numpy as np
from numba import float64

from sweep.kernels._jit import cached_jit, kernel_cache
from sweep.kernels.integrator import Settings, solve_point
from sweep.kernels.stepper import N_DENSE, N_STAGES
from sweep.registry import kernel_fields

__all__ = ["device_error", "integrate_arrays_cuda", "solve_one", "ptx", "work_order",
           "CHUNK", "THREADS_PER_BLOCK", "ORDER_BUCKETS"]

#: Points per chunk at most (:data:`_BYTES_PER_POINT` of device memory a point, twice for
#: two streams). Small enough that the host's part of a chunk (its work order, the pinned
#: copies) overlaps the other stream's kernel (chunk sizes measured in docs/speed/gpu.md).
CHUNK = 1 << 19
#: Threads per block. The solve takes about 250 registers a thread (255 at most on any
#: device, so 256 threads always fit a block's 64K registers). On an H200, 256 against 128
#: ran general exponents 17% faster and KK within the noise (docs/speed/gpu.md).
THREADS_PER_BLOCK = 256
_BYTES_PER_POINT = 4 * 8 + 4 + sum(f.dtype.itemsize for f in kernel_fields())
#: Buckets of gamma, g~, alpha and beta in :func:`work_order` (most for what moves the work
#: most: the damping).
ORDER_BUCKETS = (64, 32, 8, 8)


def _simulated() -> bool:
    return os.environ.get("NUMBA_ENABLE_CUDASIM", "") not in ("", "0")


def _cuda():
    """numba-cuda's ``cuda`` module, or a one-line reason why it cannot be used."""
    try:
        from numba import cuda  # noqa: PLC0415 -- optional, imported only when asked for
    except Exception as exc:  # e.g. numba-cuda built against another numpy
        return None, (f"numba-cuda could not be imported with numpy {np.__version__} "
                      f"({type(exc).__name__}: {exc}); install the extra: "
                      f"pip install 'sweep[cuda]'")
    return cuda, None


def device_error() -> str | None:
    """None if ``device="cuda"`` can run here, otherwise why not (one line)."""
    cuda, why = _cuda()
    if cuda is None:
        return why
    if _simulated():
        return None
    try:
        if cuda.is_available():
            return None
    except Exception as exc:  # a broken driver install raises instead of answering
        return f"the CUDA driver failed to initialise ({type(exc).__name__}: {exc})"
    return ("no CUDA GPU or driver found (numba-cuda's cuda.is_available() is False); "
            "use device='cpu', or run where an NVIDIA GPU and its driver are installed")


@cached_jit()
def solve_one(alpha, beta, gamma, gtilde, steps, rest_tol, max_steps, target, from_tol, K,
              K2, Q):
    """:func:`solve_point` with the settings as scalars (kernel arguments). Compiled as a
    device function inside the CUDA kernel; cached on disk for the CUDA simulator, which
    calls it from Python (a fresh compile there costs a minute)."""
    return solve_point(alpha, beta, gamma, gtilde,
                       Settings(steps, rest_tol, max_steps, target, from_tol), K, K2, Q)


@cached_jit()
def _code_ranges(params, bits):
    """(lowest, highest) code of each array of ``params`` over its positive entries; the
    code of x > 0 (``bits``: x's bits as int64) is its exponent and four leading mantissa
    bits (about 16 log2(x), monotone)."""
    lo = np.full(len(params), np.int64(1) << 62)
    hi = np.full(len(params), np.int64(-1))
    for k in range(len(params)):
        for i in range(params[k].size):
            if params[k][i] > 0.0:
                lo[k], hi[k] = min(lo[k], bits[k][i] >> 48), max(hi[k], bits[k][i] >> 48)
    return lo, hi


@cached_jit()
def _sorted_by_buckets(params, bits, n_buckets, order):
    """``order`` = the stable order of the points (``params``: a tuple of equal-length
    arrays) by their buckets (:func:`work_order`), by a counting sort in O(n)."""
    lo, hi = _code_ranges(params, bits)
    scale = n_buckets / (hi - lo + 1.0)
    n_keys = 1
    for k in range(n_buckets.size):
        n_keys *= n_buckets[k] + 1
    start = np.zeros(n_keys + 1, dtype=np.int64)
    keys = np.empty(params[0].size, dtype=np.int64)
    for i in range(keys.size):
        key = 0
        for k in range(len(params)):
            b = 0
            if params[k][i] > 0.0:
                b = 1 + int(((bits[k][i] >> 48) - lo[k]) * scale[k])
            key = key * (n_buckets[k] + 1) + b
        keys[i] = key
        start[key + 1] += 1
    for k in range(n_keys):
        start[k + 1] += start[k]
    for i in range(keys.size):
        order[start[keys[i]]] = i
        start[keys[i]] += 1


def work_order(alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray, gtilde: np.ndarray,
               out: np.ndarray | None = None) -> np.ndarray:
    """An order of the points that puts points of similar work side by side.

    The points sorted (stably) by the bucket of gamma, then of g~, alpha and beta: 0 for
    zero, else ``1 + floor((code - lowest) * n / (highest - lowest + 1))`` with ``n`` from
    :data:`ORDER_BUCKETS` and ``code`` about 16 log2 of the parameter (its exponent and four
    leading mantissa bits), its range taken over these points. Any order gives the same
    results; this one keeps a warp's threads on similar paths through the integrator.

    Parameters
    ----------
    alpha, beta, gamma, gtilde : ndarray of float64
        Flat arrays of equal length (scaled parameters of eq. (2)).
    out : ndarray of int32, optional
        Where to write the order (e.g. a pinned host buffer).

    Returns
    -------
    ndarray of int32
        A permutation of ``range(len(alpha))``.

    Raises
    ------
    ValueError
        Arrays of unequal lengths, 2^31 points or more, or an ``out`` that is not a 1-d
        int32 array of their length (the sort writes unchecked).
    """
    params = tuple(np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
                   for x in (gamma, gtilde, alpha, beta))
    n = params[0].size
    if any(x.size != n for x in params) or n >= 2 ** 31:
        raise ValueError(f"work_order needs four arrays of one length below 2**31, got "
                         f"lengths (gamma, g~, alpha, beta) {[x.size for x in params]}")
    order = np.empty(n, dtype=np.int32) if out is None else out
    if not (isinstance(order, np.ndarray) and order.dtype == np.int32
            and order.shape == (n,)):
        raise ValueError(f"work_order's out must be an int32 array of shape ({n},), got "
                         f"{getattr(order, 'dtype', type(order).__name__)} "
                         f"{getattr(order, 'shape', '')}")
    if n:
        _sorted_by_buckets(params, tuple(x.view(np.int64) for x in params),
                           np.array(ORDER_BUCKETS, dtype=np.int64), order)
    return order


#: numba-cuda's ``cuda`` module once :func:`_kernel` imported it (a module global, as the
#: CUDA simulator swaps it in the kernel's globals).
cuda = None


def _solve(order, alpha, beta, gamma, gtilde, steps, rest_tol, max_steps, target, from_tol,
           e, t_f, u_max, n_steps, status, e_err):
    """The kernel: thread ``i = cuda.grid(1)`` integrates point ``j = order[i]`` by
    :func:`solve_point` (one thread a point; :func:`work_order`)."""
    i = cuda.grid(1)
    if i < order.size:
        j = order[i]
        K = cuda.local.array((N_STAGES, 3), float64)
        K2 = cuda.local.array((N_STAGES, 3), float64)
        Q = cuda.local.array((2, N_DENSE), float64)
        r = solve_one(alpha[j], beta[j], gamma[j], gtilde[j], steps, rest_tol, max_steps,
                      target, from_tol, K, K2, Q)
        e[j] = r[0]
        t_f[j] = r[1]
        u_max[j] = r[2]
        n_steps[j] = r[3]
        status[j] = r[4]
        e_err[j] = r[5]


@functools.lru_cache(maxsize=None)
def _kernel():
    global cuda
    module, why = _cuda()
    if module is None:
        raise RuntimeError(why)
    cuda = module
    if _simulated():
        # The simulator calls solve_one from one Python thread per CUDA thread: compile it
        # (or load it from the cache) here first; from 128 threads at once it took 4x longer.
        stages = np.empty((N_STAGES, 3))
        solve_one(1.5, 1.5, 0.1, 0.1, 96.0, 1e-8, 10, 0.0, False, stages, stages.copy(),
                  np.empty((2, N_DENSE)))
    # Cached on disk beside the CPU kernels (keyed on the kernel sources; numba-cuda reads
    # numba's configuration when numba is installed, tests/test_cuda.py checks where):
    # NVVM takes tens of seconds for this kernel, once per machine and source version.
    with kernel_cache():
        return cuda.jit(_solve, cache=True)


def ptx(cc: tuple[int, int] = (8, 0)) -> str:
    """The kernel compiled to PTX for compute capability ``cc`` (a compile check: the shared
    device functions must compile for the GPU; needs numba-cuda and its NVVM library).

    Compiling the ``@jit`` functions the kernel calls asks numba-cuda for the current
    device's compute capability: without a GPU, patch
    ``numba.cuda.dispatcher.get_current_device`` (as ``tests/test_cuda.py`` does)."""
    _kernel()
    from numba import boolean, int8, int32, int64  # noqa: PLC0415

    a = float64[::1]
    sig = (int32[::1], a, a, a, a, float64, float64, int64, float64, boolean, a, a, a,
           int32[::1], int8[::1], a)
    code, _ = cuda.compile_ptx(_solve, sig, cc=cc)
    return code


def _chunk_size(n: int, chunk: int | None) -> int:
    if chunk is not None:
        return max(1, min(int(chunk), n))
    size = min(CHUNK, n)
    if not _simulated():
        free, _ = cuda.current_context().get_memory_info()
        # Two chunks in flight, and half the free memory left to the kernel's local memory.
        size = min(size, max(THREADS_PER_BLOCK, free // (4 * _BYTES_PER_POINT)))
    return max(1, size)


class _Slot:
    """One stream with its pinned host buffers and device arrays (one chunk in flight)."""

    def __init__(self, size: int) -> None:
        self.stream = cuda.stream()
        self.host_in = [cuda.pinned_array(size, dtype=np.float64) for _ in range(4)]
        self.dev_in = [cuda.device_array(size, dtype=np.float64, stream=self.stream)
                       for _ in range(4)]
        self.host_order = cuda.pinned_array(size, dtype=np.int32)
        self.dev_order = cuda.device_array(size, dtype=np.int32, stream=self.stream)
        fields = kernel_fields()
        self.host_out = [cuda.pinned_array(size, dtype=f.dtype) for f in fields]
        self.dev_out = [cuda.device_array(size, dtype=f.dtype, stream=self.stream)
                        for f in fields]
        self.pending = None     # (lo, hi) of the chunk in flight

    def launch(self, kernel, inputs, lo: int, hi: int, s: Settings) -> None:
        m = hi - lo
        for host, dev, x in zip(self.host_in, self.dev_in, inputs):
            host[:m] = x[lo:hi]
            dev[:m].copy_to_device(host[:m], stream=self.stream)
        work_order(*(h[:m] for h in self.host_in), out=self.host_order[:m])
        self.dev_order[:m].copy_to_device(self.host_order[:m], stream=self.stream)
        blocks = math.ceil(m / THREADS_PER_BLOCK)
        kernel[blocks, THREADS_PER_BLOCK, self.stream](
            self.dev_order[:m], *(d[:m] for d in self.dev_in), s.steps, s.rest_tol,
            s.max_steps, s.target, s.from_tol, *(d[:m] for d in self.dev_out))
        for host, dev in zip(self.host_out, self.dev_out):
            dev[:m].copy_to_host(host[:m], stream=self.stream)
        self.pending = (lo, hi)

    def collect(self, out: dict) -> None:
        if self.pending is None:
            return
        self.stream.synchronize()
        lo, hi = self.pending
        for f, host in zip(kernel_fields(), self.host_out):
            out[f.name][lo:hi] = host[:hi - lo]
        self.pending = None


def integrate_arrays_cuda(alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray,
                          gtilde: np.ndarray, s: Settings,
                          chunk: int | None = None) -> dict[str, np.ndarray]:
    """:func:`sweep.kernels.integrator.integrate_arrays` on the CUDA device.

    Parameters
    ----------
    alpha, beta, gamma, gtilde : ndarray of float64
        Flat arrays of equal length (scaled parameters of eq. (2)).
    s : Settings
        The integrator's settings (:func:`sweep.kernels.integrator.settings`).
    chunk : int, optional
        Points per chunk (default: :data:`CHUNK`, fewer if device memory is short).

    Returns
    -------
    dict of str -> ndarray
        One flat array per field of :func:`sweep.registry.kernel_fields`.

    Raises
    ------
    RuntimeError
        No usable CUDA device (the message says why, in one line).
    """
    why = device_error()
    if why is not None:
        raise RuntimeError(f"device='cuda': {why}")
    n = alpha.size
    out = {f.name: np.empty(n, dtype=f.dtype) for f in kernel_fields()}
    if n == 0:
        return out
    kernel = _kernel()          # and the module global cuda with it
    size = _chunk_size(n, chunk)
    inputs = [np.ascontiguousarray(x, dtype=np.float64) for x in (alpha, beta, gamma, gtilde)]
    slots = [_Slot(size) for _ in range(min(2, math.ceil(n / size)))]
    for k, lo in enumerate(range(0, n, size)):
        slot = slots[k % len(slots)]
        slot.collect(out)           # the chunk this stream ran before
        slot.launch(kernel, inputs, lo, min(n, lo + size), s)
    for slot in slots:
        slot.collect(out)
    return out
