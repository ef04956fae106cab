"""Serial kernels release the GIL: a Python thread keeps running while one computes."""
import threading
import time

import numpy as np

import sweep


def _count_while(fn):
    """Iterations of a pure-Python loop in another thread while ``fn`` runs."""
    stop = threading.Event()
    count = [0]

    def spin():
        while not stop.is_set():
            count[0] += 1

    t = threading.Thread(target=spin)
    t.start()
    try:
        fn()
    finally:
        stop.set()
        t.join()
    return count[0]


def test_serial_integration_lets_python_threads_run():
    rng = np.random.default_rng(0)
    g = 10 ** rng.uniform(-4, -0.5, 20000)
    gt = 10 ** rng.uniform(-3, 1, 20000)
    sweep.integrate(1.5, 1.5, g[:10], gt[:10], parallel=False)        # compiled
    t0 = time.perf_counter()
    alone = _count_while(lambda: time.sleep(0.3)) / 0.3               # the thread's speed
    t0 = time.perf_counter()
    during = _count_while(lambda: sweep.integrate(1.5, 1.5, g, gt, parallel=False))
    seconds = time.perf_counter() - t0
    # Holding the GIL starves the thread to a few percent of its speed (1.6% measured
    # before nogil); released, it keeps a large share even on a loaded 2-core machine.
    assert during / seconds > 0.1 * alone, (during / seconds, alone)
