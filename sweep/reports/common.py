"""Helpers every report shares: the plotting backend, the machine description, tables.

Owns :func:`use_agg` (matplotlib with the Agg backend, imported on demand so that importing
a report stays fast), :func:`machine_description` / :func:`machine_line` (where numbers were
measured), :func:`format_value` and :func:`write_table` (CSV at full precision, markdown at a
few digits), :func:`log_progress`, :func:`make_out_dir` (an output directory, checked
writable before a report computes) and :func:`staged` (a report's files published together).

Floor 5 (the reports' ground): may import numpy, scipy, numba, matplotlib (lazily) and the
package's public api (:func:`sweep.integrate`, lazily, to learn numba's threading layer)
and :mod:`sweep.store` (:func:`sweep.store.same_file` and :func:`sweep.store.commit`,
lazily);
never another report module, the runner's command line or argparse.
"""
from __future__ import annotations

import contextlib
import csv
import errno
import math
import os
import platform
import sys
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

__all__ = ["use_agg", "machine_description", "machine_line", "format_value", "write_table",
           "log_progress", "make_out_dir", "staged"]


def log_progress(progress: bool, msg: str) -> None:
    """Print ``msg`` to stderr (flushed) if ``progress`` is true."""
    if progress:
        print(msg, file=sys.stderr, flush=True)


def make_out_dir(out: str | os.PathLike, dataset: str | os.PathLike | None = None) -> Path:
    """Create a report's output directory ``out`` (parents included) and return it.

    Raises
    ------
    ValueError
        ``out`` is the input ``dataset`` itself (mkdir's "File exists" named the input,
        which the command line then called unreadable).
    NotADirectoryError
        ``out`` is an existing file: one line saying so, not mkdir's "File exists".
    OSError
        No file can be created in ``out`` (named): said before the report computes, not
        when it writes, after the whole computation.
    """
    from sweep import store  # noqa: PLC0415 -- lazily: importing a report stays fast

    out = Path(out)
    if dataset is not None and out.exists() and store.same_file(out, dataset):
        raise ValueError("the output directory cannot be the dataset itself")
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, "is a file, not an output directory",
                                 os.fspath(out))
    out.mkdir(parents=True, exist_ok=True)
    _check_writable(out)
    return out


def _check_writable(directory: Path) -> None:
    """Raise OSError naming ``directory`` where no file can be created in it.

    A file is created and removed: os.access says yes to root in a read-only place (a
    read-only mount, /sys), and the error of the probe names its random file name.
    """
    try:
        with tempfile.TemporaryFile(dir=directory):
            pass
    except OSError as exc:
        raise OSError(exc.errno, f"cannot create a file in this directory ({exc.strerror})",
                      os.fspath(directory)) from exc


@contextlib.contextmanager
def staged(out: Path) -> Iterator[Callable[[str], Path]]:
    """Write a report's files under temporary names in ``out``, then publish them together.

    A report that fails part-way (Ctrl-C, a full disk, a figure that cannot be drawn) must
    leave no new file: neither a half-written one nor complete ones beside the previous
    run's files that they would contradict.

    Parameters
    ----------
    out : Path
        The report's directory (:func:`make_out_dir`).

    Yields
    ------
    callable
        ``stage(name) -> Path``: where to write the file ``out / name`` for now (its suffix
        kept: numpy and matplotlib choose the format by it). When the block ends, every
        staged file is renamed onto its name (:func:`sweep.store.commit`); when it raises,
        they are all removed.
    """
    from sweep import store  # noqa: PLC0415 -- lazily: importing a report stays fast

    names: dict[Path, Path] = {}

    def stage(name: str) -> Path:
        final = out / name
        names[final] = final.with_name(f"{final.stem}.tmp{os.getpid()}{final.suffix}")
        return names[final]

    try:
        yield stage
        for final, tmp in names.items():
            store.commit(tmp, final)
    finally:
        for tmp in names.values():   # a committed one is gone; the others were not published
            with contextlib.suppress(OSError):
                tmp.unlink()


