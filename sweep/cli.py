"""Command line: ``sweep run | info | validate | report | export | example``.

::

    sweep --version
    sweep run CONFIG [-o OUT.nc] [--resume | --restart] [--quiet] [--progress-interval S]
              [--chunk-size N] [--scheduler ADDR [--scheduler-timeout S]] [--max-points N]
              [--max-size SIZE] [--force] [--debug]
    sweep info OUT.nc
    sweep validate CONFIG [-o OUT.nc] [--chunk-size N] [--max-points N] [--max-size SIZE]
              [--force] [--no-estimate]
    sweep report accuracy DATASET.nc [--out DIR]
    sweep report paper [--out DIR] [--n-gamma N] [--n-crit N] [--steps S] [--models ...]
    sweep report speed [--out DIR] [--n-points N] [--n-peer N] [--n-check N] [--model M]
              [--tols TOL ...] [--peers P ...] [--n-vector N] [--n-closed N] [--repeat R]
    sweep report error-model [--out FILE.npz] [--sub N] [--n-validate N]
    sweep export SCENE.nc (--csv | --npz) [-o OUT] [--variable V] [--no-check]
    sweep example bounce [--out DIR] [--cor direct [--method M] [--tol T] |
                         --cor lookup [--table SCENE.nc]] [--scene CONFIG [--material NAME]]
                         [--height H] [--v-stop V]

Exit status: 0 success; 1 an error: invalid configuration, refused resume or preflight,
output locked by another run, unreadable dataset, a file system or scheduler fault; 2 bad
arguments; 130 interrupted, 143 terminated by SIGTERM, 129 hung up (SIGHUP: the terminal
closed) (the finished chunks are kept; rerun the same command, less ``--restart``, to
resume); 141 the reader of the output left
(``sweep info X | head``: nothing is said, as for a command killed by SIGPIPE); a stdout
that cannot be written (``> /dev/full``) is an error naming ``<stdout>``. ``sweep
run`` whose stderr fails midway (``2>&1 | head``, ``2>/dev/full``) drops its messages and
progress from there on and finishes: 0 with the file complete, as if it had been
``--quiet``. Every error is one line on stderr naming the file, value or address and the
cause; ``--debug`` (before or after the subcommand) shows the traceback instead.
``python -m sweep`` is the same command (:mod:`sweep.__main__`).

This module owns every subcommand and all of argparse: each subparser sets ``func``, the
handler that runs it and returns the exit status. Floor 6 (the top): it may import any
module of the package; the work modules are imported inside the handlers so that ``sweep
--help`` and argument errors stay fast.
"""
from __future__ import annotations

import argparse
import contextlib
import logging
import math
import os
import signal
import sys
import warnings
from pathlib import Path

from sweep._format import naming
from sweep._version import __version__

__all__ = ["main", "build_parser", "add_report_commands"]

#: What an error writing standard output calls it (as Python names the stream).
_STDOUT = "<stdout>"


class _Parser(argparse.ArgumentParser):
    """argparse, with its errors on one line (the usage is one ``--help`` away)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def parse_known_args(self, args=None, namespace=None):
        ns, extra = super().parse_known_args(args, namespace)
        # The innermost (sub)command finishes first and is kept: the parser an unknown
        # argument belongs to, for its error line.
        if getattr(ns, "_parser", None) is None:
            ns._parser = self
        return ns, extra

    def parse_args(self, args=None, namespace=None):
        ns, extra = self.parse_known_args(args, namespace)
        if extra:
            # argparse blamed the top parser ("sweep: error: ... see sweep --help") for an
            # option misspelt after `sweep report accuracy`.
            ns._parser.error(f"unrecognized arguments: {' '.join(extra)}")
        return ns


def _int_at_least(low, high=None):
    """An argparse ``type=``: an integer >= ``low`` (and <= ``high``, if given), also in
    the form of a float that is one (``1e9``: how ``--help`` prints the defaults)."""
    rule = f">= {low}" if high is None else f"from {low} to {high:,}"

    def convert(text):
        try:
            value = int(text)
        except ValueError:
            value = _integral_float(text, low - 1)
        if not (low <= value and (high is None or value <= high)):
            raise argparse.ArgumentTypeError(f"must be an integer {rule}, got {text!r}")
        return value
    return convert


def _integral_float(text, otherwise):
    """``text`` read as a float, as an int if it is a whole number, else ``otherwise``."""
    try:
        value = float(text)
    except ValueError:
        return otherwise
    return int(value) if value.is_integer() else otherwise


_positive_int = _int_at_least(1)


def _points(low=1):
    """An argparse ``type=``: a number of points a report computes, >= ``low`` and at most
    the largest design ``sweep run`` starts unforced (its arrays are held in memory: beyond,
    numpy refused them only once the report had run that far, as an 'unexpected' error)."""
    from sweep.sweeps import limits

    return _int_at_least(low, limits.MAX_POINTS)


def _number_above_zero(unit="", finite=True):
    """An argparse ``type=``: a number > 0, finite unless ``finite`` is False (``inf``: an
    interval or a timeout that never comes); ``unit`` (e.g. ``" [m]"``) goes into the
    message, which argparse prefixes with the option's name."""
    kind = "finite number" if finite else "number"

    def convert(text):
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (value > 0 and (math.isfinite(value) or not finite)):
            raise argparse.ArgumentTypeError(f"must be a {kind} > 0{unit}, got {text!r}")
        return value
    return convert


