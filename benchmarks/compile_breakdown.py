"""Where the first ``sweep.cor()``'s compile goes (fresh process, empty kernel cache).

    python benchmarks/compile_breakdown.py [--top 15] [--plain]

The start-up figure of issue 10 (``run_all.py --only startup_compile_fresh``) is mostly
this call. Run in a subprocess with a new ``NUMBA_CACHE_DIR``, it prints one JSON line:
the call's seconds; each compiled function's own seconds (numba's ``numba:compile`` events,
callees' compiles taken out of their callers'), the largest ``--top``; and the seconds of
the parts the package's compile-time patches aim at (``sweep/kernels/_jit.py``): numba's IR
post-processor (``PostProcessor.run``: use-def sets, live variables, dead maps, after nearly
every pass and inlined call site), ``add_ir_module`` (the LLVM IR text printed, parsed and
verified, then LLVM's function passes, which ``llvm_function_passes`` gives alone).
``--plain`` leaves the package's patches of numba out, to see what they save in the same
minutes (run both, interleaved: the machine's speed drifts by a quarter within an hour).
Timings only: nothing here is a test.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: Run in the fresh process: wraps the parts named in the module docstring with timers.
_PROBE = r"""
import collections, json, sys, time
from numba.core import codegen, event, postproc
if PLAIN:
    from sweep.kernels import _jit
    _jit._patch_numba = lambda: None
spent = collections.Counter()
def timed(owner, name, key):
    plain = getattr(owner, name)
    def wrapper(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return plain(*args, **kwargs)
        finally:
            spent[key] += time.perf_counter() - t0
    setattr(owner, name, wrapper)
timed(postproc.PostProcessor, "run", "ir_post_processor")
timed(codegen.CPUCodeLibrary, "_optimize_functions", "llvm_function_passes")
timed(codegen.CPUCodeLibrary, "add_ir_module", "llvm_ir_text_and_function_passes")
own, stack = collections.Counter(), []
class Listener(event.Listener):
    def on_start(self, ev):
        stack.append([time.perf_counter(), 0.0])
    def on_end(self, ev):
        t0, inner = stack.pop()
        dt = time.perf_counter() - t0
        if stack:
            stack[-1][1] += dt
        fn = getattr(ev.data.get("dispatcher"), "py_func", None)
        name = f"{fn.__module__}.{fn.__qualname__}" if fn is not None else "?"
        own[name] += dt - inner
event.register("numba:compile", Listener())
import sweep
t0 = time.perf_counter()
sweep.cor(1.5, 1.5, 0.01, 0.1)
out = {"first_cor_s": time.perf_counter() - t0, "patched": not PLAIN}
out.update({k: round(v, 3) for k, v in spent.items()})
out["own_s"] = {k: round(v, 3) for k, v in own.most_common(TOP)}
print(json.dumps(out))
"""


def breakdown(top: int, plain: bool) -> dict:
    """The JSON line of :data:`_PROBE` run in a fresh process with an empty cache."""
    code = _PROBE.replace("PLAIN", repr(plain)).replace("TOP", str(top))
    with tempfile.TemporaryDirectory(prefix="sweep-cache-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache,
               "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
        res = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, check=True,
                             capture_output=True, text=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--top", type=int, default=15, help="functions listed (default 15)")
    p.add_argument("--plain", action="store_true",
                   help="without the package's patches of numba's internals")
    args = p.parse_args(argv)
    print(json.dumps(breakdown(args.top, args.plain)))


if __name__ == "__main__":
    main()
