"""The command line (sweep.cli), including a real kill -9 and resume."""
import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from sweep import cli

ROOT = Path(__file__).resolve().parents[1]

CONFIG = """
title = "cli test"
[design]
kind = "grid"
alpha = 1.5
beta = [1.25, 1.5]
gamma = {start = 0.0, stop = 0.2, num = 10}
gtilde = [0.0, 1.0, 10.0]
[outputs]
e = ["numeric"]
fields = ["status", "n_steps"]
[integrator]
steps = 16
[run]
chunk_size = 16
"""


@pytest.fixture
def cfg(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text(CONFIG)
    return path


def test_validate_accepts_and_describes(cfg, capsys):
    assert cli.main(["validate", str(cfg)]) == 0
    out = capsys.readouterr().out
    assert "valid" in out and "60 points" in out and "e_numeric, n_steps, status" in out
    assert "numerical integration: yes" in out


def test_validate_rejects_with_the_key_and_value(cfg, capsys):
    cfg.write_text(CONFIG.replace("beta = [1.25, 1.5]", "beta = [0.5, 1.5]"))
    assert cli.main(["validate", str(cfg)]) == 1
    err = capsys.readouterr().err
    assert "design.beta" in err and "0.5" in err and ">= 1" in err


def test_validate_tells_of_a_step_budget_the_resolution_cannot_meet(cfg, capsys):
    # 10^6 steps per half period in a budget of 1,000 steps: every point of the run would be
    # an upper bound, which validate said nothing of (the run warned only at its end).
    # (gamma > 0 and no 2 beta = alpha + 1: there e is exact at g~ = 0 without a step)
    cfg.write_text(CONFIG.replace("steps = 16", "steps = 1e6\nmax_steps = 1000")
                   .replace("start = 0.0", "start = 0.02")
                   .replace("beta = [1.25, 1.5]", "beta = [1.5, 2.0]"))
    assert cli.main(["validate", str(cfg)]) == 0
    out = capsys.readouterr().out
    n = int(out.split("(calibration on ")[1].split(" point")[0])
    assert f"caveat: {n} of {n} sample points ran out of the step budget" in out
    cfg.write_text(CONFIG)                              # 16 steps finish within the default
    assert cli.main(["validate", str(cfg)]) == 0
    assert "caveat" not in capsys.readouterr().out


def test_run_then_info(cfg, tmp_path, capsys):
    out = tmp_path / "o.nc"
    assert cli.main(["run", str(cfg), "-o", str(out), "--quiet"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and out.exists()
    assert cli.main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    for part in ("alpha = 1, beta = 2, gamma = 10, gtilde = 3", "(60 points)", "e_numeric",
                 "status", "ok: ", "integrator_steps = 16.0", "n_points = 60"):
        assert part in text, part
    # a mismatching rerun is refused with a clear message and exit status 1
    cfg.write_text(CONFIG.replace("steps = 16", "steps = 17"))
    assert cli.main(["run", str(cfg), "-o", str(out), "--quiet"]) == 1
    assert "different configuration" in capsys.readouterr().err
    assert cli.main(["run", str(cfg), "-o", str(out), "--quiet", "--restart"]) == 0
    with xr.open_dataset(out) as ds:
        assert ds.attrs["integrator_steps"] == 17.0


def test_default_output_name_and_progress_bar_only_on_a_terminal(cfg, tmp_path, capsys,
                                                                 monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli.main(["run", str(cfg)]) == 0
    err = capsys.readouterr().err
    assert (tmp_path / "c.nc").exists()
    assert "wrote c.nc" in err and "pt/s]" not in err        # stderr is not a terminal:
    assert "c.nc: 60/60 points (100%) in " in err               # plain progress lines
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    assert cli.main(["run", str(cfg), "-o", "bar.nc"]) == 0
    err = capsys.readouterr().err
    assert "pt/s]" in err and "100%" in err and "<00:00" in err   # tqdm: rate and ETA
    assert cli.main(["run", str(cfg), "-o", "quiet.nc", "--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_version(capsys):
    from sweep import __version__

    with pytest.raises(SystemExit) as info:
        cli.main(["--version"])
    assert info.value.code == 0 and capsys.readouterr().out == f"sweep {__version__}\n"
    res = subprocess.run([sys.executable, "-m", "sweep", "--version"], capture_output=True,
                         text=True, cwd=ROOT)
    assert res.returncode == 0 and res.stdout == f"sweep {__version__}\n"


def test_python_dash_m_sweep_is_the_command(cfg):
    res = subprocess.run([sys.executable, "-m", "sweep", "validate", str(cfg),
                          "--no-estimate"], capture_output=True, text=True, cwd=ROOT)
    assert res.returncode == 0, res.stderr
    assert "valid" in res.stdout and "points: 60 in 4 chunks of <= 16" in res.stdout
    res = subprocess.run([sys.executable, "-m", "sweep", "nonsense"], capture_output=True,
                         text=True, cwd=ROOT)
    assert res.returncode == 2 and "invalid choice" in res.stderr


@pytest.mark.parametrize("argv, command", [
    (["report", "accuracy", "x.nc", "--n", "5"], "sweep report accuracy"),
    (["run", "c.toml", "--bogus"], "sweep run"),
    (["validate", "c.toml", "extra"], "sweep validate"),
])
def test_an_unknown_argument_is_blamed_on_its_subcommand(argv, command, capsys):
    # argparse blamed the top parser: "sweep: error: unrecognized arguments: --n 5 (see
    # sweep --help)", whose help does not list a subcommand's options.
    with pytest.raises(SystemExit) as info:
        cli.main(argv)
    unknown = " ".join(argv[3:] if argv[0] == "report" else argv[2:])
    assert info.value.code == 2
    assert capsys.readouterr().err == (f"{command}: error: unrecognized arguments: {unknown} "
                                       f"(see {command} --help)\n")


def _parsers(parser):
    yield parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield from _parsers(sub)


def test_every_command_takes_debug_after_the_subcommand(tmp_path, capsys):
    # `sweep export X --debug` was "unrecognized arguments" (only run, info and validate
    # had it), though the module says --debug goes before or after the subcommand.
    leaves = [p for p in _parsers(cli.build_parser())
              if not any(isinstance(a, argparse._SubParsersAction) for a in p._actions)]
    assert len(leaves) >= 9 and all("--debug" in p._option_string_actions for p in leaves)
    missing = tmp_path / "missing.nc"
    assert cli.main(["export", str(missing), "--csv"]) == 1
    assert "Traceback" not in capsys.readouterr().err
    with pytest.raises(OSError):                  # --debug: the exception, not one line
        cli.main(["export", str(missing), "--csv", "--debug"])


def test_every_option_and_subcommand_has_help():
    missing = []
    for parser in _parsers(cli.build_parser()):
        for action in parser._actions:
            if not action.help or action.help == argparse.SUPPRESS:
                missing.append(f"{parser.prog}: {action.option_strings or action.dest}")
            if isinstance(action, argparse._SubParsersAction):
                missing += [f"{parser.prog} {c.dest}" for c in action._choices_actions
                            if not c.help]
    assert not missing, missing


def test_unknown_key_is_reported_before_the_missing_one(cfg, capsys):
    cfg.write_text(CONFIG.replace('kind = "grid"', 'knd = "grid"'))
    assert cli.main(["validate", str(cfg)]) == 1
    err = capsys.readouterr().err
    assert "design.knd: unknown key (did you mean 'kind'?)" in err and "required" not in err


def test_info_on_a_missing_file(tmp_path, capsys):
    assert cli.main(["info", str(tmp_path / "none.nc")]) == 1
    assert "cannot read" in capsys.readouterr().err


def test_kill_9_then_rerun_resumes_to_the_uninterrupted_result(tmp_path):
    """A real crash: the process is SIGKILLed after a few chunks are saved."""
    text = CONFIG.replace("num = 10", "num = 400").replace("chunk_size = 16",
                                                           "chunk_size = 60")
    cfg = tmp_path / "k.toml"
    cfg.write_text(text)
    out = tmp_path / "k.nc"
    partial = tmp_path / "k.nc.partial"
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    cmd = [sys.executable, "-m", "sweep.cli", "run", str(cfg), "-o", str(out), "--quiet"]
    # A slow kernel makes the race deterministic: each chunk sleeps in the subprocess.
    slow = ("import sys, time, runpy; import sweep.sweeps.runner as r; real = r.compute_chunk\n"
            "def slow(*a):\n    time.sleep(0.3)\n    return real(*a)\n"
            "r.compute_chunk = slow; sys.argv = ['sweep'] + sys.argv[1:]\n"
            "from sweep.cli import main; sys.exit(main())\n")
    proc = subprocess.Popen([sys.executable, "-c", slow] + cmd[3:], env=env, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 120
        while len(list(partial.glob("chunk_*.npz"))) < 3:
            assert proc.poll() is None, "the run ended before it could be killed"
            assert time.monotonic() < deadline
            time.sleep(0.02)
        os.kill(proc.pid, signal.SIGKILL)
        assert proc.wait() == -signal.SIGKILL
    finally:
        if proc.poll() is None:
            proc.kill()
    saved = len(list(partial.glob("chunk_*.npz")))
    assert 3 <= saved < 20 and not out.exists()
    res = subprocess.run(cmd, env=env, cwd=tmp_path, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert not partial.exists()
    # The reference runs in a fresh process too, so that both use the same compiled code.
    ref = tmp_path / "ref.nc"
    res = subprocess.run(cmd[:6] + [str(ref), "--quiet"], env=env, cwd=tmp_path,
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    with xr.open_dataset(out) as a, xr.open_dataset(ref) as b:
        for name in ("e_numeric", "status", "n_steps", "gamma"):
            np.testing.assert_array_equal(a[name].values, b[name].values)
        assert a.attrs["sweep_config"] == b.attrs["sweep_config"] == text


@pytest.mark.parametrize("output, expected", [
    (".", ". is a directory; give the output .nc file name with -o"),
    ("", "the output file name is empty"),
    ("/", "/ is a directory"),
    ("nowhere/..", "nowhere/.. names a directory, not a file"),
])
def test_an_output_that_names_no_file_is_one_clear_line(cfg, tmp_path, capsys, monkeypatch,
                                                        output, expected):
    # These used to end in "unexpected ValueError: PosixPath('.') has an empty name".
    monkeypatch.chdir(tmp_path)
    for command in ("run", "validate"):
        extra = ["--quiet"] if command == "run" else ["--no-estimate"]
        assert cli.main([command, str(cfg), "-o", output] + extra) == 1
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "unexpected" not in err, err
        assert expected in err and err.startswith(f"sweep {command}: error: "), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.toml"]


def test_a_scene_whose_scaling_overflows_fails_validate_and_run(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text('[design]\nkind = "scene"\nv0 = [1e-300]\nF = [0.0, 1.0]\n'
                     '[design.materials.m1]\nlaw = "kk"\nm = 0.154\nk = 3.6138e10\n'
                     'gamma0 = 1.5237e-6\n[outputs]\ne = ["numeric"]\nfields = ["status"]\n')
    for argv in (["validate", str(scene)], ["run", str(scene), "-o", str(tmp_path / "s.nc")]):
        assert cli.main(argv) == 1
        captured = capsys.readouterr()
        err = captured.err.strip()
        assert len(err.splitlines()) == 1 and "RuntimeWarning" not in err, err
        assert f"{scene}: design.materials.m1: gtilde overflows" in err
    assert not (tmp_path / "s.nc").exists()


SCENE = """
[design]
kind = "scene"
v0 = [1.0, 2.0, 3.0]
F = 0.0
[design.materials.steel]
law = "kk"
m = 0.154
k = 3.6138e10
gamma0 = 1.5237e-6
[outputs]
e = ["numeric"]
[integrator]
steps = 16
"""


def _to_a_closed_pipe(argv, cwd):
    """Run ``python -m sweep ARGV`` with stdout a pipe nobody reads (its reader closed
    before the start: every write fails with EPIPE, as after ``| head`` has exited)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    read, write = os.pipe()
    os.close(read)
    try:
        return subprocess.run([sys.executable, "-m", "sweep"] + argv, stdout=write,
                              stderr=subprocess.PIPE, text=True, cwd=cwd, env=env)
    finally:
        os.close(write)


@pytest.mark.skipif(not hasattr(signal, "SIGPIPE"), reason="no SIGPIPE (Windows)")
def test_a_closed_stdout_is_not_blamed_on_the_file(cfg, tmp_path):
    # QA2 4: `sweep info kk.nc | head` said "error: cannot read kk.nc: Broken pipe".
    (tmp_path / "s.toml").write_text(SCENE)
    for config, out in ((cfg, "o.nc"), (tmp_path / "s.toml", "s.nc")):
        assert cli.main(["run", str(config), "-o", str(tmp_path / out), "--quiet"]) == 0
    for argv in (["info", "o.nc"], ["validate", str(cfg), "--no-estimate"],
                 ["export", "s.nc", "--csv", "-o", "s.csv"]):
        res = _to_a_closed_pipe(argv, tmp_path)
        # silent, with the status of a command killed by SIGPIPE (128 + 13), as `cat` has
        assert (res.returncode, res.stderr) == (128 + signal.SIGPIPE, ""), argv
    assert (tmp_path / "s.csv").stat().st_size > 0      # the export itself was done


class _ClosedStdout:
    """A stdout whose reader has gone: every write and flush fails with EPIPE."""

    def write(self, text):
        raise BrokenPipeError(32, "Broken pipe")

    flush = write


def test_a_closed_stdout_in_process_returns_quietly(monkeypatch, capsys, tmp_path):
    monkeypatch.setattr("sweep.store.summarize", lambda path: "a summary")
    monkeypatch.setattr(sys, "stdout", _ClosedStdout())
    assert cli.main(["info", str(tmp_path / "any.nc")]) == 128 + 13   # 13: SIGPIPE
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("argv, bad", [
    (["report", "paper", "--n-gamma", "1"], "--n-gamma"),
    (["report", "paper", "--n-crit", "0"], "--n-crit"),
    (["report", "paper", "--steps", "0"], "--steps"),
    (["report", "paper", "--steps", "nan"], "--steps"),
    # Below the integrator's 2 (was "unexpected ValueError", exit 1), beyond every budget
    (["report", "paper", "--steps", "1"], "--steps"),
    (["report", "paper", "--steps", "1e300"], "--steps"),
    (["report", "speed", "--ref-steps", "3"], "--ref-steps"),    # its half, 1.5, is < 2
    (["report", "speed", "--ref-steps", "1e300"], "--ref-steps"),
    # Counts of points past what numpy can hold: "unexpected ValueError: Maximum allowed
    # size exceeded" (--n-validate: OverflowError, after minutes of judging)
    (["report", "paper", "--n-gamma", "1" + "0" * 30], "--n-gamma"),
    (["report", "paper", "--n-crit", "1" + "0" * 30], "--n-crit"),
    (["report", "speed", "--n-points", "1" + "0" * 30], "--n-points"),
    (["report", "error-model", "--sub", "1" + "0" * 30], "--sub"),
    (["report", "error-model", "--n-validate", "1" + "0" * 30], "--n-validate"),
    (["report", "error-model", "--sub", "0"], "--sub"),
    (["report", "error-model", "--n-validate", "-1"], "--n-validate"),
    (["report", "speed", "--seed", "-3"], "--seed"),
    # An infinite resolution or tolerance is no setting: the run would never end or mean
    # nothing (a timeout or a progress interval may be inf: never).
    (["report", "speed", "--ref-steps", "inf"], "--ref-steps"),
    (["report", "speed", "--ref-tol", "inf"], "--ref-tol"),
    (["report", "speed", "--tols", "1e-6", "inf"], "--tols")])
def test_report_numbers_out_of_range_are_usage_errors(capsys, argv, bad):
    # Before, the report ran and its ValueError came back as "unexpected ValueError ...
    # (rerun with --debug)", exit 1, as if the package had failed.
    with pytest.raises(SystemExit) as info:
        cli.main(argv)
    err = capsys.readouterr().err
    assert info.value.code == 2
    assert err.count("\n") == 1 and f"argument {bad}: must be" in err and argv[-1] in err


def test_run_caveats_are_one_line_warnings_even_when_quiet(tmp_path, capsys):
    # The file is complete and exit 0, but its e are upper bounds where the budget ran out:
    # said on stderr although --quiet silences the progress.
    cfg = tmp_path / "c.toml"
    cfg.write_text('[design]\nkind = "grid"\nalpha = 1.5\nbeta = 1.5\ngamma = [0.01, 0.1]\n'
                   'gtilde = [0.0, 1.0]\n[outputs]\ne = ["numeric"]\n[integrator]\n'
                   'max_steps = 20\n')
    assert cli.main(["run", str(cfg), "-o", str(tmp_path / "c.nc"), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert err == ("sweep run: warning: 4 of 4 points ran out of the step budget: their e is "
                   "an upper bound, not a value (status BUDGET_EXHAUSTED; store status in "
                   "outputs.fields to see which, or raise integrator.max_steps)\n")
    assert cli.main(["info", str(tmp_path / "c.nc")]) == 0
    assert "points_budget_exhausted = 4" in capsys.readouterr().out


@pytest.mark.parametrize("option, value", [("--sub", "3"), ("--n-validate", "1000000")])
def test_an_error_model_beyond_memory_is_a_usage_error(monkeypatch, capsys, tmp_path, option,
                                                        value):
    # Within the count limit but past this machine's memory: refused before the build (a
    # --sub of about 50 judged for hours, then the report was killed).
    from sweep.reports import error_model

    memory = error_model.judged_points(2) * error_model.BYTES_PER_POINT
    monkeypatch.setattr(error_model, "physical_memory", lambda: memory)
    out = tmp_path / "m.npz"
    with pytest.raises(SystemExit) as info:
        cli.main(["report", "error-model", "--out", str(out), "--sub", "1", option, value])
    err = capsys.readouterr().err
    assert info.value.code == 2 and not out.exists()
    assert err.count("\n") == 1 and f"argument {option}: must fit in memory, got {value}" in err


def _no_build(monkeypatch):
    """The error model's build (a minute at the least) replaced by the shipped model."""
    from sweep import auto
    from sweep.reports import error_model

    monkeypatch.setattr(error_model, "build_error_model",
                        lambda sub, progress: auto.default_model())


def test_error_model_out_is_written_at_exactly_its_path(monkeypatch, capsys, tmp_path):
    # numpy wrote em.npz for --out em, and the command printed "em".
    from sweep import auto

    _no_build(monkeypatch)
    out = tmp_path / "em"
    assert cli.main(["report", "error-model", "--out", str(out), "--n-validate", "0",
                     "-q"]) == 0
    assert sorted(p.name for p in out.parent.iterdir()) == ["em"]
    assert auto.ErrorModel.load(out).methods == auto.default_model().methods
    assert capsys.readouterr().out.splitlines()[-2:] == ["files:", f"  {out}"]


@pytest.mark.parametrize("where, says", [
    ("a_dir", "a_dir: is a directory, not a model file"),
    ("a_file/em.npz", "a_file: is a file, not an output directory"),
    ("/sys/em.npz", "/sys: cannot create a file in this directory")])
def test_error_model_out_faults_are_one_line_before_the_build(monkeypatch, capsys, tmp_path,
                                                              where, says):
    # Said only after the whole build (minutes), or never: a directory as --out.
    from sweep.reports import error_model

    def built(**kwargs):
        raise AssertionError("built before the output was checked")

    monkeypatch.setattr(error_model, "build_error_model", built)
    (tmp_path / "a_dir").mkdir()
    (tmp_path / "a_file").write_text("keep")
    monkeypatch.chdir(tmp_path)
    assert cli.main(["report", "error-model", "--out", where, "--sub", "1", "-q"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and says in err and "unexpected" not in err
    assert (tmp_path / "a_file").read_text() == "keep"


def test_paper_steps_beyond_the_reports_budget_are_a_usage_error(monkeypatch, capsys):
    # 2**30 passed the integrator's check, but the report's budget stayed 200,000: every
    # point ran out of it and wrong tables were written.
    from sweep.reports import paper

    def ran(*args, **kwargs):
        raise AssertionError("the report ran")

    monkeypatch.setattr(paper, "paper_report", ran)
    with pytest.raises(SystemExit) as info:
        cli.main(["report", "paper", "--steps", "1e9"])
    err = capsys.readouterr().err
    assert info.value.code == 2 and err.count("\n") == 1
    assert "argument --steps: must be <= 515,396 (the report's step budget" in err
    assert "1,073,741,824" in err and "got '1e9'" in err


@pytest.mark.parametrize("command", ["run", "validate"])
@pytest.mark.parametrize("size", ["inf", "1e400", "nan", "0.5"])
def test_a_size_out_of_range_is_a_usage_error(cfg, capsys, command, size):
    # QA: --max-size inf (or 1e400, past a double) ended in an OverflowError traceback from
    # int(inf); 0.5 became a limit of 0 bytes that refused every design.
    with pytest.raises(SystemExit) as info:
        cli.main([command, str(cfg), "--max-size", size])
    err = capsys.readouterr().err
    assert info.value.code == 2
    assert err.count("\n") == 1 and "argument --max-size: must be a size" in err
    assert repr(size) in err


@pytest.mark.parametrize("content", [b"not a dataset\n", bytes(range(256)) * 4])
@pytest.mark.parametrize("command", [["export", "{}", "--csv"], ["report", "accuracy", "{}"],
                                     ["example", "bounce", "--cor", "lookup", "--table", "{}"],
                                     ["info", "{}"]])
def test_a_file_that_is_not_netcdf_is_one_line(tmp_path, capsys, monkeypatch, content,
                                               command):
    # QA: export, report accuracy and example bounce printed xarray's three lines about IO
    # backends, with URLs; all of them open a file by sweep.store.open_dataset now.
    monkeypatch.chdir(tmp_path)
    (tmp_path / "x.nc").write_bytes(content)
    assert cli.main([a.format("x.nc") for a in command]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.endswith("error: cannot read x.nc: not a netCDF file\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.nc"]     # nothing written


def _refusal_of(argv, capsys):
    """The one-line error of ``sweep ARGV`` (exit status 1), less its command's prefix."""
    assert cli.main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err.split(": error: ", 1)[1].strip()


def _validate_refuses_as_run_does(cfg, out, capsys, *extra):
    """``sweep validate`` refuses with the refusal ``sweep run`` gives, time estimate or
    not, and neither touches what is there."""
    before = sorted(p.name for p in out.parent.iterdir())
    said = _refusal_of(["run", str(cfg), "-o", str(out), "--quiet"], capsys)
    for estimate in (["--no-estimate"], []):
        text = _refusal_of(["validate", str(cfg), "-o", str(out), *estimate, *extra], capsys)
        assert text == f"`sweep run` would refuse {cfg}: {said}"
    assert sorted(p.name for p in out.parent.iterdir()) == before
    return said


def test_validate_refuses_an_existing_output_run_would_not_overwrite(cfg, tmp_path, capsys):
    # Audit F3: validate said "valid" (exit 0) where run refused the existing -o.
    out = tmp_path / "o.nc"
    assert cli.main(["run", str(cfg), "-o", str(out), "--quiet"]) == 0
    cfg.write_text(CONFIG.replace("steps = 16", "steps = 17"))
    assert "different configuration" in _validate_refuses_as_run_does(cfg, out, capsys)
    cfg.write_text(CONFIG)
    assert cli.main(["run", str(cfg), "-o", str(out), "--quiet", "--restart"]) == 0
    out.write_bytes(out.read_bytes()[:1000])        # truncated (audit F: "not a sweep output")
    assert "cannot be read as netCDF (damaged, truncated" in _validate_refuses_as_run_does(
        cfg, out, capsys)
    out.write_text("notes\n")
    assert "cannot be read as netCDF" in _validate_refuses_as_run_does(cfg, out, capsys)
    import netCDF4

    out.unlink()
    netCDF4.Dataset(out, "w").close()               # netCDF, but no sweep's
    assert "is not a sweep output" in _validate_refuses_as_run_does(cfg, out, capsys)


def test_validate_refuses_saved_chunks_run_would_not_resume(cfg, tmp_path, capsys):
    from sweep import store

    out = tmp_path / "o.nc"
    # the partial state of another configuration's interrupted run into the same -o
    partial = store.PartialStore(out, {"config_sha256": "another"})
    partial.open()
    partial.release()
    said = _validate_refuses_as_run_does(cfg, out, capsys)
    # (its manifest names no sweep version either, which is checked first)
    assert said.startswith(f"cannot resume {out}") and "computed with a different" in said


def test_validate_refuses_a_missing_gpu_before_its_estimate(cfg, tmp_path, capsys,
                                                            monkeypatch):
    # With the estimate on, validate computed on the missing device: "unexpected
    # RuntimeError ... (rerun with --debug)"; without it, it said "valid".
    from sweep.kernels import cuda

    monkeypatch.setattr(cuda, "device_error", lambda: "no CUDA GPU here")
    cfg.write_text(CONFIG.replace("steps = 16", 'steps = 16\ndevice = "cuda"'))
    said = _validate_refuses_as_run_does(cfg, tmp_path / "o.nc", capsys)
    assert said == 'integrator.device = "cuda": no CUDA GPU here'


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full (not Linux)")
@pytest.mark.parametrize("unbuffered", ["1", ""])
def test_a_full_stdout_is_named_not_the_file(cfg, tmp_path, unbuffered):
    # Audit F7: `> /dev/full` gave "sweep export: error: s.nc: [Errno 28] ..." (the input,
    # although the CSV was written whole) and "sweep info: error: [Errno 28] ..." (no
    # name); block-buffered, the interpreter's flush at exit failed again with 2 lines more.
    (tmp_path / "s.toml").write_text(SCENE)
    for config, out in ((cfg, "o.nc"), (tmp_path / "s.toml", "s.nc")):
        assert cli.main(["run", str(config), "-o", str(tmp_path / out), "--quiet"]) == 0
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               PYTHONUNBUFFERED=unbuffered)
    for argv in (["info", "o.nc"], ["validate", str(cfg), "--no-estimate"],
                 ["export", "s.nc", "--csv", "-o", "s.csv"]):
        with open("/dev/full", "w") as full:
            res = subprocess.run([sys.executable, "-m", "sweep"] + argv, stdout=full,
                                 stderr=subprocess.PIPE, text=True, cwd=tmp_path, env=env)
        assert (res.returncode, res.stderr) == (
            1, f"sweep {argv[0]}: error: <stdout>: No space left on device\n"), argv
    with open(tmp_path / "s.csv") as f:             # the export itself was done
        assert len(f.readlines()) == 1 + 3


def test_a_scheduler_timeout_without_a_scheduler_is_a_usage_error(cfg, tmp_path, capsys):
    # Audit F8: accepted and ignored (exit 0), as if it had bounded something.
    out = tmp_path / "o.nc"
    with pytest.raises(SystemExit) as info:
        cli.main(["run", str(cfg), "-o", str(out), "--scheduler-timeout", "2"])
    err = capsys.readouterr().err
    assert info.value.code == 2 and err.count("\n") == 1 and not out.exists()
    assert "argument --scheduler-timeout: applies to --scheduler only, got 2.0" in err


def test_max_points_takes_the_default_as_help_prints_it(cfg, capsys):
    # Audit F8: the help said "(default 1e+09)" but --max-points 1e9 was "must be an
    # integer >= 1", although --max-size 1e9 was taken.
    run = next(p for p in cli._leaf_parsers(cli.build_parser()) if p.prog == "sweep run")
    option = next(a for a in run._actions if a.dest == "max_points")
    default = option.help.split("(default ")[1].rstrip(")")
    for value in (default, "1e9", "3000.0"):
        assert cli.main(["validate", str(cfg), "--no-estimate", "--max-points", value]) == 0
    capsys.readouterr()
    assert cli.main(["validate", str(cfg), "--no-estimate", "--max-points", "59.0"]) == 1
    assert "above the limit of 59 points" in capsys.readouterr().err      # 60 points
    for value in ("1.5", "inf", "nan", "0.0"):
        with pytest.raises(SystemExit) as info:
            cli.main(["validate", str(cfg), "--max-points", value])
        assert info.value.code == 2
        assert f"must be an integer >= 1, got {value!r}" in capsys.readouterr().err