_finite_positive = _number_above_zero
_positive_float = _number_above_zero(finite=False)


def _resolution(also_half=False):
    """An argparse ``type=``: a resolution ``steps`` the integrator accepts, by the
    registry's own check and rule (its range is the registry's, not a copy); with
    ``also_half``, half of it too (report speed checks its reference at half of it)."""
    from sweep import registry

    option = registry.METHODS["numeric"].option("steps")

    def convert(text):
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (option.check(value) and (not also_half or option.check(value / 2))):
            half = ", and so must half of it (the reference's check)" if also_half else ""
            raise argparse.ArgumentTypeError(f"must be {option.rule}{half}, got {text!r}")
        return value
    return convert


def _paper_steps(text):
    """An argparse ``type=``: ``steps`` of ``report paper``: a resolution the integrator
    accepts (:func:`_resolution`) whose step budget the report can raise with it
    (:func:`sweep.reports.paper.step_budget`; beyond, every point ran out of budget)."""
    from sweep.reports import paper

    value = _resolution()(text)
    try:
        paper.step_budget(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be {paper.STEPS_RULE}, got {text!r}") from None
    return value


_SIZE_UNITS = {"": 1, "k": 10 ** 3, "m": 10 ** 6, "g": 10 ** 9, "t": 10 ** 12, "p": 10 ** 15}


def _size(text):
    """``"50G"``, ``"50GB"``, ``"2e11"`` -> bytes (decimal units): at least one byte, and
    finite (``inf`` or ``1e400`` is no size: int() of it raised OverflowError)."""
    t = text.strip().lower().removesuffix("b")
    unit = t[-1:] if t[-1:] in _SIZE_UNITS and t[-1:] else ""
    try:
        value = float(t[:len(t) - len(unit)]) * _SIZE_UNITS[unit]
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 1):
        raise argparse.ArgumentTypeError(f"must be a size such as 500M or 2T, got {text!r}")
    return int(value)


def _add_debug(p):
    # SUPPRESS: a subcommand's default must not reset `sweep --debug run ...`.
    p.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                   help="show the traceback of an error instead of a one-line message")


def _add_limit_options(p):
    from sweep.sweeps import limits

    p.add_argument("--chunk-size", type=_int_at_least(1, limits.MAX_CHUNK_SIZE), metavar="N",
                   help="points per chunk (default: the configuration's run.chunk_size)")
    p.add_argument("--max-points", type=_positive_int, metavar="N",
                   default=limits.MAX_POINTS,
                   help=f"largest design run without --force (default {limits.MAX_POINTS:g})")
    p.add_argument("--max-size", type=_size, metavar="SIZE", default=limits.MAX_OUTPUT_BYTES,
                   help="largest output, uncompressed, run without --force (default "
                        f"{limits.MAX_OUTPUT_BYTES / 1e9:g}G)")
    p.add_argument("--force", action="store_true",
                   help="run although the design is above these limits or the free disk "
                        "looks short")


def _limits(args):
    from sweep.sweeps.preflight import Limits

    return Limits(max_points=args.max_points, max_bytes=args.max_size)


# --------------------------------------------------------------------------- run, info, validate

def _add_run_command(sub):
    from sweep.sweeps import limits

    p = sub.add_parser("run", help="run a sweep configuration and write a netCDF dataset",
                       description="Run the sweep described by CONFIG. An interrupted run "
                                   "resumes from its finished chunks when the same command "
                                   "is run again.")
    p.add_argument("config", metavar="CONFIG", help="TOML configuration file")
    p.add_argument("-o", "--output", metavar="OUT.nc",
                   help="output netCDF file (.nc, .nc4 or .netcdf; default: CONFIG's name "
                        "with .nc, in the current directory)")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--resume", dest="restart", action="store_false", default=False,
                      help="resume from saved chunks if any (default)")
    mode.add_argument("--restart", dest="restart", action="store_true",
                      help="discard saved chunks and an existing output, start afresh")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no progress bar, no progress lines and no messages")
    p.add_argument("--progress-interval", type=_positive_float, metavar="S", default=None,
                   help="when stderr is not a terminal (batch jobs, CI logs), print a "
                        "progress line every S seconds (default "
                        f"{limits.PROGRESS_INTERVAL_S:g}); on a terminal a bar is drawn")
    _add_limit_options(p)
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="Dask scheduler address (tcp://host:port): run the chunks on that "
                        "cluster instead of locally")
    p.add_argument("--scheduler-timeout", type=_positive_float, metavar="S", default=None,
                   help="seconds to wait for the scheduler to answer (default "
                        f"{limits.SCHEDULER_TIMEOUT_S:g})")
    _add_debug(p)
    p.set_defaults(func=_cmd_run, usage_error=p.error)


