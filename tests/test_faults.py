"""Injected faults: every one ends in the correct file or a clear one-line error, and
nothing finished is lost (issue 11).

Faults: a second writer (``--restart`` included, in real processes), a partial directory
without its manifest or that is a plain file, damaged chunk files, a damaged finished
output, a full disk, no free inode and a read-only target (on a small tmpfs, skipped where
the test cannot mount one), a full disk or a quota at one file (a patched ``open``), a
stderr that fails midway, a huge design, a bad scheduler address, bad inputs on the command
line (a chunk size beyond the range included), and signals at start-up and during the final
clean-up.
"""
import errno
import io
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import traceback
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import xarray as xr

from sweep import cli, store
from sweep.sweeps import config, design, limits, preflight, runner

ROOT = Path(__file__).resolve().parents[1]

GRID = """
title = "fault test"
[design]
kind = "grid"
alpha = 1.5
beta = [1.0, 1.5]
gamma = {start = 0.0, stop = 0.2, num = 9}
gtilde = [0.0, 0.05, 1.0, 10.0]
[outputs]
e = ["numeric", "ord1"]
fields = ["status"]
[integrator]
steps = 16
[run]
chunk_size = 10
"""
#: The same design with another gamma range: another configuration, same chunking.
OTHER = GRID.replace("stop = 0.2", "stop = 0.3")

#: Cheap (closed forms only), with a few hundred kB of per-point coordinates.
DOE = """
[design]
kind = "doe"
sampler = "sobol"
n = 40000
seed = 5
alpha = {min = 1.0, max = 3.0}
beta = {min = 1.0, max = 3.0}
gamma = {min = 1e-3, max = 0.5, scale = "log"}
gtilde = {min = 0.0, max = 10.0}
[outputs]
e = ["ord1"]
[run]
chunk_size = 4000
"""

VOLATILE = runner.VOLATILE_ATTRS


def run(text, path, **kw):
    kw.setdefault("quiet", True)
    return runner.run(config.loads(text, source="test.toml"), path, **kw)


def opened(path):
    with xr.open_dataset(path) as ds:
        ds = ds.load()
    for key in VOLATILE:
        ds.attrs.pop(key, None)     # compile_time_s is absent when every chunk was resumed
    return ds


def interrupt_after(monkeypatch, n_chunks):
    real = runner.compute_chunk
    count = [0]

    def compute(*args):
        if count[0] == n_chunks + 1:            # the first call is the warm-up
            raise KeyboardInterrupt
        count[0] += 1
        return real(*args)

    monkeypatch.setattr(runner, "compute_chunk", compute)


def interrupted(text, out, n_chunks, monkeypatch, **kw):
    """Run ``text`` into ``out`` until ``n_chunks`` chunks are saved, then interrupt."""
    with monkeypatch.context() as m:
        interrupt_after(m, n_chunks)
        with pytest.raises(KeyboardInterrupt):
            run(text, out, **kw)
    return store.partial_dir(out)


def snapshot(directory):
    return {p.name: p.read_bytes() for p in sorted(Path(directory).iterdir())}


