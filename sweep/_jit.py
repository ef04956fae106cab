"""Where compiled kernels are cached, keyed by the package's source.

numba's ``cache=True`` checks only the modification time of the file that defines a cached
function, not of the modules it calls into: an edit to the step function would keep serving
the old machine code. Kernel modules are therefore imported (and their dispatchers created,
which is when numba picks the cache location) while ``numba.config.CACHE_DIR`` points to a
directory named after a hash of the kernel sources (every module defining jitted functions,
and the package modules those import, transitively) and the numba version. Editing the CLI or the
store does not invalidate compiled kernels. The user's own setting is restored right after.
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import re
from pathlib import Path

import numba

_PACKAGE_DIR = Path(__file__).resolve().parent


_IMPORT = re.compile(r"^\s*(?:from\s+sweep\.(\w+)\s+import|import\s+sweep\.(\w+))", re.MULTILINE)


def kernel_sources() -> list[Path]:
    """Modules whose text can change compiled code: those defining jitted functions, and
    the package modules they import (transitively)."""
    sources = {p.stem: p.read_text(encoding="utf-8") for p in _PACKAGE_DIR.glob("*.py")}
    todo = [name for name, text in sources.items() if re.search(r"\bnjit\b", text)]
    seen = set()
    while todo:
        name = todo.pop()
        if name in seen or name not in sources:
            continue
        seen.add(name)
        todo.extend(a or b for a, b in _IMPORT.findall(sources[name]))
    return sorted(_PACKAGE_DIR / f"{name}.py" for name in seen)


def source_hash() -> str:
    """Hash of the kernel sources (:func:`kernel_sources`) and the numba version."""
    h = hashlib.sha256(numba.__version__.encode())
    for path in kernel_sources():
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def cache_dir() -> Path:
    """Cache directory for this exact source tree (``$NUMBA_CACHE_DIR`` or ``~/.cache``)."""
    base = os.environ.get("NUMBA_CACHE_DIR") or os.environ.get("XDG_CACHE_HOME") \
        or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "sweep-numba" / source_hash()


@contextlib.contextmanager
def kernel_cache():
    """Context in which ``@njit(cache=True)`` dispatchers cache under :func:`cache_dir`."""
    previous = numba.config.CACHE_DIR
    try:
        path = cache_dir()
        path.mkdir(parents=True, exist_ok=True)
        numba.config.CACHE_DIR = str(path)
    except OSError:  # unwritable home: numba falls back to its own locations
        yield
        return
    try:
        yield
    finally:
        numba.config.CACHE_DIR = previous
