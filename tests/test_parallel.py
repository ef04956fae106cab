"""Array calls under numba's workqueue layer, made from several Python threads at once.

workqueue aborts the process when numba parallel regions are launched from several threads
at once. The front ends launch none (their thread pool runs serial ``nogil`` kernels) and
run serially off the main thread (like numbagg); results are identical to the main
thread's parallel ones.
"""
import os
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent("""
    import threading
    import numba
    import numpy as np
    import sweep

    rng = np.random.default_rng(0)
    n = 4000
    g = 10 ** rng.uniform(-4, -0.5, n)
    gt = 10 ** rng.uniform(-3, 1, n)
    expected = sweep.integrate(1.5, 1.5, g, gt, steps=24).e          # main thread: parallel
    approx = sweep.cor(1.5, 1.5, g, gt, method="ord2_approx")
    assert numba.threading_layer() == "workqueue", numba.threading_layer()
    results = {}

    def work(k):
        results[k] = (sweep.integrate(1.5, 1.5, g, gt, steps=24).e,
                      sweep.cor(1.5, 1.5, g, gt, method="ord2_approx"))

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(results) == 4
    for e, a in results.values():
        np.testing.assert_array_equal(e, expected)
        np.testing.assert_array_equal(a, approx)
    print("ok")
""")


def test_workqueue_falls_back_to_serial_in_threads():
    env = dict(os.environ, NUMBA_THREADING_LAYER="workqueue", NUMBA_NUM_THREADS="2")
    proc = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                          env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip().endswith("ok")