def use_agg() -> Any:
    """Import matplotlib with the non-interactive Agg backend.

    Returns
    -------
    module
        ``matplotlib.pyplot``.
    """
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _cpu_model():
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_description() -> dict[str, Any]:
    """Where the numbers were measured: CPU, cores, numba threading, versions.

    Runs a tiny parallel integration first so that numba's threading layer is known.

    Returns
    -------
    dict
        ``cpu``, ``logical_cores``, ``usable_cores``, ``numba_threads``,
        ``threading_layer``, versions, ``platform`` and ``load_average``.
    """
    import numba
    import numpy as np
    import scipy

    import sweep

    try:
        sweep.integrate(1.5, 1.5, np.full(2048, 0.01), 0.1, parallel=True)
        layer = numba.threading_layer()
    except Exception as exc:  # pragma: no cover - no parallel layer available
        layer = f"unavailable ({exc.__class__.__name__})"
    try:
        affinity = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        affinity = os.cpu_count()
    return {
        "cpu": _cpu_model(),
        "logical_cores": os.cpu_count(),
        "usable_cores": affinity,
        "numba_threads": numba.get_num_threads(),
        "threading_layer": layer,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "sweep": sweep.__version__,
        "platform": platform.platform(),
        "load_average": _loadavg(),
    }


def _loadavg():
    """1-minute load average when measured (other processes compete for the cores)."""
    try:
        return round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):  # pragma: no cover - not Unix
        return None


def machine_line(m: Mapping[str, Any]) -> str:
    """One-line form of :func:`machine_description` (its returned dict ``m``)."""
    return (f"{m['cpu']}, {m['usable_cores']} usable cores ({m['numba_threads']} numba "
            f"threads, {m['threading_layer']} layer); Python {m['python']}, numpy "
            f"{m['numpy']}, scipy {m['scipy']}, numba {m['numba']}, sweep {m['sweep']}; "
            f"{m['platform']}; load average {m.get('load_average')} at start")


def format_value(x: Any, digits: int = 3) -> str:
    """Compact text of a table value: ``-`` for None, ``nan``, ``0``, or ``1.23e-04``.

    Strings, booleans and integers are written as they are; other numbers with ``digits``
    significant digits in exponent form.
    """
    if x is None:
        return "-"
    if isinstance(x, str):
        return x
    if isinstance(x, (bool,)):
        return str(x)
    if isinstance(x, int):
        return str(x)
    x = float(x)
    if math.isnan(x):
        return "nan"
    if x == 0.0:
        return "0"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:.{digits - 1}e}"


def write_table(rows: Sequence[Mapping[str, Any]], columns: Sequence[str],
                csv_path: str | os.PathLike | None = None,
                md_path: str | os.PathLike | None = None, title: str | None = None,
                notes: Sequence[str] = (), digits: int = 3,
                formats: Mapping[str, str] | None = None) -> str:
    """Write rows (dicts) as CSV (full precision) and/or markdown (``digits`` digits).

    Parameters
    ----------
    rows : sequence of dict
        One dict per row; missing keys are empty cells.
    columns : sequence of str
        Columns, in order.
    csv_path, md_path : path-like, optional
        Where to write the CSV and the markdown (neither: only return the markdown).
    title : str, optional
        Markdown heading (``###``).
    notes : sequence of str
        Bullet points after the markdown table.
    digits : int
        Significant digits of the markdown numbers (see :func:`format_value`).
    formats : dict, optional
        Column -> format spec for the markdown (e.g. ``{"alpha": "g"}``).

    Returns
    -------
    str
        The markdown text.
    """
    formats = dict(formats or {})
    formats.setdefault("alpha", "g")
    formats.setdefault("beta", "g")

    def cell(r, c):
        v = r.get(c)
        if c in formats and isinstance(v, (float, int)) and not isinstance(v, bool):
            return format(v, formats[c])
        return format_value(v, digits)

    if csv_path is not None:
        with open(csv_path, "w", newline="", encoding="utf-8") as f:
            w = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
            w.writeheader()
            for r in rows:
                w.writerow({c: ("" if r.get(c) is None else
                                (repr(float(r[c])) if isinstance(r.get(c), float) else r[c]))
                            for c in columns})
    lines = []
    if title:
        lines += [f"### {title}", ""]
    lines.append("| " + " | ".join(columns) + " |")
    lines.append("|" + "|".join("---" for _ in columns) + "|")
    for r in rows:
        lines.append("| " + " | ".join(cell(r, c) for c in columns) + " |")
    if notes:
        lines.append("")
        lines += [f"- {n}" for n in notes]
    text = "\n".join(lines) + "\n"
    if md_path is not None:
        Path(md_path).write_text(text, encoding="utf-8")
    return text
