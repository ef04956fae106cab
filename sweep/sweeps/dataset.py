"""``sweep.run``: a sweep as an ``xarray.Dataset``, from a notebook or a script.

Owns :func:`run`, the Python counterpart of ``sweep run``: a configuration in any form
(:func:`sweep.sweeps.config.as_config`) in, the dataset out -- computed in memory by
:func:`sweep.sweeps.runner.run_in_memory` (nothing written), or written by
:func:`sweep.sweeps.runner.run` and opened when ``out=`` is given. Either way the same
driver, kernels, chunks, attributes and progress as the command line.

Floor 4: may import :mod:`sweep.sweeps.config` and :mod:`sweep.sweeps.runner`, and xarray
lazily (``import sweep`` does not load it).
"""
from __future__ import annotations

import os
from typing import Any

from sweep.sweeps import config as _config
from sweep.sweeps import runner as _runner

__all__ = ["run"]


def run(config: Any, *, out: str | os.PathLike | None = None, **run_options: Any) -> Any:
    """Run a sweep and return its dataset.

    Parameters
    ----------
    config : path-like, str, dict or sweep.sweeps.config.Config
        The configuration: a file, TOML text, the same tables as a dict, or a parsed one
        (see :func:`sweep.sweeps.config.as_config`).
    out : path-like, optional
        Write the dataset to this netCDF file, as ``sweep run CONFIG -o OUT`` does (lock,
        resume, atomic publication), and return it opened from the file. Without it the
        dataset is computed in memory and nothing is written: no file, no partial
        directory, no lock, and no resume (an interrupted in-memory run starts again).
    **run_options
        Keyword options of :func:`sweep.sweeps.runner.run`: ``quiet``, ``chunk_size``,
        ``scheduler``, ``log``, ``force``, ``limits``, ``scheduler_timeout``,
        ``progress_interval``; and with ``out=`` also ``restart``.

    Returns
    -------
    xarray.Dataset
        Dimensions, coordinates, variables and attributes as ``sweep run`` writes them
        and ``xarray.open_dataset`` reads them back (identical but for the run-dependent
        attributes, :data:`sweep.sweeps.runner.VOLATILE_ATTRS`). In memory: loaded,
        numpy-backed. With ``out=``: lazily read from the file (``.load()`` reads it, and
        ``.close()`` releases it).

    Raises
    ------
    sweep.sweeps.config.ConfigError
        An invalid configuration, with the message ``sweep validate`` gives.
    sweep.sweeps.runner.RunError
        Refused by the preflight (e.g. a dataset larger than this machine's memory), an
        output that cannot be written, an unreachable scheduler.
    TypeError
        ``restart`` without ``out=``, or an option :func:`sweep.sweeps.runner.run` does
        not take.

    Examples
    --------
    >>> ds = sweep.run("configs/report_kk.toml", quiet=True)        # doctest: +SKIP
    >>> ds.e_numeric.sel(gtilde=1.0).plot(x="gamma")                 # doctest: +SKIP
    """
    if out is None and "restart" in run_options:
        # Said here: run_in_memory's own TypeError would name a function the caller never saw.
        raise TypeError("restart= needs out=: an in-memory run writes nothing and has "
                        "nothing to resume or restart")
    cfg = _config.as_config(config)
    if out is None:
        dataset, _ = _runner.run_in_memory(cfg, **run_options)
        return dataset
    import xarray as xr

    _runner.run(cfg, out, **run_options)
    return xr.open_dataset(out)
