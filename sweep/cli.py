"""Command line: ``sweep run | info | validate``.

::

    sweep run CONFIG [-o OUT.nc] [--resume | --restart] [--quiet] [--scheduler ADDR]
    sweep info OUT.nc
    sweep validate CONFIG

Exit status: 0 success, 1 invalid configuration or refused resume, 130 interrupted
(the finished chunks are kept; rerun the same command to resume).
"""
from __future__ import annotations

import argparse
import signal
import sys

__all__ = ["main", "build_parser"]


def build_parser():
    parser = argparse.ArgumentParser(
        prog="sweep",
        description="Parameter sweeps of the coefficient of restitution of a bead on a "
                    "nonlinear visco-elastic contact (Chatterjee, James, Brogliato 2021).")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("run", help="run a sweep configuration and write a netCDF dataset",
                       description="Run the sweep described by CONFIG. An interrupted run "
                                   "resumes from its finished chunks when the same command "
                                   "is run again.")
    p.add_argument("config", metavar="CONFIG", help="TOML configuration file")
    p.add_argument("-o", "--output", metavar="OUT.nc",
                   help="output netCDF file (default: CONFIG's name with .nc, in the "
                        "current directory)")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--resume", dest="restart", action="store_false", default=False,
                      help="resume from saved chunks if any (default)")
    mode.add_argument("--restart", dest="restart", action="store_true",
                      help="discard saved chunks and an existing output, start afresh")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no progress bar and no messages")
    p.add_argument("--chunk-size", type=int, metavar="N",
                   help="points per chunk (default: the configuration's run.chunk_size)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="Dask scheduler address (tcp://host:port): run the chunks on that "
                        "cluster instead of locally")

    p = sub.add_parser("info", help="describe an output dataset",
                       description="Print the dimensions, variables with summary "
                                   "statistics, and settings of a sweep output.")
    p.add_argument("path", metavar="OUT.nc")

    p = sub.add_parser("validate", help="check a configuration without running it")
    p.add_argument("config", metavar="CONFIG")

    from sweep.reports import add_report_commands  # noqa: PLC0415 -- plotting stays lazy
    add_report_commands(sub)
    return parser


def _cmd_validate(args):
    from sweep.sweeps import config, design

    cfg = config.load(args.config)
    d = design.build(cfg.design)
    out = cfg.outputs
    print(f"{args.config}: valid")
    print(f"  {d.describe()}")
    print(f"  stored variables: {', '.join(out.variables)}")
    print(f"  numerical integration: {'yes' if out.needs_integration else 'no'}; "
          f"approximations evaluated: {', '.join(out.approximations) or 'none'}")
    return 0


def _cmd_info(args):
    from sweep import store

    try:
        print(store.summarize(args.path))
    except (OSError, FileNotFoundError) as exc:
        print(f"sweep info: cannot read {args.path}: {exc}", file=sys.stderr)
        return 1
    return 0


def _cmd_run(args):
    from sweep.sweeps import runner

    runner.run(args.config, args.output, restart=args.restart, quiet=args.quiet,
               chunk_size=args.chunk_size, scheduler=args.scheduler)
    return 0


def _terminate(signum, frame):
    # SIGTERM (e.g. a batch system's time limit) unwinds like Ctrl-C: finished chunks are
    # already saved, and the half-assembled file is closed.
    raise KeyboardInterrupt


def main(argv=None):
    """Entry point of the ``sweep`` console script; returns the exit status."""
    args = build_parser().parse_args(argv)
    from sweep.sweeps.config import ConfigError
    from sweep.store import ResumeError

    handlers = {"run": _cmd_run, "info": _cmd_info, "validate": _cmd_validate,
                "report": lambda a: a.func(a)}
    previous = None
    if args.command == "run":
        try:
            previous = signal.signal(signal.SIGTERM, _terminate)
        except ValueError:  # not the main thread (embedded use): leave signals alone
            previous = None
    try:
        return handlers[args.command](args)
    except (ConfigError, ResumeError) as exc:
        print(f"sweep {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("sweep: interrupted", file=sys.stderr)
        return 130
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # python -m sweep.cli
    sys.exit(main())