def one_line_error(err, *parts):
    """stderr is exactly one line, with no traceback, naming every part."""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for part in parts:
        assert str(part) in lines[0], (part, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """Uninterrupted outputs to compare against, computed once."""
    d = tmp_path_factory.mktemp("reference")
    out = {}
    for name, text in (("grid", GRID), ("other", OTHER), ("doe", DOE)):
        run(text, d / f"{name}.nc")
        out[name] = opened(d / f"{name}.nc")
    return out


# --------------------------------------------------------------------------- the lock

def test_a_run_whose_lock_file_was_removed_publishes_nothing(tmp_path, monkeypatch, capsys,
                                                             reference):
    # Audit F: a lock file deleted as "stale" let a second run take the output; the first
    # then published the second's half-written file, exit 0.
    out = tmp_path / "out.nc"
    real, calls = runner.compute_chunk, [0]
    theirs = store.partial_dir(out) / "assembling.nc"

    def compute(*args):
        calls[0] += 1
        if calls[0] == 4:                       # the warm-up, then two chunks
            store.lock_path(out).unlink()
            store.OutputLock(out).acquire()     # another process's lock, never released
            theirs.unlink()                     # which replaced the assembled file
            theirs.write_bytes(b"the other run's")
        return real(*args)

    monkeypatch.setattr(runner, "compute_chunk", compute)
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    assert cli.main(["run", str(cfg), "-o", str(out), "--quiet"]) == 1
    one_line_error(capsys.readouterr().err, store.lock_path(out),
                   "was removed during the run", "not published")
    assert not out.exists() and theirs.read_bytes() == b"the other run's"
    monkeypatch.setattr(runner, "compute_chunk", real)
    store.lock_path(out).unlink()               # the other process is gone
    run(GRID, out)
    xr.testing.assert_identical(opened(out), reference["grid"])


def test_a_second_writer_is_refused_with_the_holders_pid_and_host(tmp_path):
    out = tmp_path / "out.nc"
    with store.OutputLock(out) as lock:
        info = json.loads(lock.path.read_text())
        assert info["pid"] == os.getpid() and info["host"] == socket.gethostname()
        with pytest.raises(store.LockError) as refused:
            store.OutputLock(out).acquire()
        msg = str(refused.value)
        assert f"PID {os.getpid()} on host {socket.gethostname()}" in msg and str(out) in msg
    assert not store.lock_path(out).exists()       # released and removed
    store.OutputLock(out).acquire().release()      # free again


def test_restart_under_someone_elses_lock_touches_nothing(tmp_path, monkeypatch, reference):
    out = tmp_path / "out.nc"
    run(GRID, out)
    before = out.read_bytes()
    partial = interrupted(OTHER, out, 3, monkeypatch, restart=True)
    saved = snapshot(partial)
    with store.OutputLock(out):                    # another run writes this output
        for restart in (True, False):
            with pytest.raises(store.LockError, match=f"PID {os.getpid()}"):
                run(OTHER, out, restart=restart)
    assert snapshot(partial) == saved and out.read_bytes() == before
    res = run(OTHER, out)                          # the lock is free: resume as usual
    assert res.resumed_chunks == 3
    xr.testing.assert_identical(opened(out), reference["other"])


#: Runs `sweep run` with a compute_chunk that waits, before its third chunk (the fourth call:
#: the first is the warm-up), until the file named by SWEEP_TEST_GATE exists: the test
#: decides when it goes on (no sleeps). The chunks are written in the main thread, so that
#: when it creates SWEEP_TEST_GATE + ".waiting" the files on disk are still.
GATED = """
import os, sys, time
import sweep.sweeps.runner as r
r.WRITE_BEHIND = r.SAVE_BEHIND = 0      # the partial state settled when the gate opens
real, count = r.compute_chunk, [0]
def gated(*a):
    if count[0] == 3:
        open(os.environ["SWEEP_TEST_GATE"] + ".waiting", "w").close()
        deadline = time.monotonic() + 120
        while not os.path.exists(os.environ["SWEEP_TEST_GATE"]):
            assert time.monotonic() < deadline, "the test never opened the gate"
            time.sleep(0.01)
    count[0] += 1
    return real(*a)
r.compute_chunk = gated
sys.argv = ["sweep"] + sys.argv[1:]
from sweep.cli import main
sys.exit(main())
"""


def test_concurrent_restart_in_another_process_is_refused(tmp_path, reference):
    cfg = tmp_path / "c.toml"
    cfg.write_text(DOE)
    out = tmp_path / "out.nc"
    gate = tmp_path / "gate"
    env = dict(os.environ, SWEEP_TEST_GATE=str(gate),
               PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    args = ["run", str(cfg), "-o", str(out), "--quiet"]
    first = subprocess.Popen([sys.executable, "-c", GATED] + args, env=env, cwd=tmp_path,
                             stderr=subprocess.PIPE, text=True)
    try:
        partial = store.partial_dir(out)
        deadline = time.monotonic() + 120
        while not Path(f"{gate}.waiting").exists():
            assert first.poll() is None, first.stderr.read()
            assert time.monotonic() < deadline
            time.sleep(0.01)
        saved = snapshot(partial)
        second = subprocess.run([sys.executable, "-m", "sweep.cli"] + args + ["--restart"],
                                env=env, cwd=tmp_path, capture_output=True, text=True,
                                timeout=120)
        assert second.returncode == 1
        one_line_error(second.stderr, "another sweep process", f"PID {first.pid}",
                       socket.gethostname(), out)
        assert snapshot(partial) == saved           # nothing deleted under the first run
        gate.touch()
        assert first.wait(timeout=120) == 0, first.stderr.read()
    finally:
        if first.poll() is None:
            first.kill()
    assert not partial.exists() and not store.lock_path(out).exists()
    result = opened(out)
    assert result.attrs["sweep_config"] == DOE
    xr.testing.assert_equal(result, reference["doe"])   # values; titles name other files


# --------------------------------------------------------------------------- untrusted state

def test_chunks_without_a_manifest_are_never_resumed(tmp_path, monkeypatch, reference):
    out = tmp_path / "out.nc"
    partial = interrupted(GRID, out, 4, monkeypatch)
    (partial / "manifest.json").unlink()           # e.g. kill -9 during the clean-up
    res = run(OTHER, out)                          # another gamma range
    assert (res.discarded_chunks, res.resumed_chunks, res.computed_points) == (4, 0, 72)
    xr.testing.assert_identical(opened(out), reference["other"])


def test_leftovers_of_an_interrupted_cleanup_never_replace_a_good_output(tmp_path,
                                                                        monkeypatch):
    out = tmp_path / "out.nc"
    run(GRID, out)
    before = out.read_bytes()
    partial = interrupted(GRID, out, 4, monkeypatch, restart=True)
    (partial / "manifest.json").unlink()
    with pytest.raises(store.ResumeError, match="different configuration"):
        run(OTHER, out)
    assert out.read_bytes() == before and not partial.exists()
    interrupted(GRID, out, 4, monkeypatch, restart=True)
    (partial / "manifest.json").unlink()
    assert run(GRID, out).up_to_date and not partial.exists()
    assert out.read_bytes() == before


@pytest.mark.parametrize("restart", [False, True])
def test_a_plain_file_in_place_of_the_partial_directory_is_named_and_kept(tmp_path, capsys,
                                                                         restart):
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    out = tmp_path / "out.nc"
    store.partial_dir(out).write_text("someone's notes")
    argv = ["run", str(cfg), "-o", str(out), "--quiet"] + ["--restart"] * restart
    assert cli.main(argv) == 1
    one_line_error(capsys.readouterr().err, store.partial_dir(out),
                   "not a run's partial directory", "-o")
    assert store.partial_dir(out).read_text() == "someone's notes" and not out.exists()


def test_a_damaged_output_is_not_up_to_date(tmp_path, capsys, reference):
    out = tmp_path / "out.nc"
    run(GRID, out)
    raw = bytearray(out.read_bytes())
    gamma = np.linspace(0.0, 0.2, 9).tobytes()
    at = raw.find(gamma) + len(gamma) // 2          # the middle of the stored gamma axis
    assert at > len(gamma) // 2 and raw.find(gamma, at) == -1
    raw[at:at + 8] = b"\xab" * 8
    out.write_bytes(bytes(raw))
    with pytest.raises(store.ResumeError, match="cannot be read.*damaged.*--restart"):
        run(GRID, out)                              # it said "up to date", exit 0
    assert out.read_bytes() == raw
    assert cli.main(["info", str(out)]) == 1
    one_line_error(capsys.readouterr().err, f"sweep info: error: cannot read {out}: ")
    run(GRID, out, restart=True)                    # what the message advises
    xr.testing.assert_identical(opened(out), reference["grid"])


def test_a_new_title_or_compression_keeps_the_chunks_a_new_value_is_named(tmp_path,
                                                                          monkeypatch):
    # Audit F: any edit refused the resume, even writing compress = "fast" (the default)
    # out, which the run's own hint suggests; the refusal showed two hashes.
    out = tmp_path / "out.nc"
    partial = interrupted(GRID, out, 4, monkeypatch)
    saved = snapshot(partial)
    edited = GRID.replace('title = "fault test"', 'title = "renamed"').replace(
        "chunk_size = 10", 'chunk_size = 10\ncompress = "none"').replace(
        "steps = 16", "steps = 16.0")                        # the same number
    res = run(edited, out)
    assert res.resumed_chunks == 4 and len(saved) == 5        # four chunks, the manifest
    fresh = tmp_path / "fresh.nc"
    run(edited, fresh)
    xr.testing.assert_identical(opened(out), opened(fresh))
    with xr.open_dataset(out) as ds:
        assert ds.attrs["title"] == "renamed" and not ds["e_numeric"].encoding.get("zlib")
    interrupted(GRID, out, 4, monkeypatch, restart=True)
    with pytest.raises(store.ResumeError, match=r"different configuration \(design\.gamma\."
                                                r"stop: 0\.2 there, 0\.3 now\)"):
        run(OTHER, out)


def _rewrite_chunk(path, change):
    """Rewrite a chunk file as a valid npz whose content ``change`` altered."""
    with np.load(path) as z:
        data = {k: z[k] for k in z.files}
    change(data)
    with open(path, "wb") as fh:
        np.savez(fh, **data)


def test_damaged_or_foreign_chunks_are_recomputed(tmp_path, monkeypatch, reference):
    out = tmp_path / "out.nc"
    partial = interrupted(GRID, out, 7, monkeypatch)
    chunk = [partial / f"chunk_{i:07d}.npz" for i in range(7)]
    raw = chunk[0].read_bytes()
    chunk[0].write_bytes(raw[:len(raw) // 2])                       # truncated
    raw = bytearray(chunk[1].read_bytes())
    with np.load(chunk[1]) as z:
        at = bytes(raw).find(z["e_numeric"][3:].tobytes())
    raw[at] ^= 0x10                                                  # one bit flipped
    chunk[1].write_bytes(bytes(raw))

    def flip_value(data):                    # silent corruption behind a valid container
        data["e_ord1"] = data["e_ord1"].copy()
        data["e_ord1"][0] += 1e-9

    _rewrite_chunk(chunk[2], flip_value)
    chunk[4].replace(chunk[3])                                       # misplaced
    foreign = store.PartialStore(tmp_path / "x.nc", {"config_sha256": "another",
                                                     "variables": ["e_numeric"]})
    with np.load(chunk[5]) as z:
        foreign.dir = partial                                        # from another run
        foreign.save_chunk(5, 50, 60, {k: z[k] for k in z.files if k != "__meta__"},
                           (1.0, 1.0))
    logged = []
    res = run(GRID, out, log=logged.append, quiet=False)
    assert (res.resumed_chunks, res.recomputed_chunks) == (1, 5)
    line = [m for m in logged if m.startswith("resume:")]
    assert line == ["resume: recomputed 5 saved chunks that failed verification (1 checksum "
                    "mismatch, 1 from another run, 1 misplaced, 2 unreadable)"]
    xr.testing.assert_identical(opened(out), reference["grid"])


def _source_hash_of(package_parent):
    """``runner.source_sha256()`` as a fresh interpreter computes it for the package
    found under ``package_parent``."""
    code = ("import sweep.sweeps.runner as r; print(r.__file__); "
            "print(r.source_sha256())")
    proc = subprocess.run([sys.executable, "-c", code], env=dict(
        os.environ, PYTHONPATH=str(package_parent)), cwd=package_parent,
        capture_output=True, text=True, timeout=300, check=True)
    where, digest = proc.stdout.split()
    assert Path(where).is_relative_to(package_parent)      # the copy, not this checkout
    return digest


def test_a_rebuilt_error_model_is_another_source(tmp_path):
    # `sweep report error-model` rewrites sweep/data/error_model.npz in place, and every
    # point of method = "auto" is served by what it says; the hash that resume and the
    # "up to date" check compare read the .py files only, so a run interrupted before a
    # rebuild resumed into a file mixing both models' choices (exit 0), and an output
    # made with the old model was called up to date.
    copy = _package_copy(tmp_path)
    before = _source_hash_of(copy)
    model = copy / "sweep" / "data" / "error_model.npz"
    with np.load(model) as z:
        data = {k: z[k] for k in z.files}
    data["bound"] = np.full_like(data["bound"], 127)       # no closed form anywhere
    np.savez(model, **data)
    assert _source_hash_of(copy) != before


def test_saved_chunks_of_other_points_are_recomputed(tmp_path, monkeypatch):
    # A design's points come from scipy's and numpy's samplers, whose sequences a new
    # version may change while the configuration, so the manifest, stays the same: the
    # resumed chunks kept the values of the old points, stored under the new points'
    # coordinates (exit 0).
    out = tmp_path / "out.nc"
    interrupted(DOE, out, 3, monkeypatch)
    real = design.DoEDesign.points

    def drifted(self, start, stop):               # another sampler's sequence
        alpha, beta, gamma, gtilde = real(self, start, stop)
        return alpha, beta, gamma * 0.5, gtilde

    monkeypatch.setattr(design.DoEDesign, "points", drifted)
    logged = []
    res = run(DOE, out, log=logged.append, quiet=False)
    assert (res.resumed_chunks, res.recomputed_chunks) == (0, 3)
    assert "resume: recomputed 3 saved chunks that failed verification (3 computed at " \
           "other points)" in logged
    run(DOE, tmp_path / "fresh.nc")
    xr.testing.assert_equal(opened(out), opened(tmp_path / "fresh.nc"))


# --------------------------------------------------------------------------- preflight

HUGE = GRID.replace("gamma = {start = 0.0, stop = 0.2, num = 9}",
                    "gamma = {start = 0.0, stop = 0.2, num = 1000000}").replace(
    "gtilde = [0.0, 0.05, 1.0, 10.0]", "gtilde = {start = 0.0, stop = 10.0, num = 1000000}")


def test_a_huge_design_is_refused_before_anything_is_allocated(tmp_path, monkeypatch,
                                                              capsys):
    def forbidden(*args, **kwargs):
        raise AssertionError("a refused design must not be generated or stored")

    monkeypatch.setattr(design.GridDesign, "points", forbidden)
    monkeypatch.setattr(store, "NetCDFWriter", forbidden)
    cfg = tmp_path / "huge.toml"
    cfg.write_text(HUGE)
    out = tmp_path / "huge.nc"
    assert cli.main(["run", str(cfg), "-o", str(out)]) == 1
    one_line_error(capsys.readouterr().err, "2,000,000,000,000 points",
                   f"{limits.MAX_POINTS:,}", "--force")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["huge.toml"]
    assert cli.main(["validate", str(cfg), "--no-estimate"]) == 1
    captured = capsys.readouterr()
    assert "points: 2,000,000,000,000 in 200,000,000,000 chunks of <= 10" in captured.out
    one_line_error(captured.err, "would refuse", "--max-points")
    # a limit of one's own, in bytes: the small grid is refused too
    assert cli.main(["run", str(cfg).replace("huge", "x"), "--max-size", "1k"]) == 1


def test_a_chunk_larger_than_memory_is_refused_before_the_run(tmp_path, monkeypatch,
                                                              capsys):
    # A chunk is computed whole in memory: --chunk-size 2147483648 on a large design
    # allocated until the OOM killer ended the run (SIGKILL, no message) or failed with
    # "unexpected MemoryError: Unable to allocate 2.00 MiB ...".
    monkeypatch.setattr(preflight, "physical_memory", lambda: 2 ** 20)   # a 1 MiB machine
    cfg = tmp_path / "c.toml"
    cfg.write_text(DOE)                    # 40,000 points of 8 B, 32 B of coordinates
    out = tmp_path / "out.nc"
    argv = ["run", str(cfg), "-o", str(out), "--quiet"]
    assert cli.main(argv + ["--chunk-size", "40000"]) == 1
    one_line_error(capsys.readouterr().err, "a chunk of 40,000 points", "memory",
                   "--chunk-size", "--force")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.toml"]
    assert cli.main(["validate", str(cfg), "--no-estimate", "--chunk-size", "40000"]) == 1
    assert "would refuse" in capsys.readouterr().err
    assert cli.main(argv) == 0                                 # its chunks of 4,000 fit


def test_the_chunk_list_is_lazy():
    chunks = design.Chunks(10 ** 12, 7)
    assert len(chunks) == -(-10 ** 12 // 7)
    assert chunks[0] == (0, 7) and chunks[-1] == (10 ** 12 - 10 ** 12 % 7, 10 ** 12)
    assert list(design.Chunks(10, 4)) == design.chunk_bounds(10, 4) == [(0, 4), (4, 8),
                                                                         (8, 10)]
    assert design.Chunks(10, 4)[1:] == [(4, 8), (8, 10)]
    with pytest.raises(ValueError, match=">= 1"):
        design.Chunks(10, 0)


def test_preflight_sizes_and_limits():
    cfg = config.loads(GRID)
    d = design.build(cfg.design)
    pre = runner.preflight(cfg, "/tmp/x.nc")
    assert (pre.n_points, pre.n_chunks, pre.value_bytes) == (72, 8, 8 + 8 + 1)
    assert pre.output_bytes == 72 * 17 + 8 * (1 + 2 + 9 + 4)
    assert pre.disk_needed == pre.output_bytes + 72 * 17 + 8 * limits.CHUNK_FILE_OVERHEAD
    assert pre.refusal(preflight.Limits()) is None
    assert "--max-points" in pre.refusal(preflight.Limits(max_points=71))
    assert "--max-size" in pre.refusal(preflight.Limits(max_bytes=100))
    assert "--chunk-size" in pre.refusal(preflight.Limits(max_chunks=7))
    rate, n = preflight.calibrate(d, lambda *p: None, seconds=0.01)
    assert rate > 0 and n == 72


def test_validate_prints_the_preflight_and_an_estimate(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    assert cli.main(["validate", str(cfg)]) == 0
    out = capsys.readouterr().out
    for part in ("points: 72 in 8 chunks of <= 10", "output: <= ", "disk: needs <= ",
                 "free", "estimated time: ", "points/s (calibration on 72 points)"):
        assert part in out, part
    run(GRID, tmp_path / "c.nc")           # the last run of this output gives the rate
    assert cli.main(["validate", str(cfg), "-o", str(tmp_path / "c.nc")]) == 0
    assert f"(last run of {tmp_path / 'c.nc'})" in capsys.readouterr().out


# --------------------------------------------------------------------------- the environment

@pytest.fixture
def tmpfs(tmp_path):
    """``mount(size, *options)`` mounts a fresh tmpfs; skips where that is not allowed."""
    mounted = []

    def mount(name, size, *options):
        if os.geteuid() != 0:
            pytest.skip("mounting a small tmpfs needs root")
        target = tmp_path / name
        target.mkdir()
        try:
            res = subprocess.run(["mount", "-t", "tmpfs", "-o", ",".join((f"size={size}",)
                                                                          + options),
                                  "tmpfs", str(target)], capture_output=True, text=True)
        except FileNotFoundError:
            pytest.skip("no mount command to make a small tmpfs")
        if res.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here: {res.stderr.strip()}")
        mounted.append(target)
        return target

    yield mount
    for target in reversed(mounted):
        subprocess.run(["umount", "-l", str(target)], capture_output=True)


def remount(target, *options):
    subprocess.run(["mount", "-o", ",".join(("remount",) + options), str(target)],
                   check=True, capture_output=True)


def test_too_little_free_disk_is_refused_before_starting(tmpfs):
    fs = tmpfs("small", "256k")
    with pytest.raises(runner.RunError, match=f"not enough free disk in {fs}") as info:
        run(DOE, fs / "out.nc")
    assert "--force" in str(info.value) and list(fs.iterdir()) == []


def test_a_full_disk_keeps_the_finished_chunks_and_resume_completes(tmpfs, reference):
    fs = tmpfs("full", "512k")
    out = fs / "out.nc"
    with pytest.raises(runner.RunError, match=f"no space left on the device of {fs}") as info:
        run(DOE, out, force=True)
    partial = store.partial_dir(out)
    saved = sorted(p.name for p in partial.iterdir())
    assert "finished chunks are kept" in str(info.value) and not out.exists()
    assert saved[-1] == "manifest.json" and len(saved) >= 2       # chunks, nothing else
    assert all(n.startswith("chunk_") and n.endswith(".npz") for n in saved[:-1])
    remount(fs, "size=8m")                                         # space freed
    res = run(DOE, out)
    assert res.resumed_chunks == len(saved) - 1
    xr.testing.assert_identical(opened(out), reference["doe"])


def test_a_read_only_target_is_a_clear_error_and_the_output_survives(tmpfs, capsys):
    fs = tmpfs("ro", "4m")
    out = fs / "out.nc"
    run(GRID, out)
    before = out.read_bytes()
    remount(fs, "ro")
    cfg = fs.parent / "other.toml"
    cfg.write_text(OTHER)
    assert cli.main(["run", str(cfg), "-o", str(out), "--restart", "--quiet"]) == 1
    one_line_error(capsys.readouterr().err, f"cannot write in {fs}", "Read-only file system")
    assert out.read_bytes() == before and sorted(os.listdir(fs)) == ["out.nc"]


def test_no_free_inode_is_said_so_not_permission_denied(tmpfs, capsys):
    # Four inodes: the root, the lock, the partial directory and its manifest; the
    # assembled file finds none (netCDF called that "Permission denied").
    fs = tmpfs("inodes", "4m", "nr_inodes=4")
    cfg = fs.parent / "c.toml"
    cfg.write_text(GRID)
    assert cli.main(["run", str(cfg), "-o", str(fs / "out.nc"), "--quiet"]) == 1
    line = one_line_error(capsys.readouterr().err, "no free inodes left on the device of",
                          store.partial_dir(fs / "out.nc"))
    assert "Permission denied" not in line


def _failing_open(monkeypatch, module, name, code):
    """``open`` in ``module`` as a full disk has it: a file whose name starts with ``name``
    is created, and its first write raises errno ``code`` as write(2) does (no file
    name)."""
    real = open

    class Refused(io.FileIO):
        def write(self, data):
            raise OSError(code, os.strerror(code))

    def fake(path, mode="r", *args, **kwargs):
        if Path(path).name.startswith(name):
            return Refused(path, mode.replace("b", ""))
        return real(path, mode, *args, **kwargs)

    monkeypatch.setattr(module, "open", fake, raising=False)


def test_a_full_disk_at_the_manifest_names_it(tmp_path, monkeypatch, capsys):
    from sweep.store import partial
    _failing_open(monkeypatch, partial, "manifest.json", errno.ENOSPC)
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    out = tmp_path / "out.nc"
    assert cli.main(["run", str(cfg), "-o", str(out), "--quiet"]) == 1
    one_line_error(capsys.readouterr().err, store.partial_dir(out) / "manifest.json",
                   "No space left on device")
    assert list(store.partial_dir(out).iterdir()) == []  # no temporary file left


def test_a_quota_at_the_assembled_file_is_called_a_quota(tmp_path, monkeypatch, capsys):
    from sweep.store import netcdf

    def over_quota(path, mode="r", *args, **kwargs):  # an inode quota refuses the create
        raise OSError(errno.EDQUOT, os.strerror(errno.EDQUOT), str(path))

    monkeypatch.setattr(netcdf, "open", over_quota, raising=False)
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    out = tmp_path / "out.nc"
    assert cli.main(["run", str(cfg), "-o", str(out), "--quiet"]) == 1
    one_line_error(capsys.readouterr().err, store.partial_dir(out) / "assembling.nc",
                   os.strerror(errno.EDQUOT), "kept")


@pytest.mark.parametrize("fault", ["interrupt", "full disk"])
def test_the_advice_after_a_failed_restart_resumes(tmp_path, monkeypatch, capsys, fault):
    # The same command again, --restart included, would discard the finished chunks.
    from sweep.store import partial
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    out = tmp_path / "out.nc"
    saved = store.PartialStore.save_chunk

    def save_then_fail(self, index, *args):
        saved(self, index, *args)
        if index == 2:
            _failing_open(monkeypatch, partial, "chunk_", errno.ENOSPC)

    if fault == "interrupt":
        interrupt_after(monkeypatch, 3)
    else:
        monkeypatch.setattr(store.PartialStore, "save_chunk", save_then_fail)
    status = cli.main(["run", str(cfg), "-o", str(out), "--restart"])
    assert status == (130 if fault == "interrupt" else 1)
    err = capsys.readouterr().err
    assert "rerun without --restart to resume" in err and "same command" not in err, err
    monkeypatch.undo()
    res = run(GRID, out)                           # what the advice says: it resumes
    assert res.resumed_chunks == 3


def _closed_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_an_unreachable_scheduler_fails_fast_naming_the_address(tmp_path):
    pytest.importorskip("distributed")
    address = f"tcp://127.0.0.1:{_closed_port()}"
    t0 = time.monotonic()
    with pytest.raises(runner.RunError, match=f"cannot reach the Dask scheduler at "
                                              f"'{address}'"):
        run(GRID, tmp_path / "out.nc", scheduler=address, scheduler_timeout=0.5)
    assert time.monotonic() - t0 < 20 and list(tmp_path.iterdir()) == []
    with pytest.raises(runner.RunError, match="'nonsense'"):
        run(GRID, tmp_path / "out.nc", scheduler="nonsense")


def test_a_failed_scheduler_connection_leaves_no_default_client(tmp_path):
    # distributed registers a Client as the process's default, and sets dask's scheduler
    # to it, before it connects; one that failed ("nonsense" fails parsing the address),
    # kept alive by its exception's traceback, then served every later dask compute in the
    # process, which waited on it for ever (a CI run hung so, in the README's notebook
    # example). The runner's client is never the default: it submits to it explicitly.
    distributed = pytest.importorskip("distributed")
    import dask
    for address in ("nonsense", f"tcp://127.0.0.1:{_closed_port()}"):
        with pytest.raises(runner.RunError) as info:
            run(GRID, tmp_path / "out.nc", scheduler=address, scheduler_timeout=0.5)
        assert info.value.__cause__ is not None        # the failure's traceback is alive
        with pytest.raises(ValueError):
            distributed.Client.current(allow_global=True)
        assert dask.config.get("scheduler", None) is None
        # ... and the client it holds is closed: finalised by the garbage collector in the
        # thread that started the next client's loop, its close blocked that start for
        # 10 s and failed it (seen once in CI, at the second address).
        held = [frame.f_locals["self"] for frame, _ in
                traceback.walk_tb(info.value.__cause__.__traceback__)
                if isinstance(frame.f_locals.get("self"), distributed.Client)]
        assert held and all(client.status == "closed" for client in held)


def _package_copy(tmp_path):
    """A copy of the sweep package under ``tmp_path / "pkg"``."""
    copy = tmp_path / "pkg"
    shutil.copytree(ROOT / "sweep", copy / "sweep",
                    ignore=shutil.ignore_patterns("__pycache__"))
    return copy


def test_a_worker_running_another_sweep_is_refused(tmp_path):
    # A Dask worker imports its own sweep: one left with another version (a stale install
    # on the cluster's nodes) computed chunks with its code and the run exited 0, the file
    # claiming the source hash of the process that wrote it.
    distributed = pytest.importorskip("distributed")
    copy = _package_copy(tmp_path)
    with open(copy / "sweep" / "api.py", "a") as fh:
        fh.write("\n# another sweep\n")
    out = tmp_path / "out.nc"
    with distributed.LocalCluster(n_workers=0, processes=False, protocol="tcp://",
                                  host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        worker = subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", cluster.scheduler_address,
             "--nthreads", "1", "--no-nanny", "--no-dashboard"],
            env=dict(os.environ, PYTHONPATH=str(copy)), cwd=copy,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            with distributed.Client(cluster, set_as_default=False) as client:
                client.wait_for_workers(1, timeout=120)
            with pytest.raises(runner.RunError, match="runs another sweep"):
                run(GRID, out, scheduler=cluster.scheduler_address)
        finally:
            worker.kill()
            worker.wait(timeout=60)
    assert not out.exists()


def test_a_cluster_without_workers_says_so_and_runs_once_one_joins(tmp_path, reference):
    # A scheduler with no worker held the chunks and the run waited in silence.
    distributed = pytest.importorskip("distributed")
    out, said, box = tmp_path / "out.nc", [], {}
    with distributed.LocalCluster(n_workers=0, processes=False, protocol="tcp://",
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        def go():
            try:
                box["result"] = run(GRID, out, scheduler=cluster.scheduler_address,
                                    log=said.append)
            except BaseException as exc:  # noqa: BLE001 - re-raised in the test's thread
                box["error"] = exc
        thread = threading.Thread(target=go)
        thread.start()
        deadline = time.monotonic() + 120
        while not any("no workers yet" in m for m in said):
            assert thread.is_alive() and time.monotonic() < deadline, box
            time.sleep(0.05)
        assert not out.exists()
        cluster.scale(1)
        thread.join(timeout=120)
    assert "error" not in box, box
    line = next(m for m in said if "no workers yet" in m)
    assert cluster.scheduler_address in line and "\n" not in line
    xr.testing.assert_identical(opened(out), reference["grid"])


def test_a_chunk_lost_on_the_cluster_names_it_and_the_run_resumes(tmp_path, monkeypatch,
                                                                   capsys, reference):
    # A worker killed while it computes (out of memory, preempted) fails its chunk once
    # Dask has tried it on several: the run said "unexpected KilledWorker: ..." (or
    # MemoryError, ...), as if it were a bug, naming neither the chunk nor the finished
    # chunks kept, nor how to go on.
    distributed = pytest.importorskip("distributed")
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    out = tmp_path / "out.nc"
    real = runner.compute_chunk
    fourth = design.build(config.loads(GRID).design).points(30, 40)

    def dies_at_the_fourth_chunk(plan, *points):
        if all(np.array_equal(a, b) for a, b in zip(points, fourth)):
            raise MemoryError("Unable to allocate 1.00 GiB")
        return real(plan, *points)

    monkeypatch.setattr(runner, "compute_chunk", dies_at_the_fourth_chunk)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        argv = ["run", str(cfg), "-o", str(out), "--quiet", "--scheduler",
                cluster.scheduler_address]
        assert cli.main(argv) == 1
        one_line_error(capsys.readouterr().err, "chunk 3 (points 30 to 39)",
                       "failed on the Dask cluster", "MemoryError: Unable to allocate",
                       f"kept in {store.partial_dir(out)}", "rerun the same command")
        monkeypatch.setattr(runner, "compute_chunk", real)
        assert cli.main(argv) == 0
    assert not store.partial_dir(out).exists()
    xr.testing.assert_equal(opened(out), reference["grid"])


#: A worker preload (``dask worker --preload``): its third chunk waits for ever, so that
#: the test decides when the scheduler goes (no sleeps).
STALLED_WORKER = """
import time
import sweep.sweeps.runner as r
real, count = r.compute_chunk, [0]
def stalled(*a):
    count[0] += 1
    while count[0] >= 3:
        time.sleep(0.1)
    return real(*a)
r.compute_chunk = stalled
"""


def _dask_process(tmp_path, command, *args):
    """``dask scheduler`` or ``dask worker`` in a process of its own, this sweep first on
    its path (and ``tmp_path``, for preloads)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(tmp_path)]))
    return subprocess.Popen([sys.executable, "-m", f"distributed.cli.dask_{command}",
                             *args, "--no-dashboard"], env=env, cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def test_a_scheduler_lost_mid_run_is_one_line(tmp_path):
    # distributed's client logged its failed reconnection, two tracebacks in 35 lines, on
    # stderr before the run's own one-line error.
    pytest.importorskip("distributed")
    (tmp_path / "stalled_worker.py").write_text(STALLED_WORKER)
    cfg = tmp_path / "c.toml"
    cfg.write_text(DOE)
    out = tmp_path / "out.nc"
    port = _closed_port()
    address = f"tcp://127.0.0.1:{port}"
    scheduler = _dask_process(tmp_path, "scheduler", "--host", "127.0.0.1", "--port",
                              str(port))
    worker = _dask_process(tmp_path, "worker", address, "--nthreads", "1", "--no-nanny",
                           "--preload", "stalled_worker")
    try:
        run = subprocess.Popen(
            [sys.executable, "-m", "sweep", "run", str(cfg), "-o", str(out), "--quiet",
             "--scheduler", address, "--scheduler-timeout", "5"],
            env=dict(os.environ, PYTHONPATH=str(ROOT)), cwd=tmp_path,
            stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 120
        while len(list(store.partial_dir(out).glob("chunk_*.npz"))) < 2:
            assert run.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        scheduler.kill()
        assert run.wait(timeout=120) == 1
        one_line_error(run.stderr.read(), "chunk 2 (points 8,000 to 11,999)",
                       "failed on the Dask cluster", "the 2 finished chunks are kept")
    finally:
        for process in (scheduler, worker):
            process.kill()
            process.wait(timeout=60)


# --------------------------------------------------------------------------- the command line

def _non_sweep_netcdf(path):
    with netCDF4.Dataset(path, "w") as nc:
        nc.createDimension("x", 3)
        nc.createVariable("v", "f8", ("x",))[:] = [1.0, 2.0, 3.0]


@pytest.mark.parametrize("case", [
    "not-utf8", "deep", "dev-zero", "oversized", "axis", "zarr", "long-name", "directory",
    "chunk-negative", "chunk-zero", "chunk-huge", "chunk-huge-toml", "info-not-sweep",
    "scheduler"])
def test_input_faults_end_in_one_line(tmp_path, capsys, case):
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    argv = ["run", str(cfg), "-o", str(tmp_path / "out.nc"), "--quiet"]
    expect = {
        "not-utf8": ("not UTF-8", "0xff", cfg),
        "deep": ("nested deeper than 16 levels", cfg),
        "dev-zero": ("/dev/zero", "larger than"),
        "oversized": ("larger than the limit", cfg),
        "axis": ("design.gamma.num", "1000000000000"),
        "zarr": ("out.zarr", "unknown output format", ".nc"),
        "long-name": ("output name too long", "255"),
        "directory": ("out.nc is a directory",),
        "chunk-negative": ("--chunk-size", "-5"),
        "chunk-zero": ("--chunk-size", "'0'"),
        "chunk-huge": ("--chunk-size", f"from 1 to {limits.MAX_CHUNK_SIZE:,}", "1" + "0" * 23),
        "chunk-huge-toml": ("run.chunk_size", f"from 1 to {limits.MAX_CHUNK_SIZE:,}",
                            "1" + "0" * 23, cfg),
        "info-not-sweep": ("not a sweep output", "x.nc"),
        "scheduler": ("cannot reach the Dask scheduler", "'nonsense'"),
    }[case]
    if case == "not-utf8":
        cfg.write_bytes(b'title = "\xff"\n' + GRID.encode())
    elif case == "deep":
        cfg.write_text(GRID + "x = " + "[" * 3000 + "]" * 3000 + "\n")
    elif case == "dev-zero":
        argv[1] = "/dev/zero"
    elif case == "oversized":
        cfg.write_text(GRID + "#" * limits.CONFIG_MAX_BYTES)
    elif case == "axis":
        cfg.write_text(GRID.replace("num = 9", "num = 1000000000000"))
    elif case == "zarr":
        argv[3] = str(tmp_path / "out.zarr")
    elif case == "long-name":
        argv[3] = str(tmp_path / ("a" * 250 + ".nc"))
    elif case == "directory":
        (tmp_path / "out.nc").mkdir()
        argv.append("--restart")
    elif case == "chunk-negative":
        argv += ["--chunk-size", "-5"]
    elif case == "chunk-zero":
        argv += ["--chunk-size", "0"]
    elif case == "chunk-huge":           # beyond the file's 64-bit attribute
        argv += ["--chunk-size", "1" + "0" * 23]
    elif case == "chunk-huge-toml":
        cfg.write_text(GRID.replace("chunk_size = 10", "chunk_size = 1" + "0" * 23))
    elif case == "info-not-sweep":
        _non_sweep_netcdf(tmp_path / "x.nc")
        argv = ["info", str(tmp_path / "x.nc")]
    elif case == "scheduler":
        pytest.importorskip("distributed")
        argv += ["--scheduler", "nonsense"]
    if case in ("chunk-negative", "chunk-zero", "chunk-huge"):
        with pytest.raises(SystemExit) as info:
            cli.main(argv)
        assert info.value.code == 2
    else:
        assert cli.main(argv) == 1
    one_line_error(capsys.readouterr().err, *expect)
    assert not (tmp_path / "out.nc.partial").exists()
    assert not (tmp_path / "out.nc.lock").exists()


@pytest.mark.parametrize("under", ["c.toml", "c.toml/sub"])
def test_a_file_where_the_output_directory_should_be_is_named(tmp_path, capsys, under):
    # `-o c.toml/out.nc` said "cannot write in .../c.toml: c.toml: File exists", as if the
    # file's existence were the fault, not that it is no directory.
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    out = tmp_path / under / "out.nc"
    assert cli.main(["run", str(cfg), "-o", str(out), "--quiet"]) == 1
    line = one_line_error(capsys.readouterr().err, f"{cfg} is not a directory", "-o")
    assert "File exists" not in line
    assert cfg.read_text() == GRID and sorted(p.name for p in tmp_path.iterdir()) == ["c.toml"]


@pytest.mark.parametrize("stderr", ["closed pipe", "/dev/full"])
def test_a_failing_stderr_drops_the_messages_not_the_run(tmp_path, reference, stderr):
    # `sweep run c.toml 2>&1 | head -c 10` and `2>/dev/full`: the run was lost, blamed on
    # "cannot write X.partial: Broken pipe", and a traceback followed.
    if stderr == "/dev/full" and not Path("/dev/full").exists():
        pytest.skip("no /dev/full here")
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    out = tmp_path / "out.nc"
    env = dict(os.environ,
               PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    cmd = [sys.executable, "-m", "sweep", "run", str(cfg), "-o", str(out),
           "--progress-interval", "1e-9"]               # a progress line at every chunk
    with open(os.devnull if stderr == "closed pipe" else stderr, "w") as sink:
        proc = subprocess.Popen(cmd, env=env, cwd=tmp_path, stdout=sink,
                                stderr=subprocess.PIPE if stderr == "closed pipe" else sink)
        if proc.stderr is not None:
            proc.stderr.close()                         # the reader leaves at once
        assert proc.wait(timeout=300) == 0
    xr.testing.assert_equal(opened(out), reference["grid"])
    assert not store.partial_dir(out).exists()


@pytest.mark.parametrize("closed", ["2>&-", ">&-", ">&- 2>&-"])
def test_a_closed_descriptor_drops_the_messages_not_the_run(tmp_path, reference, closed):
    # Python starts with sys.stderr (sys.stdout) None where the descriptor is closed: the
    # run wrote nothing ("unexpected AttributeError: 'NoneType' object has no attribute
    # 'write'", exit 1), or wrote its file and then failed on flushing stdout.
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    out = tmp_path / "out.nc"
    env = dict(os.environ,
               PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    python = f'"{sys.executable}" -m sweep'
    for command in (f'run "{cfg}" -o "{out}"', f'info "{out}"'):
        proc = subprocess.run(["bash", "-c", f"{python} {command} {closed}"], env=env,
                              cwd=tmp_path, timeout=300)
        assert proc.returncode == 0, (command, closed)
    xr.testing.assert_equal(opened(out), reference["grid"])
    assert not store.partial_dir(out).exists()


def test_debug_shows_the_traceback(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_bytes(b"\xff")
    with pytest.raises(config.ConfigError, match="not UTF-8"):
        cli.main(["--debug", "validate", str(cfg)])
    with pytest.raises(config.ConfigError):
        cli.main(["validate", str(cfg), "--debug"])


# --------------------------------------------------------------------------- signals

def test_a_signal_during_the_cleanup_is_not_an_interruption(tmp_path, monkeypatch, capsys,
                                                            reference):
    real = store.PartialStore.remove

    def interrupted_remove(self):
        next(self.dir.glob("chunk_*.npz")).unlink()      # partly cleaned up, then killed
        raise KeyboardInterrupt

    monkeypatch.setattr(store.PartialStore, "remove", interrupted_remove)
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    out = tmp_path / "out.nc"
    assert cli.main(["run", str(cfg), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "interrupted:" not in err and "sweep: interrupted" not in err
    assert f"{out} is complete" in err
    assert store.partial_dir(out).exists()
    monkeypatch.setattr(store.PartialStore, "remove", real)
    xr.testing.assert_equal(opened(out), reference["grid"])
    res = run(GRID, out)                                 # leftovers go, the output stays
    assert res.up_to_date and res.discarded_chunks == 7
    assert not store.partial_dir(out).exists()


def test_an_interrupt_during_start_up_is_one_line(monkeypatch, capsys):
    # The start-up's slow part is loading numba: none of it may happen before main() can
    # handle a Ctrl-C (the `sweep` script imports sweep.cli first, and that printed a
    # traceback out of `import sweep`)...
    loaded = subprocess.run([sys.executable, "-c", "import sys, sweep.cli; "
                             "print(sorted({'numba', 'sweep.api'} & set(sys.modules)))"],
                            env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True,
                            text=True, timeout=120)
    assert loaded.stdout.strip() == "[]", loaded
    # ... and main() handles it while it builds the parser, which imports the reports.
    def interrupted(sub):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_add_run_command", interrupted)
    assert cli.main(["run", "c.toml"]) == 130
    assert capsys.readouterr().err == "sweep: interrupted\n"


def test_signals_wait_for_the_end_of_the_publication():
    def handler(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, handler)
    reached = False
    try:
        with pytest.raises(KeyboardInterrupt):
            with runner._signals_deferred():
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(0.01)
                reached = True                           # not cut short by the signal
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert reached


def test_signal_handlers_are_restored_ignored_ones_kept_and_other_threads_left_alone():
    def mine(signum, frame):
        pass

    def theirs(signum, frame):
        pass

    saved = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        signal.signal(signal.SIGTERM, theirs)
        signal.signal(signal.SIGHUP, signal.SIG_IGN)            # as under nohup
        with runner.signals_handled(mine, (signal.SIGTERM, signal.SIGHUP)):
            assert signal.getsignal(signal.SIGTERM) is mine
            assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
        assert signal.getsignal(signal.SIGTERM) is theirs
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
        # Python sets handlers from the main thread only: elsewhere the block just runs.
        seen = []

        def off_main():
            with runner.signals_handled(mine, (signal.SIGTERM,)):
                seen.append(signal.getsignal(signal.SIGTERM))

        worker = threading.Thread(target=off_main)
        worker.start()
        worker.join()
        assert seen == [theirs]
    finally:
        for s, handler in saved.items():
            signal.signal(s, handler)


@pytest.mark.parametrize("through", ["argument", "config"])
def test_a_chunk_size_past_the_limit_is_refused_before_the_run(tmp_path, through):
    # QA scan: sweep.run(chunk_size=2**63), or run.chunk_size = 2**63 (tomllib reads integers
    # of any size), computed every point, then failed on the file's int64 attribute.
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID if through == "argument"
                   else GRID.replace("chunk_size = 10\n", "chunk_size = 9223372036854775808\n"))
    kwargs = {"chunk_size": 2 ** 63} if through == "argument" else {}
    error = runner.RunError if through == "argument" else config.ConfigError
    rule = f"from 1 to {limits.MAX_CHUNK_SIZE:,}, got 9223372036854775808"
    with pytest.raises(error, match=r"chunk.size.*" + rule):
        runner.run(cfg, tmp_path / "out.nc", quiet=True, **kwargs)
    assert not (tmp_path / "out.nc").exists()
    assert not (tmp_path / "out.nc.partial").exists()


def test_the_memory_a_chunk_may_take_is_the_containers_where_that_is_lower(tmp_path,
                                                                           monkeypatch):
    """A container on a large host sees the host's RAM in sysconf; its cgroup limit is what
    the OOM killer enforces."""
    from sweep.sweeps import preflight

    host = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    v2, v1 = tmp_path / "memory.max", tmp_path / "limit_in_bytes"
    monkeypatch.setattr(preflight, "CGROUP_MEMORY_LIMITS", (str(v2), str(v1)))
    assert preflight.physical_memory() == host                  # neither file: the host's
    v1.write_text("2147483648\n")
    assert preflight.physical_memory() == min(host, 2 ** 31)    # cgroup v1
    v2.write_text("max\n")
    assert preflight.physical_memory() == host                  # v2 says: no limit
    v2.write_text("1073741824\n")
    assert preflight.physical_memory() == min(host, 2 ** 30)


def test_an_output_name_that_is_not_utf8_is_refused_before_anything_is_written(tmp_path,
                                                                               capsys):
    # Audit F: netCDF-C raised UnicodeEncodeError ("unexpected"), past the lock and the
    # partial directory, which stayed behind.
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    out = tmp_path / os.fsdecode(b"bad\xff.nc")
    assert cli.main(["run", str(cfg), "-o", str(out), "--quiet"]) == 1
    one_line_error(capsys.readouterr().err, "the output path is not valid UTF-8")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.toml"]


def test_a_failed_publication_names_the_output_and_keeps_the_chunks(tmp_path, monkeypatch,
                                                                    capsys, reference):
    # Audit F: the rename onto the output failed (another file system, a read-only
    # directory) and the message named the partial directory's assembling.nc.
    out = tmp_path / "out.nc"
    real = os.replace

    def replace(src, dst):
        if Path(dst) == out:
            raise OSError(errno.EXDEV, "Invalid cross-device link", str(src), None, str(dst))
        return real(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    assert cli.main(["run", str(cfg), "-o", str(out), "--quiet"]) == 1
    one_line_error(capsys.readouterr().err, f"cannot write {out}: Invalid cross-device link",
                   "kept")
    monkeypatch.setattr(os, "replace", real)
    assert not out.exists() and run(GRID, out).resumed_chunks > 0
    xr.testing.assert_identical(opened(out), reference["grid"])


@pytest.mark.skipif(not hasattr(os, "fork"), reason="RLIMIT_FSIZE is POSIX")
def test_a_file_size_limit_is_named_and_the_chunks_are_kept(tmp_path, reference):
    # Audit F: `ulimit -f` made HDF5 say only "NetCDF: HDF error".
    import resource

    cfg, out = tmp_path / "c.toml", tmp_path / "out.nc"
    cfg.write_text(GRID)

    def limited():
        resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))

    done = subprocess.run([sys.executable, "-m", "sweep", "run", str(cfg), "-o", str(out),
                           "--quiet"], preexec_fn=limited, capture_output=True, text=True)
    assert done.returncode == 1 and not out.exists()
    one_line_error(done.stderr, "NetCDF: HDF error", "at most 20,000 bytes: ulimit -f",
                   "kept")
    assert run(GRID, out).resumed_chunks > 0
    xr.testing.assert_identical(opened(out), reference["grid"])


def test_a_directory_in_place_of_a_chunk_file_is_named_or_cleared(tmp_path, monkeypatch,
                                                                   capsys, reference):
    # Its rename failed on every resume ("Is a directory"), with the advice to rerun the
    # same command, once its chunk was computed again, and it counted among the finished
    # chunks.
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    out = tmp_path / "out.nc"
    partial = interrupted(GRID, out, 3, monkeypatch)
    saved = sorted(partial.glob("chunk_*.npz"))
    assert len(saved) == 3
    saved[0].unlink()
    saved[0].mkdir()
    (saved[0] / "notes").write_text("kept")
    empty = partial / "chunk_0000005.npz"
    empty.mkdir()
    argv = ["run", str(cfg), "-o", str(out), "--quiet"]
    assert cli.main(argv) == 1                    # refused before any chunk is computed
    one_line_error(capsys.readouterr().err, f"cannot resume {out}", saved[0],
                   "a directory, not a chunk file")
    assert not empty.exists()
    assert (saved[0] / "notes").read_text() == "kept" and not out.exists()
    (saved[0] / "notes").unlink()
    run(GRID, out)                                # the empty directories give way
    xr.testing.assert_identical(opened(out), reference["grid"])


@pytest.mark.parametrize("signum, status, said", [(signal.SIGTERM, 143, "terminated"),
                                                  (signal.SIGHUP, 129, "hung up")])
def test_a_stopping_signal_exits_128_plus_it_keeping_the_finished_chunks(
        tmp_path, monkeypatch, capsys, signum, status, said):
    # A batch system's SIGTERM unwound like Ctrl-C and exited 130, SIGINT's status (a shell
    # reports a command killed by a signal as 128 + its number); a closed terminal's SIGHUP
    # killed the run outright (its default action), the save in flight cut short.
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    real, calls = runner.compute_chunk, [0]

    def stopped(*args):
        calls[0] += 1
        if calls[0] == 4:                          # the warm-up, then two chunks saved
            os.kill(os.getpid(), signum)
            time.sleep(1.0)                        # the handler raises before this ends
        return real(*args)

    monkeypatch.setattr(runner, "compute_chunk", stopped)
    missed = []                   # a run that does not catch it must not end pytest

    def before(signum, frame):
        missed.append(signum)
    previous = signal.signal(signum, before)
    try:
        assert cli.main(["run", str(cfg), "-o", str(tmp_path / "out.nc"), "--quiet"]) == status
        assert signal.getsignal(signum) is before and not missed   # restored
    finally:
        signal.signal(signum, previous)
    assert capsys.readouterr().err == f"sweep: {said}\n"
    assert len(list((tmp_path / "out.nc.partial").glob("chunk_*.npz"))) == 2
    assert cli.main(["run", str(cfg), "-o", str(tmp_path / "out.nc"), "--quiet"]) == 0


def test_an_ignored_sighup_stays_ignored(tmp_path):
    # Under nohup SIGHUP is ignored: the run must go on when the terminal closes.
    cfg = tmp_path / "c.toml"
    cfg.write_text(GRID)
    code = ("import os, signal, sys\n"
            "from sweep import cli\n"
            "from sweep.sweeps import runner\n"
            "real = runner.compute_chunk\n"
            "def hung_up(*a):\n"
            "    os.kill(os.getpid(), signal.SIGHUP)\n"
            "    return real(*a)\n"
            "runner.compute_chunk = hung_up\n"
            "sys.exit(cli.main(sys.argv[1:]))\n")
    done = subprocess.run(["nohup", sys.executable, "-c", code, "run", str(cfg), "-o",
                           str(tmp_path / "out.nc"), "--quiet"], cwd=tmp_path,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "out.nc").exists()


def test_a_failed_close_leaves_no_file_for_the_collector_to_close(tmpfs):
    # netCDF4 keeps a Dataset whose close failed (HDF5 could not flush to a full disk) open,
    # and closed it again when collected: later, in any thread, into a thread-unsafe HDF5
    # (a segfault in the writer thread of a later run in the same process, in CI).
    from sweep.store import netcdf
    fs = tmpfs("tiny", "1m")
    nc = netCDF4.Dataset(fs / "x.nc", "w")
    nc.createDimension("n", None)
    var = nc.createVariable("x", "f8", ("n",))
    with pytest.raises(RuntimeError):
        for i in range(100):
            var[i * 10000:(i + 1) * 10000] = np.arange(10000.0) * (i + 1)
    with pytest.raises(RuntimeError):
        netcdf.close_once(nc)
    assert not nc.isopen()
    netcdf.close_once(nc)                        # closed for good: nothing to raise again
