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


# --- map_blocks' kept pool -------------------------------------------------------------

import multiprocessing  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from sweep.kernels import _parallel  # noqa: E402


def _blocks_seen(n, size, order):
    seen = []
    lock = threading.Lock()

    def run(lo, hi):
        with lock:
            seen.append((lo, hi))
    _parallel.map_blocks(run, [(j * size, min(n, (j + 1) * size)) for j in order])
    return sorted(seen)


def test_map_blocks_runs_every_block_once_whatever_the_thread_count():
    n, size = 1003, 100
    expected = [(lo, min(n, lo + size)) for lo in range(0, n, size)]
    before = numba.get_num_threads()
    try:
        for t in (numba.config.NUMBA_NUM_THREADS, 1, numba.config.NUMBA_NUM_THREADS):
            numba.set_num_threads(t)
            assert _blocks_seen(n, size, reversed(range(len(expected)))) == expected
            if t > 1:   # the caller computes too: t - 1 helpers
                assert _parallel._POOL[1] == t - 1
    finally:
        numba.set_num_threads(before)


#: (n, size, smallest, seed) -> the blocks' sizes in their order on 2 threads: the last two
#: blocks a thread (four) in quarters, none below ``smallest``, the short last block alone.
SCHEDULES = {
    (65536, 1024, 256, 7): [1024] * 60 + [256] * 16,
    (1003, 100, 10, None): [100] * 7 + [25] * 12 + [3],
    (300, 100, 100, 3): [100, 100, 100],
}


@pytest.mark.parametrize("case", list(SCHEDULES))
def test_a_schedule_covers_every_point_once_and_ends_in_small_blocks(case):
    n, size, smallest, seed = case
    before = numba.get_num_threads()
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs 2 numba threads")
    try:
        numba.set_num_threads(2)
        bounds = _parallel.schedule(n, size, smallest, seed)
    finally:
        numba.set_num_threads(before)
    covered = np.zeros(n, dtype=int)
    for lo, hi in bounds:
        covered[lo:hi] += 1
    assert np.all(covered == 1)
    assert [hi - lo for lo, hi in bounds] == SCHEDULES[case]
    if seed is None:
        assert [lo for lo, _ in bounds] == sorted(lo for lo, _ in bounds)


def test_map_blocks_raises_the_first_error_once_no_block_still_runs():
    started, lock = [], threading.Lock()

    def run(lo, hi):
        with lock:
            started.append(lo)
        if lo == 0:
            raise ValueError("block 0")
        time.sleep(0.01)
    with pytest.raises(ValueError, match="block 0"):
        _parallel.map_blocks(run, [(j, j + 1) for j in range(200)])
    count = len(started)
    time.sleep(0.1)
    # Blocks not started were cancelled; none starts after the call returned.
    assert len(started) == count < 200


def test_map_blocks_stops_every_thread_when_the_callers_block_is_interrupted():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs 2 numba threads")
    started, lock = [], threading.Lock()

    def run(lo, hi):
        with lock:
            started.append(lo)
        time.sleep(0.005)
        if threading.current_thread() is threading.main_thread() and len(started) > 4:
            raise KeyboardInterrupt   # Ctrl-C lands in the caller, which computes too
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(2)
        with pytest.raises(KeyboardInterrupt):
            _parallel.map_blocks(run, [(j, j + 1) for j in range(400)])
    finally:
        numba.set_num_threads(before)
    count = len(started)
    time.sleep(0.1)
    assert len(started) == count < 400


def _child(queue):
    queue.put(_blocks_seen(30, 10, range(3)))


@pytest.mark.skipif(sys.platform != "linux", reason="fork start method")
def test_map_blocks_in_a_forked_child_gets_its_own_pool():
    _blocks_seen(30, 10, range(3))          # the parent's pool exists, its threads started
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    proc = ctx.Process(target=_child, args=(queue,))
    proc.start()
    try:
        # The inherited pool has no threads in the child: its blocks would never run.
        assert queue.get(timeout=60) == [(0, 10), (10, 20), (20, 30)]
    finally:
        proc.join(timeout=10)
        if proc.is_alive():
            proc.kill()
    assert proc.exitcode == 0