def _add_info_and_validate_commands(sub):
    p = sub.add_parser("info", help="describe an output dataset",
                       description="Print the dimensions, variables with summary "
                                   "statistics, and settings of a sweep output.")
    p.add_argument("path", metavar="OUT.nc", help="netCDF file written by `sweep run`")
    _add_debug(p)
    p.set_defaults(func=_cmd_info)
    p = sub.add_parser("validate", help="check a configuration without running it",
                       description="Check CONFIG and print what running it costs: points, "
                                   "chunks, output size, free disk needed, estimated time. "
                                   "Exit status 1, with the reason and no estimate, if "
                                   "`sweep run` would refuse it.")
    p.add_argument("config", metavar="CONFIG", help="TOML configuration file")
    p.add_argument("-o", "--output", metavar="OUT.nc",
                   help="the output `sweep run` would write (default: CONFIG's name with .nc)")
    _add_limit_options(p)
    p.add_argument("--no-estimate", action="store_true",
                   help="skip the time estimate (it times the computation on a few points)")
    _add_debug(p)
    p.set_defaults(func=_cmd_validate)


def _cmd_validate(args):
    from sweep import _format
    from sweep.sweeps import config, design, preflight, runner

    cfg = config.load(args.config)
    d = design.build(cfg.design, cfg.source)
    out = cfg.outputs
    pre = runner.preflight(cfg, args.output, args.chunk_size)
    _print(f"{args.config}: valid", f"  {d.describe()}",
           f"  stored variables: {', '.join(out.variables)}",
           f"  numerical integration: {'yes' if out.needs_integration else 'no'}; "
           f"approximations evaluated: {', '.join(out.approximations) or 'none'}"
           + (f"; per-point choice: {', '.join(out.composites)}" if out.composites else ""),
           *(f"  {line}" for line in pre.lines()))
    # The run's own checks: a missing GPU, an existing output or saved chunks it would not
    # take are refused here too, before the estimate (it would compute on that device).
    refusal = runner.refusal(cfg, args.output, args.chunk_size, force=args.force,
                             limits=_limits(args))
    if refusal is not None:
        print(f"sweep validate: error: `sweep run` would refuse {args.config}: {refusal}",
              file=sys.stderr)
        return 1
    if not args.no_estimate:
        rate, source, caveats = runner.estimate_rate(cfg, args.output)
        _print(f"  estimated time: {preflight.format_duration(pre.n_points / rate)} at "
               f"{_format.rate(rate)} ({source})", *(f"  caveat: {line}" for line in caveats))
    return 0


def _names(exc: OSError, path: str) -> bool:
    """The error is about the file ``path`` (the same file, however it was spelt)."""
    return exc.filename is not None and Path(os.fspath(exc.filename)) == Path(path)


def _input_fault(args: argparse.Namespace, exc: Exception, path: str) -> int:
    """Print the one line of a fault of the input file ``path`` and return status 1.

    ``cannot read X: not a netCDF file`` where the file cannot be read; an OSError about
    another file (an output that cannot be written) names that file; any other error is
    prefixed by ``path`` (e.g. ``X: not a scene dataset: ...``). With ``--debug``, the
    exception itself, as every other command's.
    """
    if getattr(args, "debug", False):
        raise exc
    if isinstance(exc, OSError) and exc.filename is not None:
        where = f"cannot read {path}" if _names(exc, path) else os.fspath(exc.filename)
        text = f"{where}: {exc.strerror or exc}"
    else:
        text = f"{path}: {_one_line(exc)}"
    print(f"{_command_name(args)}: error: {text}", file=sys.stderr)
    return 1


def _cmd_info(args):
    from sweep import store

    try:
        text = store.summarize(args.path)
    except OSError as exc:
        return _input_fault(args, exc, args.path)
    except ValueError as exc:  # a netCDF file, but not a sweep output
        print(f"sweep info: error: {exc}", file=sys.stderr)
        return 1
    _print(text)  # outside the try: a closed stdout is no fault of the file (main's concern)
    return 0


@contextlib.contextmanager
def _dask_logs_off(args):
    """Keep distributed's log off stderr during a run on a cluster (``--debug``: not).

    Its client logs a lost scheduler or worker, tracebacks included (35 lines for a
    scheduler killed mid-run), where the run says what happened in one line and keeps
    the finished chunks."""
    if args.scheduler is None or getattr(args, "debug", False):
        yield
        return
    previous = logging.root.manager.disable
    logging.disable(logging.CRITICAL)
    try:
        yield
    finally:
        logging.disable(previous)


def _cmd_run(args):
    from sweep.sweeps import runner

    if args.scheduler_timeout is not None and args.scheduler is None:
        # ignored, it would look as if it had bounded something (a local run waits for none)
        args.usage_error(f"argument --scheduler-timeout: applies to --scheduler only, got "
                         f"{args.scheduler_timeout!r}")
    with warnings.catch_warnings(record=True) as caught, _dask_logs_off(args):
        warnings.simplefilter("always", runner.CaveatWarning)
        runner.run(args.config, args.output, restart=args.restart, quiet=args.quiet,
                   chunk_size=args.chunk_size, scheduler=args.scheduler, force=args.force,
                   limits=_limits(args), scheduler_timeout=args.scheduler_timeout,
                   progress_interval=args.progress_interval)
    for w in caught:  # the file is complete: its caveats are warnings, even with --quiet
        if issubclass(w.category, runner.CaveatWarning):
            _say(f"sweep run: warning: {w.message}")
        else:
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    return 0


# --------------------------------------------------------------------------- report

@contextlib.contextmanager
def _writing_stdout():
    """An error writing stdout (``> /dev/full``) names stdout, not a file the command reads
    or writes, and drops stdout: the interpreter's flush at exit would fail again, with a
    traceback. A closed pipe stays a BrokenPipeError (main() leaves quietly)."""
    try:
        with naming(_STDOUT):
            yield
    except OSError:
        _drop_stdout()
        raise


def _print(*lines: str) -> None:
    """Print ``lines`` on stdout (see :func:`_writing_stdout`)."""
    with _writing_stdout():
        for line in lines:
            print(line)


def _print_files(res, heading):
    _print(heading, *(f"  {f}" for f in res["files"]))
    return 0


def _cmd_accuracy(args):
    from sweep.reports.accuracy import accuracy_report

    try:
        res = accuracy_report(args.dataset, args.out)
    except (OSError, ValueError) as exc:
        return _input_fault(args, exc, args.dataset)
    return _print_files(res, f"accuracy report of {args.dataset}: {len(res['files'])} "
                             f"files in {res['out']}")


def _cmd_paper(args):
    from sweep.reports.paper import UndecidedError, paper_report

    try:
        res = paper_report(args.out, n_gamma=args.n_gamma, n_crit=args.n_crit,
                           steps=args.steps, models=args.models, progress=not args.quiet)
    except UndecidedError as exc:   # the settings' fault, not the package's: no traceback
        _say(f"{_command_name(args)}: error: {exc}")
        return 1
    _print(res["markdown"])
    _print_files(res, f"files in {res['out']}:")
    _print(res["summary"])  # last, where a reader of the terminal looks first
    return 0


def _cmd_speed(args):
    from sweep.reports.speed import PEER_SETTINGS, TOLS, speed_report

    peers = [p for p in PEER_SETTINGS if p[0] in args.peers]
    res = speed_report(args.out, n_points=args.n_points, n_peer=args.n_peer,
                       n_check=args.n_check, n_vector=args.n_vector, n_closed=args.n_closed,
                       tols=args.tols or TOLS, ref_steps=args.ref_steps, ref_tol=args.ref_tol,
                       peer_settings=peers, model=args.model, seed=args.seed,
                       repeat=args.repeat, progress=not args.quiet)
    _print(res["markdown"])
    return _print_files(res, f"files in {res['out']}:")


def _add_accuracy_command(sub):
    p = sub.add_parser(
        "accuracy", help="error maps of the approximations stored in a dataset",
        description="For each approximation in DATASET: a heat map of |e_method - "
                    "e_numeric| over (gamma, g~), one panel per (alpha, beta), with the "
                    "numerical stick/rebound boundary and the report's boundary (24); and a "
                    "table of max and median abs error per region.")
    p.add_argument("dataset", metavar="DATASET.nc", help="output of `sweep run`")
    p.add_argument("--out", metavar="DIR",
                   help="output directory (default: DATASET's name + '_accuracy')")
    p.set_defaults(func=_cmd_accuracy)


def _add_paper_command(sub, models):
    p = sub.add_parser(
        "paper", help="the report's Tables 2-5 and Figures 8-11, next to its numbers",
        description="Recompute the report's Tables 2-5 (max abs error of the O(gamma^2) "
                    "approximation with numerical and approximated I, Q) on the report's "
                    "gamma grids, print them next to the published values, and redraw "
                    "Figures 8-11 (g~_c against gamma, bisection on the numerical e versus "
                    "eq. (24)).")
    p.add_argument("--out", metavar="DIR", default="paper_report",
                   help="output directory (default: ./paper_report)")
    p.add_argument("--n-gamma", type=_points(2), default=1000, metavar="N",
                   help="gamma grid points per (model, g~) (default 1000, as the report)")
    p.add_argument("--n-crit", type=_points(), default=100, metavar="N",
                   help="gamma values of Figures 8-11 (default 100, as the report)")
    p.add_argument("--steps", type=_paper_steps, default=None,
                   help="integrator resolution (default: the package default); the step "
                        "budget per point grows with it")
    p.add_argument("--models", nargs="+", choices=models, default=None,
                   help="subset of models (default: all four)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=_cmd_paper)


def _add_speed_command(sub, models):
    p = sub.add_parser(
        "speed", help="work-precision: error against time per point, beside scipy and peers",
        description="Time the engine at several accuracy targets tol, every closed form, "
                    "and the peers a user would otherwise pick (scipy solve_ivp RK45, "
                    "DOP853, LSODA, Radau one point at a time; numbalsoda and diffrax when "
                    "installed) on one common point set against one reference; plot max abs "
                    "error against CPU time per point and against points/s, and report the "
                    "time ratio at equal error. The defaults take a few minutes.")
    p.add_argument("--out", metavar="DIR", default="speed_report",
                   help="output directory (default: ./speed_report)")
    p.add_argument("--n-points", type=_points(), default=20000, metavar="N",
                   help="common point set size (default 20000)")
    p.add_argument("--n-peer", "--n-scipy", dest="n_peer", type=_points(), default=100,
                   metavar="N", help="points of the subset given to the peers (default 100)")
    p.add_argument("--n-vector", type=_points(), default=2000, metavar="N",
                   help="points given to the vectorised peer, diffrax (default 2000)")
    p.add_argument("--n-check", type=_points(), default=100, metavar="N",
                   help="points on which the reference is cross-checked with DOP853")
    p.add_argument("--n-closed", type=_points(), default=2_000_000, metavar="N",
                   help="largest tiled set the closed forms are timed on (default 2000000)")
    p.add_argument("--tols", type=_finite_positive(), nargs="+", metavar="TOL",
                   help="the engine's accuracy targets (default 1e-4 ... 1e-11)")
    p.add_argument("--peers", nargs="+", choices=("scipy", "numbalsoda", "diffrax"),
                   default=["scipy", "numbalsoda", "diffrax"],
                   help="peers to time (default: all; the optional ones when installed)")
    p.add_argument("--ref-steps", type=_resolution(also_half=True), default=1024.0,
                   help="resolution of the reference (default 1024)")
    p.add_argument("--ref-tol", type=_finite_positive(), default=1e-13,
                   help="refinement target of the reference (default 1e-13)")
    p.add_argument("--repeat", type=_positive_int, default=3,
                   help="engine timings are the best of this many (default 3)")
    p.add_argument("--model", choices=models, default="kk",
                   help="contact model of the point set (default kk)")
    p.add_argument("--seed", type=_int_at_least(0), default=0,
                   help="seed of the random point set (default 0)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=_cmd_speed)


def _cmd_error_model(args):
    from sweep.reports import error_model as em

    for option, value, points in (("--sub", args.sub, em.judged_points(args.sub)),
                                  ("--n-validate", args.n_validate, args.n_validate)):
        why = em.memory_refusal(points)
        if why is not None:  # refused before the build, not hours into it
            args.usage_error(f"argument {option}: must fit in memory, got {value}: {why}")
    res = em.error_model_report(args.out, sub=args.sub, n_validate=args.n_validate,
                                progress=not args.quiet)
    _print(res["markdown"])
    return _print_files(res, "files:")


def _add_error_model_command(sub):
    p = sub.add_parser(
        "error-model", help="rebuild and validate the error model of method = \"auto\"",
        description="Measure every closed form against the numerical CoR (the judge, at "
                    "256 steps) over (alpha, beta, gamma, g~), tabulate bounds with a "
                    "safety factor, save them (default: the package's own "
                    "sweep/data/error_model.npz) and check |e_auto - e_judge| <= tol on "
                    "random points in and out of the model.")
    p.add_argument("--out", metavar="FILE.npz", default=None,
                   help="where to write the model (default: the file the package ships)")
    p.add_argument("--sub", type=_points(), default=2, metavar="N",
                   help="samples per cell edge (default 2: 166,026 points judged, about a "
                        "minute; the points grow as N^2 and are all held in memory)")
    p.add_argument("--n-validate", type=_points(0), default=20000, metavar="N",
                   help="random points of the validation (default 20000; 0: none)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=_cmd_error_model, usage_error=p.error)


def add_report_commands(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add ``report {accuracy, paper, speed}`` to an argparse sub-parsers object.

    Each leaf parser gets ``func`` as a default: ``args.func(args)`` runs the report and
    returns the exit status.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        What ``ArgumentParser.add_subparsers()`` returned.

    Returns
    -------
    argparse.ArgumentParser
        The ``report`` parser.
    """
    from sweep.reports.paper_values import PAPER_MODELS  # pure data, no plotting

    rep = subparsers.add_parser(
        "report", help="accuracy maps, the report's tables and figures, speed against error",
        description="Reports built from a sweep dataset, from the report's own test cases, "
                    "or from a timing run. Figures are PNG, tables CSV and markdown.")
    sub = rep.add_subparsers(dest="report", required=True, metavar="REPORT",
                             help="the report to build")
    _add_accuracy_command(sub)
    _add_paper_command(sub, list(PAPER_MODELS))
    _add_speed_command(sub, list(PAPER_MODELS))
    _add_error_model_command(sub)
    return rep


# --------------------------------------------------------------------------- export, example

def _lookup_error_line(err):
    """What ``sweep export`` says of its table's stated error (:meth:`Table.error`)."""
    from sweep import _format

    w, var = err["where"], err["variable"]
    if not err["n_points"] and not err["collapse_cells"]:
        return f"lookup ({var}): one node a material, nothing interpolated, no error to state"
    held = _format.count(err["n_points"], "held-back point")
    line = (f"lookup ({var}, monotone PCHIP) against {var} computed directly (the method's "
            f"own error comes on top): stated error {err['max_abs']:.3g} (at "
            f"{w.get('material')}, v0 = {w.get('v0', 0):.4g} m/s, F = {w.get('F', 0):.4g} "
            f"N); on {held}: max {err['held_back_max_abs']:.3g}, median "
            f"{err['median_abs']:.3g}")
    if err["collapse_cells"]:
        line += (f"; {_format.count(err['collapse_cells'], 'cell')} where e falls to 0 "
                 f"(no rebound), bounded by their largest node, {err['collapse_bound']:.3g}; "
                 f"away from them {err['away_max_abs']:.3g}")
    return line


def _cmd_export(args):
    from sweep import tables

    if args.no_check and args.variable is not None:
        args.usage_error(f"argument --variable: names the variable of the lookup check, "
                         f"which --no-check skips, got {args.variable!r}")
    fmt = "csv" if args.csv else "npz"
    out = args.output or str(Path(args.dataset).with_suffix("." + fmt))
    try:
        # The table first: a bad --variable is refused before any file is written.
        table = None if args.no_check else tables.Table(args.dataset, args.variable)
        err = None if table is None else table.error()
        written = tables.export(args.dataset, out, fmt, error=err)
        _print(f"wrote {written}")
        if err is not None:
            _print(_lookup_error_line(err))
    except BrokenPipeError:  # stdout closed, the dataset is fine: main() handles it
        raise
    except (OSError, ValueError) as exc:
        return _input_fault(args, exc, args.dataset)
    return 0


def _add_export_command(sub):
    p = sub.add_parser(
        "export", help="a scene's e(v0, F) table as CSV or NumPy .npz",
        description="Write the table of a scene dataset (dimensions material, v0, F) for "
                    "simulation codes, and report the interpolation error of a lookup in it "
                    "(sweep.lookup) against direct computation on held-back points.")
    p.add_argument("dataset", metavar="SCENE.nc", help="output of `sweep run` on a scene")
    fmt = p.add_mutually_exclusive_group(required=True)
    fmt.add_argument("--csv", action="store_true", help="CSV, one row per (material, v0, F)")
    fmt.add_argument("--npz", action="store_true", help="NumPy .npz, arrays on (material, "
                                                        "v0, F)")
    p.add_argument("-o", "--output", metavar="OUT", help="output file, written at exactly "
                   "this path (default: SCENE with the format's suffix)")
    p.add_argument("--variable", default=None, help="e_<method> variable the lookup check "
                                                    "interpolates (default e_numeric, else "
                                                    "e_auto)")
    p.add_argument("--no-check", action="store_true", help="skip the interpolation check")
    p.set_defaults(func=_cmd_export, usage_error=p.error)


def _bounce_conflict(args):
    """The first option ``sweep example bounce`` would ignore in this combination, as a
    message (None: none). Dropped silently, it would look as if it had counted."""
    from sweep import registry

    method = args.method or "numeric"
    if args.material is not None and args.scene is None:
        return ("argument --material: needs --scene (it picks a material of a scene "
                f"config; the default bead is the report's steel ball), got {args.material!r}")
    if args.cor == "lookup" and (args.method is not None or args.tol is not None):
        given = "--method" if args.method is not None else "--tol"
        return (f"argument {given}: applies to --cor direct only (a lookup table's CoR is "
                "the one it stores: e_numeric, else e_auto, else its first e_<method>)")
    if args.cor == "direct" and args.table is not None:
        return f"argument --table: applies to --cor lookup only, got {args.table!r}"
    takes_tol = [m.name for m in registry.METHODS.values()
                 if any(opt.name == "tol" for opt in m.options)]
    if args.tol is not None and method not in takes_tol:
        return (f"argument --tol: --method {method} takes no tol (methods with one: "
                f"{', '.join(takes_tol)})")
    return None


def _cmd_bounce(args):
    from sweep import examples

    conflict = _bounce_conflict(args)
    if conflict is not None:
        args.usage_error(conflict)  # exits 2, as argparse does for any bad argument
    material, g = examples.STEEL_BALL, 9.81
    if args.scene:
        material, g = examples.scene_material(args.scene, args.material)
    try:
        v_hit = examples.first_impact_speed(args.height, g)
    except ValueError as exc:
        args.usage_error(f"argument --height: {exc}, got {args.height!r}")
    if args.cor == "lookup" and args.table is None and not args.v_stop < v_hit:
        # the table built on the fly spans [--v-stop, first impact speed]: it would be empty
        args.usage_error(f"argument --v-stop: must be < the first impact speed {v_hit:.6g} "
                         f"m/s with --cor lookup, got {args.v_stop!r}")
    options = {"tol": args.tol} if args.tol is not None else {}
    try:
        res = examples.bounce_example(args.out, material, h0=args.height, g=g,
                                      source=args.cor, table=args.table,
                                      method=args.method or "numeric", v_stop=args.v_stop,
                                      **options)
    except ValueError as exc:  # what the options cannot show, e.g. a scale (2) overflow
        print(f"sweep example bounce: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        if args.table is None or not _names(exc, args.table):
            raise               # a file of --out: main() names it
        return _input_fault(args, exc, args.table)
    _print(res["summary"])
    return _print_files(res, f"files in {args.out}:")


def _add_example_commands(sub):
    from sweep import registry

    ex = sub.add_parser("example", help="worked examples (the bouncing ball)")
    exs = ex.add_subparsers(dest="example", required=True, metavar="EXAMPLE",
                            help="the example to run")
    p = exs.add_parser(
        "bounce", help="a ball dropped from 1 m, each impact's CoR from the engine",
        description="Drop a bead (default: the report's steel ball, KK) from a height and "
                    "follow its bounces until it no longer rebounds (e = 0) or rebounds "
                    "slower than --v-stop; each impact's CoR comes from the engine, directly "
                    "or from a lookup table. Writes bounce_height.png, bounce_impacts.png "
                    "and bounce_impacts.csv.")
    p.add_argument("--out", metavar="DIR", default="bounce", help="output directory")
    p.add_argument("--cor", choices=("direct", "lookup"), default="direct",
                   help="CoR per impact: sweep.cor, or a lookup table (default direct)")
    p.add_argument("--table", metavar="SCENE.nc", help="lookup table of --cor lookup (a "
                   "scene dataset at F = 0 holding the material; default: built on the fly)")
    p.add_argument("--scene", metavar="CONFIG", help="take the material from a scene config")
    p.add_argument("--material", metavar="NAME", help="material of --scene (default: first)")
    p.add_argument("--height", type=_finite_positive(" [m]"), default=1.0,
                   help="drop height [m] (default 1)")
    # default None, not "numeric": --method given with --cor lookup is refused
    p.add_argument("--method", choices=tuple(registry.METHODS), default=None,
                   help="method of --cor direct (default numeric; e.g. auto)")
    p.add_argument("--tol", type=_finite_positive(), default=None,
                   help="tol of --method auto or numeric (largest abs error on e wanted)")
    p.add_argument("--v-stop", type=_finite_positive(" [m/s]"), default=1e-5,
                   help="rest: rebound speed below this [m/s] (default 1e-5)")
    p.set_defaults(func=_cmd_bounce, usage_error=p.error)


# --------------------------------------------------------------------------- entry point

def build_parser() -> argparse.ArgumentParser:
    """The ``sweep`` argument parser, every subcommand included.

    Returns
    -------
    argparse.ArgumentParser
        Parsed arguments carry ``func``, the handler of the chosen subcommand.
    """
    parser = _Parser(
        prog="sweep",
        description="Parameter sweeps of the coefficient of restitution of a bead on a "
                    "nonlinear visco-elastic contact (Chatterjee, James, Brogliato 2021).")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}",
                        help="print the version of sweep and exit")
    parser.add_argument("--debug", action="store_true",
                        help="show the traceback of an error instead of a one-line message")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                help="what to do (sweep COMMAND --help for its options)")
    _add_run_command(sub)
    _add_info_and_validate_commands(sub)
    add_report_commands(sub)
    _add_export_command(sub)
    _add_example_commands(sub)
    for leaf in _leaf_parsers(parser):
        # "before or after the subcommand" (module docstring) for every command, not only
        # those that added it themselves (report, export and example had it before only).
        if "--debug" not in leaf._option_string_actions:
            _add_debug(leaf)
    return parser


def _leaf_parsers(parser: argparse.ArgumentParser):
    """The parsers of the commands that run something (no subcommand of their own)."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield parser
    for action in subs:
        for child in dict.fromkeys(action.choices.values()):   # aliases: once each
            yield from _leaf_parsers(child)


class _Terminated(KeyboardInterrupt):
    """SIGTERM (e.g. a batch system's time limit) or SIGHUP (the terminal closed): it
    unwinds like Ctrl-C, finished chunks already saved and the half-assembled file closed,
    and exits as a shell reports a command killed by that signal, 128 + its number (143,
    129; not Ctrl-C's 130)."""

    def __init__(self, signum: int = signal.SIGTERM) -> None:
        super().__init__(signum)
        self.signum = int(signum)


def _terminate(signum, frame):
    raise _Terminated(signum)


def _drop_stdout() -> None:
    """Point stdout at devnull, Python's own recipe (its ``signal`` docs, "Note on
    SIGPIPE"): the interpreter's flush at exit does not fail again and print a traceback."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # stdout is no file (embedded, captured)
        pass


def _stdout_closed() -> int:
    """Leave quietly once the reader of stdout has gone (``sweep info X | head``), with the
    status a shell gives a command killed by SIGPIPE, 128 + 13 (stdout dropped first)."""
    _drop_stdout()
    return 128 + getattr(signal, "SIGPIPE", 13)


def _say(line: str) -> None:
    """Print ``line`` on stderr if it can still be written: a stderr that failed (its
    reader left, a full disk) changes no exit status and adds no traceback."""
    with contextlib.suppress(OSError, ValueError):
        print(line, file=sys.stderr, flush=True)


def _one_line(exc: BaseException) -> str:
    """The message of an error on one line, naming the file of an OSError."""
    if isinstance(exc, OSError) and exc.filename is not None:
        text = f"{exc.filename}: {exc.strerror or exc}"
    else:
        text = str(exc) or type(exc).__name__
    return " ".join(text.split())


def _expected_errors():
    """Faults of the input or the environment: reported as one line, no traceback."""
    from sweep.store import ResumeError
    from sweep.sweeps.config import ConfigError
    from sweep.sweeps.runner import RunError

    return (ConfigError, ResumeError, RunError, OSError)


def _command_name(args: argparse.Namespace) -> str:
    """The command as typed (``sweep report paper``), as argparse's own error lines say it."""
    sub = getattr(args, "report", None) or getattr(args, "example", None)
    return f"sweep {args.command}" + (f" {sub}" if sub else "")


def _closed_streams_to_devnull() -> None:
    """Python starts without sys.stdout or sys.stderr where that descriptor is closed
    (``>&-``, ``2>&-``, some daemons): they become os.devnull, so that the messages are
    dropped as from a stream that failed (a print to a None stderr lands on stdout, and a
    flush of a None stdout failed a complete run as "unexpected AttributeError")."""
    for name in ("stdout", "stderr"):
        if getattr(sys, name) is None:
            setattr(sys, name, open(os.devnull, "w", encoding="utf-8"))  # noqa: SIM115


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``sweep`` console script.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status.
    """
    _closed_streams_to_devnull()
    try:
        args = build_parser().parse_args(argv)
    except KeyboardInterrupt:  # during start-up: the parser imports the reports (numba)
        _say("sweep: interrupted")
        return 130
    stopping = contextlib.nullcontext()
    if args.command == "run":
        from sweep.sweeps import runner

        stopping = runner.signals_handled(_terminate, runner.STOP_SIGNALS)
    try:
        with stopping:
            status = args.func(args)
        with _writing_stdout():
            sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's exit
        return status
    except BrokenPipeError:  # before Exception: it is an OSError, not the input's fault
        return _stdout_closed()
    except _Terminated as stop:
        from sweep.sweeps.runner import STOP_SIGNALS

        _say(f"sweep: {STOP_SIGNALS.get(stop.signum, 'terminated')}")
        return 128 + stop.signum
    except KeyboardInterrupt:
        _say("sweep: interrupted")
        return 130
    except Exception as exc:
        if getattr(args, "debug", False):
            raise
        kind = "" if isinstance(exc, _expected_errors()) else f"unexpected {type(exc).__name__}: "
        _say(f"{_command_name(args)}: error: {kind}{_one_line(exc)}"
             + (" (rerun with --debug for the traceback)" if kind else ""))
        return 1


if __name__ == "__main__":  # python -m sweep.cli
    sys.exit(main())
