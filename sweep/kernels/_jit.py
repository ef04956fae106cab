"""Where compiled kernels are cached, keyed by the source they are compiled from.

numba's ``cache=True`` checks only the modification time of the file that defines a cached
function, not of the modules it calls into: an edit to the step function would keep serving
the old machine code. Kernel modules are therefore imported (and their dispatchers created,
which is when numba picks the cache location) while ``numba.config.CACHE_DIR`` points to a
directory named after a hash of the kernel sources and the numba version.

The kernel sources are the modules of :mod:`sweep.kernels` and every package module they
import, transitively, whatever the import form (``import sweep.x``, ``from sweep import x``,
``from sweep.x import y``, ``from . import x``, ``from .x import y``), read from the syntax
tree, not by pattern. Editing the CLI, the store or the reports does not invalidate compiled
kernels. The user's own setting is restored right after.

While numba compiles one of the package's kernels, Python's cyclic garbage collector runs
with relaxed thresholds (:data:`COMPILE_GC_THRESHOLDS`, through numba's public
``numba:compile`` event): a compile allocates millions of objects, and the collections they
triggered took a tenth of the first compile. Meanwhile numba's inliner splices in the IR it
built for the call site without copying it (:func:`_skip_fresh_copies`) and copies other
callees with one memo for all their blocks (:func:`_share_inline_copies`); a helper that
only kernels call gets no machine code and no module passes of its own: the kernel's run
once over all it links (:func:`_leave_helpers_unemitted`); an
operator on scalars is not matched against numpy's ufunc loops first
(:func:`_scalar_operators_skip_ufuncs`); compile flags hash and compare faster
(:func:`_quick_flag_comparisons`); numba's SSA reconstruction rewrites, for each variable,
only the blocks that name it (:func:`_ssa_visits_mentioning_blocks`), and finds live
variables on bit sets (:func:`_liveness_on_bit_sets`) and the variables an instruction
names with fewer calls (:func:`_quick_instruction_vars`); a type's ABI size is asked of LLVM
once (:func:`_abi_sizes_remembered`); and the llvmlite IR handed to LLVM is taken apart when
the compile ends, for reference counting to free (:func:`_llvm_ir_taken_apart`). Each of
these patches of numba's internals applies to the numba release and sources it was written
for only (:data:`PATCHED_NUMBA`). A compile that a call from Python starts runs under a
frame with a chunk of CPython's frame stack to itself (:func:`on_own_chunk`).

Owns: the kernel cache location and the compile-time settings. May import:
:mod:`sweep.kernels._numba_ir` only.
"""
from __future__ import annotations

import ast
import contextlib
import copy
import functools
import gc
import hashlib
import inspect
import os
import threading
import types
import weakref
from collections.abc import Iterator
from pathlib import Path

import numba
from numba.core import event as _event
from numba.core.registry import CPUDispatcher

from sweep.kernels import _numba_ir

__all__ = ["kernel_sources", "source_hash", "cache_dir", "kernel_cache", "package_imports",
           "jit", "cached_jit", "on_own_chunk", "FLAGS", "COMPILE_GC_THRESHOLDS",
           "PATCHED_NUMBA", "INLINE_IR_SOURCES", "INLINE_FUNCTION_SOURCES",
           "EXECUTABLE_SOURCES", "ARRAY_OPERATOR_SOURCES", "TARGET_CONFIG_SOURCES",
           "SSA_SOURCES", "LIVE_MAP_SOURCES", "LIST_VARS_SOURCES",
           "ABI_SIZE_SOURCES", "ADD_IR_SOURCES", "OWN_CHUNK_SLOTS"]

_PACKAGE_DIR = Path(__file__).resolve().parents[1]
_PACKAGE = _PACKAGE_DIR.name
_KERNELS = "kernels"


def _module_files(root: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package under ``root``."""
    files = {}
    for path in root.rglob("*.py"):
        parts = path.relative_to(root.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        files[".".join(parts)] = path
    return files


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    """Absolute name of the module an ``ImportFrom`` node reads from."""
    if not node.level:
        return node.module or ""
    base = module.split(".")
    if not is_package:
        base = base[:-1]
    base = base[:len(base) - node.level + 1] if node.level > 1 else base
    return ".".join(base + ([node.module] if node.module else []))


def package_imports(module: str, path: Path, known: dict[str, Path]) -> set[str]:
    """Package modules that ``module`` (source at ``path``) imports, in any form.

    ``from P import x`` counts ``P.x`` when that is a module of the package, and ``P``
    itself otherwise (a name defined in ``P``'s ``__init__``).
    """
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    is_package = path.name == "__init__.py"
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(module, is_package, node)
            names = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base
                     for alias in node.names]
        else:
            continue
        for name in names:
            while name and name not in known:
                name = name.rpartition(".")[0]
            if name and name != module:
                found.add(name)
    return found


def kernel_sources(root: Path | None = None) -> list[Path]:
    """Files whose text can change compiled code: the kernel modules and the package
    modules they import, transitively (the package ``__init__`` only for names it defines).

    Parameters
    ----------
    root : Path, optional
        Package directory (default: this installed package); tests pass a copy.
    """
    root = Path(root) if root is not None else _PACKAGE_DIR
    known = _module_files(root)
    package = root.name
    todo = [m for m in known if m.startswith(f"{package}.{_KERNELS}")]
    seen: set[str] = set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        todo.extend(package_imports(name, known[name], known))
    return sorted(known[name] for name in seen)


def source_hash(root: Path | None = None) -> str:
    """Hash of the kernel sources (:func:`kernel_sources`) and the numba version."""
    root = Path(root) if root is not None else _PACKAGE_DIR
    h = hashlib.sha256(numba.__version__.encode())
    for path in kernel_sources(root):
        h.update(path.relative_to(root).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def cache_dir() -> Path:
    """Cache directory for this exact source tree (``$NUMBA_CACHE_DIR`` or ``~/.cache``)."""
    return _cache_dir(os.environ.get("NUMBA_CACHE_DIR"), os.environ.get("XDG_CACHE_HOME"))


@functools.lru_cache(maxsize=4)
def _cache_dir(numba_cache: str | None, xdg_cache: str | None) -> Path:
    # Hashing parses every kernel source: once per process (sources do not change under it).
    base = numba_cache or xdg_cache or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "sweep-numba" / source_hash()


@contextlib.contextmanager
def kernel_cache() -> Iterator[None]:
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


#: Compilation flags of every kernel. numpy's error model: a division by zero gives inf or
#: NaN (which the kernels test for and turn into a status) instead of raising
#: ZeroDivisionError out of a parallel loop and losing the whole call. nogil: a serial
#: kernel called from a Python thread (Dask workers, a GUI) lets the others run. Of
#: fastmath's flags only ``contract``: ``a * b + c`` may become one fused multiply-add (one
#: rounding instead of two; 4-6% less time a point, KK to general exponents and heavy
#: damping, measured interleaved on 2026-12-02), which the GPU's compiler does anyway.
#: None of the others: ``nnan``/``ninf`` would drop the finiteness tests,
#: ``reassoc``/``arcp`` change values with the compiler's whims. What is contracted is
#: fixed when a kernel compiles, so results stay bit-identical whatever the thread count,
#: block or order; on a CPU without FMA they differ from these in the last bits.
FLAGS = {"error_model": "numpy", "nogil": True, "fastmath": {"contract"}}


def jit(entry: bool = False, counted: bool = True, **options):
    """``numba.njit`` with the package's :data:`FLAGS` (for helpers compiled into kernels).

    ``counted=False``: a called helper that allocates nothing and keeps no array beyond its
    call is compiled without reference counts (numba's ``_nrt=False``): its caller holds
    the arrays it is passed. Each array variable of a helper costs a call of
    ``NRT_incref`` and one of ``NRT_decref`` (on the lanes' borrowed views too, whose
    records are null), 30-50 a call of the lanes' per-point and per-event helpers, which
    numba's reference-count pruning leaves where control flow branches: 100-230 ns less a
    KK point (``benchmarks/step_cost.py``, 2026-12-05). An allocation in such a helper
    fails its compile (numba types no array constructor without reference counts).

    Compile time: every dispatcher a kernel calls costs 0.1-0.3 s of its own (its optimised
    IR, which includes all it calls again), and every ``inline="always"`` call site costs
    the callee's front end again (numba builds its IR anew for each call site): at each
    level of a nest of inlined helpers the whole subtree is built once more. So what runs
    per step is inlined, in as few levels as will do; what runs once per point or event, or
    at a step only where a cheap test says it may, is compiled once and called
    (``benchmarks/run_all.py --only startup_compile_fresh``).

    A called helper gets no Python or C wrapper and no machine code of its own (only
    kernels run it, from their own copies: building the wrappers that unbox its named-tuple
    arguments cost about 0.5 s of the first calls, emitting the helpers' code 0.4-0.8 s;
    :func:`_leave_helpers_unemitted`). Called from Python (a test, a diagnostic), it
    compiles a twin with wrappers on the first such call; one that Python calls as a matter
    of course says ``entry=True``. Inlined helpers keep their wrappers, which cost nothing
    until Python calls them.
    """
    if not counted:
        options["_nrt"] = False
    if entry or options.get("inline") == "always":
        return lambda fn: _entry(numba.njit(**FLAGS, **options)(fn))

    def wrap(fn):
        dispatcher = numba.njit(no_cpython_wrapper=True, no_cfunc_wrapper=True, **FLAGS,
                                **options)(fn)
        # Called from Python, a dispatcher without its wrapper would jump into nothing (a
        # segmentation fault): this class calls a twin with wrappers instead.
        dispatcher.__class__ = _KernelOnly
        return dispatcher
    return wrap


#: Options of a kernel-only helper that its Python twin drops (``nopython``: njit's own).
_WRAPPERLESS = ("no_cpython_wrapper", "no_cfunc_wrapper", "nopython")


class _KernelOnly(CPUDispatcher):
    """A helper compiled for kernels only (no wrappers, no machine code of its own).
    Called from Python, it runs a twin compiled from the same function with the same
    options and its wrappers, made on the first such call."""

    def __call__(self, *args, **kwargs):
        twin = self.__dict__.get("_python_twin")
        if twin is None:
            options = {k: v for k, v in self.targetoptions.items() if k not in _WRAPPERLESS}
            twin = self._python_twin = _entry(numba.njit(**options)(self.py_func))
        return twin(*args, **kwargs)


def cached_jit(**options):
    """:func:`jit` with ``cache=True``, the cache living under :func:`cache_dir`.

    numba picks a dispatcher's cache location when the dispatcher is created, so creating it
    inside :func:`kernel_cache` is what keys it on the kernel sources, whenever and in
    whatever order the kernel modules are imported.
    """
    def wrap(fn):
        with kernel_cache():
            return _entry(numba.njit(cache=True, **FLAGS, **options)(fn))
    return wrap


#: Stack slots that the frame of :func:`on_own_chunk` claims: 512 KiB, which CPython serves
#: with a frame-stack chunk of 1 MiB, the other half left for the compile's frames (the
#: first calls of every method, ``benchmarks/run_all.py``'s start-up figure, then map 380
#: chunks of 16 KiB in all, where the first ``sweep.cor()`` alone mapped 224,000).
OWN_CHUNK_SLOTS = 1 << 16


def _call(fn, args, kwargs):
    return fn(*args, **kwargs)


#: ``fn(*args, **kwargs)`` under a frame that claims :data:`OWN_CHUNK_SLOTS`.
_on_own_chunk = types.FunctionType(
    _call.__code__.replace(co_stacksize=OWN_CHUNK_SLOTS, co_name="_on_own_chunk"),
    globals(), "_on_own_chunk")


def on_own_chunk(fn, *args, **kwargs):
    """``fn(*args, **kwargs)``, its frames on a chunk of CPython's frame stack of their own.

    CPython 3.11 keeps a thread's Python frames in chunks of 16 KiB, each mapped (mmap) when
    a frame no longer fits in the last one and unmapped as soon as the frame at its start
    returns. numba's compiler calls in and out of that depth all the time: the first
    ``sweep.cor()`` mapped and unmapped 224,000 chunks, 2.0 s of system time of a 15.6 s
    compile (one core, empty cache). Called through a frame of :data:`OWN_CHUNK_SLOTS`
    slots, which opens a chunk of 1 MiB, the compile's frames stay in that chunk: 340
    chunks mapped, 13.5 s (docs/speed/history.md). (Python before 3.11 gives the frame a
    512 KiB value stack of its own, once a call.)
    """
    return _on_own_chunk(fn, args, kwargs)


class _Entry(CPUDispatcher):
    """A dispatcher that Python calls: the compiles those calls start (a signature not seen
    yet, the kernels it calls with it) run :func:`on_own_chunk`."""

    def _compile_for_args(self, *args, **kws):
        return _on_own_chunk(super()._compile_for_args, args, kws)


def _entry(dispatcher):
    dispatcher.__class__ = _Entry
    return dispatcher


#: Cyclic-GC thresholds while a kernel of this package compiles: a young-generation
#: collection every 10,000 allocations (against 700) and none of the older ones. The first
#: ``cor()`` compiled in 15.4-15.7 s with the defaults and 14.1-14.6 s with these, measured
#: interleaved (13.5 s with the collector off); peak memory 390 MB against 280 MB (460 MB
#: off). What the compile left for the collector is collected once the defaults are back.
COMPILE_GC_THRESHOLDS = (10_000, 1_000_000, 1_000_000)


class _RelaxedCollector(_event.Listener):
    """Sets :data:`COMPILE_GC_THRESHOLDS` from the start of the outermost compile of one of
    this package's dispatchers (the callees it compiles are nested in it) to its end,
    failed or not, then restores the thresholds found. Other code's compiles are left as
    they are. Meanwhile it knows which dispatcher's compile is innermost
    (:attr:`compiling`), and the first such compile applies :func:`_patch_numba`."""

    def __init__(self):
        self._lock = threading.Lock()
        self._nest = []
        self._saved = None

    @property
    def depth(self) -> int:
        """Nesting of the package's compiles now running (0: none)."""
        return len(self._nest)

    @property
    def compiling(self):
        """The dispatcher whose compile is innermost within the package's (None: none)."""
        return self._nest[-1] if self._nest else None

    def on_start(self, event):
        with self._lock:
            if not self._nest:
                if not _ours(event.data):
                    return
                _patch_numba()
                self._saved = gc.get_threshold()
                gc.set_threshold(*COMPILE_GC_THRESHOLDS)
            self._nest.append(event.data.get("dispatcher"))

    def on_end(self, event):
        with self._lock:
            if not self._nest:
                return
            self._nest.pop()
            if not self._nest:
                _take_apart(_HANDED)
                gc.set_threshold(*self._saved)


def _ours(data) -> bool:
    # A function made by exec() without a __name__ has __module__ None.
    module = getattr(getattr(data.get("dispatcher"), "py_func", None), "__module__", None) or ""
    return module == _PACKAGE or module.startswith(f"{_PACKAGE}.")


_COLLECTOR = _RelaxedCollector()
_event.register("numba:compile", _COLLECTOR)

#: numba releases whose internals the patches of :func:`_patch_numba` were written for
#: (with the sources hashed below: IR nodes that copy themselves as the inliner's patches
#: assume, ``ir.Var`` recording itself in the memo, ``Const`` and ``FreeVar`` sharing
#: their location; a code library finalized as the unemitted one assumes).
PATCHED_NUMBA = frozenset({"0.68.1"})
#: Sources of numba's ``InlineWorker.inline_ir`` (sha256, first 16 hex digits: numba
#: 0.68.1's) whose copies :func:`_share_inline_copies` shares a memo in; any other is left
#: as it is (the compile is then slower, never different).
INLINE_IR_SOURCES = frozenset({"26fd2b7600c9d929"})
#: Sources of ``InlineWorker.inline_function`` (numba 0.68.1's) that hand ``inline_ir``
#: IR built for the one call site, which :func:`_skip_fresh_copies` then leaves uncopied.
INLINE_FUNCTION_SOURCES = frozenset({"1b53f183258e659d"})
#: Sources of ``CPUContext.get_executable``, ``CPUCodeLibrary.finalize`` and
#: ``CPUCodeLibrary._finalize_final_module`` (numba 0.68.1's) that
#: :func:`_leave_helpers_unemitted` replaces for called helpers.
EXECUTABLE_SOURCES = frozenset({"3892c8a654a2ca69", "4b4c34b83488a72f", "95bbf4fcbb90ed99"})
#: Sources of ``NumpyRulesArrayOperator.generic`` (numba 0.68.1's) that
#: :func:`_scalar_operators_skip_ufuncs` lets decline scalar operands at once.
ARRAY_OPERATOR_SOURCES = frozenset({"4647f17d50ba1ade"})
#: Sources of ``TargetConfig.__hash__``, ``__eq__``, ``values`` and of the metaclass that
#: makes the options' properties (numba 0.68.1's), which :func:`_quick_flag_comparisons`
#: replaces with what they compute, computed faster.
TARGET_CONFIG_SOURCES = frozenset({"4d15a6c75137a983", "6d8774572d07d381", "12a29dc810f6a91b",
                                   "f2ff91c25728a971"})
#: Sources of numba's ``ssa._run_ssa``, ``ssa._fix_ssa_vars`` and ``ssa._run_block_rewrite``
#: (numba 0.68.1's) that :func:`_ssa_visits_mentioning_blocks` narrows to the blocks that
#: name each variable.
SSA_SOURCES = frozenset({"c497422bcf049990", "3f183045a5355bf4", "d17efdbed57062bf"})
#: Sources of numba's ``analysis.compute_live_map`` (0.68.1's) whose fixed point
#: :func:`_liveness_on_bit_sets` finds on bit sets.
LIVE_MAP_SOURCES = frozenset({"713c4c094977e93b"})
#: Sources of numba's ``ir.Inst._rec_list_vars`` (0.68.1's) whose list
#: :func:`_quick_instruction_vars` finds faster.
LIST_VARS_SOURCES = frozenset({"054700e9100b6299"})
#: Sources of llvmlite's ``Type.get_abi_size`` and ``get_abi_alignment`` (0.50.0's, which
#: numba 0.68.1 requires) whose answers :func:`_abi_sizes_remembered` keeps.
ABI_SIZE_SOURCES = frozenset({"01d00b21d2d646ca", "0b15b89afc4eb5dc"})
#: Sources of numba's ``CPUCodeLibrary.add_ir_module`` (0.68.1's), after which
#: :func:`_llvm_ir_taken_apart` lets the package's compile take the module apart.
ADD_IR_SOURCES = frozenset({"fb6dd665f0f609c4"})


def _known(functions, sources, version) -> bool:
    """Whether numba ``version`` is one of :data:`PATCHED_NUMBA` and every function's
    source hashes (sha256, first 16 hex digits) to one of ``sources``."""
    if version not in PATCHED_NUMBA:
        return False
    for fn in functions:
        try:
            source = inspect.getsource(fn)
        except (TypeError, OSError):
            return False
        if hashlib.sha256(source.encode()).hexdigest()[:16] not in sources:
            return False
    return True


def _patch_numba() -> None:
    """Apply the compile-time patches of numba's internals (each once, each only for the
    sources it was written for): the package's compiles then take less time and give the
    same results. All but one give the CPU kernels' LLVM IR and assembly byte for byte; the
    helpers' module passes, run once in the kernel instead of at every level, give other
    machine code (the integrator's 1% shorter), whose results were bit for bit the same on
    every draw checked (docs/speed/history.md, 2026-12-05)."""
    _share_inline_copies()
    _skip_fresh_copies()
    _leave_helpers_unemitted()
    _scalar_operators_skip_ufuncs()
    _quick_flag_comparisons()
    _ssa_visits_mentioning_blocks()
    _liveness_on_bit_sets()
    _quick_instruction_vars()
    _abi_sizes_remembered()
    _llvm_ir_taken_apart()


class _OneMemo:
    """The ``copy`` module as numba's inliner sees it while it inlines one callee: every
    ``deepcopy`` without a memo of its own shares this one."""

    def __init__(self):
        self._memo = {}

    def deepcopy(self, x, memo=None):
        return copy.deepcopy(x, self._memo if memo is None else memo)

    def __getattr__(self, name):
        return getattr(copy, name)


class _NoCopy:
    """The ``copy`` module as numba's inliner sees it while it inlines a callee whose IR
    was built for that one call site: ``deepcopy`` gives back what it is given."""

    @staticmethod
    def deepcopy(x, memo=None):
        return x

    def __getattr__(self, name):
        return getattr(copy, name)


@functools.cache
def _share_inline_copies() -> bool:
    """Make numba's inliner copy a callee with one memo for all its blocks, while one of
    this package's dispatchers compiles; True where it does.

    ``inline_ir`` deep-copies the callee's IR block by block, twice (a working copy and a
    copy of that), and every block refers to the callee's scope, which holds every variable
    of the callee and of all that was inlined into it: each block's copy copied the whole
    scope, blocks times variables (a rhs of 79 blocks and 456 variables: 1.3 s). With one
    memo the scope is copied once, as a single deepcopy of the IR would; the generated code
    is the same (the CPU ``_kernel``'s LLVM IR and machine code byte for byte). numba's
    inlining passes over the first ``sweep.cor()`` took 3.1-4.9 s against 5.6-7.0 s
    (summed, nested; docs/speed/history.md). Applied to the source hashed in
    :data:`INLINE_IR_SOURCES` of the releases in :data:`PATCHED_NUMBA` only: that the
    two copies start from different objects, as there, is what lets them share the memo.
    numba-cuda compiles with its own copy of the inliner, which this leaves alone. Where
    :func:`_skip_fresh_copies` marks the worker, there are no copies at all.
    """
    from numba.core import inline_closurecall as icc    # noqa: PLC0415 -- numba internals

    worker = getattr(icc, "InlineWorker", None)
    plain = getattr(worker, "inline_ir", None)
    if (not _known([plain], INLINE_IR_SOURCES, numba.__version__)
            or getattr(icc, "copy", None) is not copy):
        return False

    @functools.wraps(plain)
    def inline_ir(self, *args, **kwargs):
        if _COLLECTOR.depth == 0:       # another package's compile: numba's own way
            return plain(self, *args, **kwargs)
        fresh = getattr(self, _FRESH, False)
        previous, icc.copy = icc.copy, _NoCopy() if fresh else _OneMemo()
        try:
            return plain(self, *args, **kwargs)
        finally:
            icc.copy = previous
    worker.inline_ir = inline_ir
    return True


#: Attribute of an ``InlineWorker`` that is True while its ``inline_function`` runs.
_FRESH = "_sweep_fresh_callee"


@functools.cache
def _skip_fresh_copies() -> bool:
    """Let numba's inliner use, uncopied, the IR it builds for each call site of an
    ``inline="always"`` function; True where it does (with :func:`_share_inline_copies`).

    ``inline_function`` runs the untyped front end over the callee, for this call site
    alone, and ``inline_ir`` then deep-copies that fresh IR twice: a working copy, which it
    mutates and splices in, and an "unmutated" copy that it returns and the inlining pass
    throws away. Nobody else holds the fresh IR, so working on it directly is what the copy
    gave, without the copying: 1.1 s → 0.2 s of ``inline_ir`` over the first
    ``sweep.cor()``, the same LLVM IR and assembly. The overloads that numba's typed pass
    inlines come from a cache and are still copied.
    """
    from numba.core import inline_closurecall as icc    # noqa: PLC0415 -- numba internals

    return _mark_fresh_callees(getattr(icc, "InlineWorker", None), numba.__version__)


def _mark_fresh_callees(worker, version) -> bool:
    """Wrap ``worker.inline_function`` to mark the worker :data:`_FRESH` while it runs,
    where its source is one of :data:`INLINE_FUNCTION_SOURCES` under ``version``."""
    plain = getattr(worker, "inline_function", None)
    if not _known([plain], INLINE_FUNCTION_SOURCES, version):
        return False

    @functools.wraps(plain)
    def inline_function(self, *args, **kwargs):
        previous = getattr(self, _FRESH, False)
        setattr(self, _FRESH, True)
        try:
            return plain(self, *args, **kwargs)
        finally:
            setattr(self, _FRESH, previous)
    worker.inline_function = inline_function
    return True


@functools.cache
def _leave_helpers_unemitted() -> bool:
    """Compile a called helper (:class:`_KernelOnly`) to LLVM IR optimised function by
    function only, without module passes or machine code of its own; True where that
    applies.

    numba finalizes every dispatcher's code library into machine code, but a helper's is
    never run: each caller links the helper's IR into its own module (numba's
    ``linkonce_odr`` copies) and emits it there, and Python may not call the helper. A
    kernel loaded from the cache already runs on those copies alone. Emitting the helpers
    took 0.44 s of the first ``sweep.cor()``'s 1.5 s of machine code.

    numba also runs the full module pipeline (inlining, the reference-count pruning, O3)
    on every library once its callees are linked in, so a helper's code went through it
    once for each level of helpers above it, and again in the kernel that links them all.
    A kernel's own library (an entry, or a kernel Python calls) still runs it, over the
    whole linked module: every helper's code goes through it there, once. That took 0.8 s
    off the first ``sweep.cor()`` (13.0-13.9 s, mean 13.3, against 14.0-14.2, mean 14.1;
    five fresh caches each, interleaved), the kernels' times and results unchanged
    (docs/speed/history.md, 2026-12-05).
    """
    from numba.core import cpu                            # noqa: PLC0415 -- numba internals

    return _unemitted_helpers_in(cpu.CPUContext, numba.__version__)


def _unemitted_helpers_in(context, version) -> bool:
    """Wrap ``context.get_executable`` so that a helper's library is finalized unemitted,
    where the sources of :data:`EXECUTABLE_SOURCES` are those of ``version``."""
    from numba import _dynfunc                            # noqa: PLC0415 -- numba internals
    from numba.core.codegen import CPUCodeLibrary         # noqa: PLC0415 -- numba internals

    plain = getattr(context, "get_executable", None)
    library_steps = [getattr(CPUCodeLibrary, "finalize", None),
                     getattr(CPUCodeLibrary, "_finalize_final_module", None)]
    if not _known([plain, *library_steps], EXECUTABLE_SOURCES, version):
        return False

    @functools.wraps(plain)
    def get_executable(self, library, fndesc, env):
        if not _helper_being_compiled(fndesc):
            return plain(self, library, fndesc, env)
        library._optimize_final_module = _left_to_the_kernel
        library._finalize_final_module = functools.partial(_finalize_unemitted, library)
        library._ensure_finalized()
        # numba's own entry object, with no code address: _KernelOnly refuses calls.
        return _dynfunc.make_function(fndesc.lookup_module(), fndesc.qualname.split(".")[-1],
                                      f"compiled wrapper for {fndesc.qualname!r}", 0, env,
                                      (library,))
    context.get_executable = get_executable
    return True


def _helper_being_compiled(fndesc) -> bool:
    """Whether ``fndesc`` is the function of the :class:`_KernelOnly` whose compile is the
    innermost one now (numba lowers, then finalizes, a dispatcher in its own compile)."""
    dispatcher = _COLLECTOR.compiling
    if not isinstance(dispatcher, _KernelOnly):
        return False
    fn = dispatcher.py_func
    return fndesc.qualname == fn.__qualname__ and fndesc.modname == fn.__module__


def _left_to_the_kernel() -> None:
    """A helper library's module passes: none; the kernel that links it runs them."""


def _finalize_unemitted(library) -> None:
    """numba's ``_finalize_final_module`` for a helper's library, less what makes machine
    code (``add_module`` to the JIT engine, ``finalize_object``) and the dumps: the checks
    run, the optimised module stays for callers to link."""
    library._finalize_dynamic_globals()
    library._verify_declare_only_symbols()
    library._finalized = True


@functools.cache
def _scalar_operators_skip_ufuncs() -> bool:
    """Let numba's typing template of numpy's array operators decline scalar operands
    without matching them against the ufunc's loops; True where it does.

    numba types every ``+``, ``*``, ``<`` ... through this template before the scalar ones,
    and the template found the ufunc loop for the operands (about 35 us) before it declined
    them for having no array among them: 12,700 times in the first ``sweep.cor()``. The
    template declines the same operands as before, with the same result, and types every
    operation with an array among its operands as numba does.
    """
    from numba.core.typing import npydecl                 # noqa: PLC0415 -- numba internals

    return _declining_scalars_in(npydecl.NumpyRulesArrayOperator, numba.__version__)


def _declining_scalars_in(template, version) -> bool:
    """Wrap ``template.generic`` to return None at once for operands that hold no array
    (an Optional stands for its type, as numba's ufunc typing takes it), while one of this
    package's dispatchers compiles, where its source is one of
    :data:`ARRAY_OPERATOR_SOURCES` under ``version``."""
    from numba.core import types                          # noqa: PLC0415 -- numba internals

    plain = getattr(template, "generic", None)
    if not _known([plain], ARRAY_OPERATOR_SOURCES, version):
        return False

    @functools.wraps(plain)
    def generic(self, args, kws):
        if _COLLECTOR.depth and not any(
                isinstance(a.type if isinstance(a, types.Optional) else a,
                           types.ArrayCompatible) for a in (*args, *kws.values())):
            return None
        return plain(self, args, kws)
    template.generic = generic
    return True


@functools.cache
def _quick_flag_comparisons() -> bool:
    """Let numba's compile flags hash and compare as they do, faster, while one of this
    package's dispatchers compiles; True where they do.

    numba's typing templates of overloaded functions key their cache on the flags of the
    compile: 32,000 hashes and 26,000 comparisons in the first ``sweep.cor()``, each
    building the dict of every option through its property (3.5 us; 0.3-0.4 s in all).
    The hash is numba's own value (that of the sorted option names: numba's hash sorts the
    dict's keys), computed once per class; a comparison compares the same dicts, built
    from the defaults and the options set.
    """
    from numba.core import targetconfig                   # noqa: PLC0415 -- numba internals

    config = targetconfig.TargetConfig
    sources = [config.__hash__, config.__eq__, config.values,
               type(config).__init__]
    return _quick_comparisons_in(config, sources, numba.__version__)


def _quick_comparisons_in(config, sources, version) -> bool:
    """Replace ``config.__hash__`` and ``__eq__`` (:func:`_quick_flag_comparisons`) where
    ``sources`` are those of :data:`TARGET_CONFIG_SOURCES` under ``version``."""
    plain_hash, plain_eq = config.__hash__, config.__eq__
    if not _known(sources, TARGET_CONFIG_SOURCES, version):
        return False

    @functools.wraps(plain_hash)
    def __hash__(self):
        if _COLLECTOR.depth == 0:
            return plain_hash(self)
        return _names_hash(type(self))

    @functools.wraps(plain_eq)
    def __eq__(self, other):
        if _COLLECTOR.depth == 0 or not isinstance(other, config):
            return plain_eq(self, other)
        return _option_values(self) == _option_values(other)
    config.__hash__, config.__eq__ = __hash__, __eq__
    return True


@functools.cache
def _names_hash(cls) -> int:
    return hash(tuple(sorted(cls.options)))


@functools.cache
def _defaults(cls) -> dict:
    return {name: option.default for name, option in cls.options.items()}


def _option_values(config) -> dict:
    """``config.values()``: the defaults, overridden by the options set (numba's own
    ``values()`` where something not an option of the class was set)."""
    defaults = _defaults(type(config))
    if not config._values.keys() <= defaults.keys():
        return config.values()
    return {**defaults, **config._values}


#: While numba's SSA reconstruction runs on one of the package's functions: the labels of
#: the blocks that name each variable (:func:`_ssa_visits_mentioning_blocks`).
_SSA = threading.local()


@functools.cache
def _ssa_visits_mentioning_blocks() -> bool:
    """Let numba's SSA reconstruction rewrite, for each variable assigned more than once,
    only the blocks that name it; True where it does.

    ``_run_ssa`` renames each such variable's definitions and then its uses by two passes
    over every statement of the function, one variable at a time: variables times
    statements. A block that does not name the variable comes out of both passes as it
    went in (each statement given back unchanged), so it is passed over here; only a block
    that gets the variable's phi nodes is rebuilt. ``march_lanes``, everything inlined:
    194 such variables over about 4,000 blocks, 0.55 s of SSA reconstruction, 1.0 s with
    the lanes' in-place steps (docs/speed/history.md, 2026-12-05). Applied to the sources
    in :data:`SSA_SOURCES` of the releases in :data:`PATCHED_NUMBA`, to the package's
    compiles only.
    """
    from numba.core import ssa    # noqa: PLC0415 -- numba internals

    return _narrowed_in(ssa, numba.__version__)


def _narrowed_in(ssa, version) -> bool:
    """Replace ``_run_ssa``, ``_fix_ssa_vars`` and ``_run_block_rewrite`` of the module
    ``ssa`` by :func:`_narrowed_ssa`'s, where numba ``version`` and their sources are
    those :data:`SSA_SOURCES` knows; True where it does."""
    from numba.core import ir     # noqa: PLC0415 -- numba internals

    names = ("_run_ssa", "_fix_ssa_vars", "_run_block_rewrite")
    functions = [getattr(ssa, name, None) for name in names]
    if not _known(functions, SSA_SOURCES, version):
        return False
    for name, wrapped in zip(names, _narrowed_ssa(ssa, ir, *functions)):
        setattr(ssa, name, wrapped)
    return True


def _narrowed_ssa(ssa, ir, run_ssa, fix_ssa_vars, run_block_rewrite):
    """numba's ``_run_ssa``, ``_fix_ssa_vars`` and ``_run_block_rewrite`` (of the module
    ``ssa``) wrapped to rewrite, inside the package's compiles, only the blocks that name
    each variable (:func:`_ssa_visits_mentioning_blocks`)."""

    @functools.wraps(run_ssa)
    def _run_ssa(blocks):
        # Each run gets the index of its own blocks (None: numba's own passes), and leaves
        # the one it found.
        previous = getattr(_SSA, "named", None)
        _SSA.named = _blocks_naming(blocks) if _COLLECTOR.depth else None
        try:
            return run_ssa(blocks)
        finally:
            _SSA.named = previous

    @functools.wraps(run_block_rewrite)
    def _run_block_rewrite(blocks, states, handler):
        named = getattr(_SSA, "named", None)
        if named is None:
            return run_block_rewrite(blocks, states, handler)
        naming = named.get(states["varname"], ())
        out = {}
        for label, blk in blocks.items():
            out[label] = (run_block_rewrite({label: blk}, states, handler)[label]
                          if label in naming else blk)
        return out

    @functools.wraps(fix_ssa_vars)
    def _fix_ssa_vars(blocks, varname, defmap, cfg, df_plus, cache_list_vars):
        if getattr(_SSA, "named", None) is None:
            return fix_ssa_vars(blocks, varname, defmap, cfg, df_plus, cache_list_vars)
        states = ssa._make_states(blocks)
        states["varname"] = varname
        states["defmap"] = defmap
        states["phimap"] = phimap = ssa.defaultdict(list)
        states["cfg"] = cfg
        states["phi_locations"] = ssa._compute_phi_locations(df_plus, defmap)
        newblocks = _run_block_rewrite(blocks, states, ssa._FixSSAVars(cache_list_vars))
        for label, philist in phimap.items():
            # A new block: one passed over is shared with the function's IR before.
            old = newblocks[label]
            newblocks[label] = blk = ir.Block(scope=old.scope, loc=old.loc)
            blk.body = philist + old.body
        return newblocks

    return _run_ssa, _fix_ssa_vars, _run_block_rewrite


def _blocks_naming(blocks) -> dict:
    """Variable name -> labels of the blocks whose statements name it."""
    named: dict = {}
    for label, blk in blocks.items():
        for stmt in blk.body:
            for var in stmt.list_vars():
                named.setdefault(var.name, set()).add(label)
    return named


@functools.cache
def _liveness_on_bit_sets() -> bool:
    """Let numba find the variables live at each block's entry on bit sets
    (:func:`sweep.kernels._numba_ir.compute_live_map`: the same sets, whose order of
    iteration may differ, which nothing numba compiles depends on), while one of this
    package's dispatchers compiles; True where it does.

    numba's IR post-processor recomputes them after nearly every pass and inlined call
    site, with set unions that copy thousands of names: 2,367 times and 1.3 s in the
    first ``sweep.cor()``, 0.3 s on bit sets (docs/speed/history.md, 2026-12-07).
    Applied to the sources in :data:`LIVE_MAP_SOURCES` of the releases in
    :data:`PATCHED_NUMBA`. As with the other patches, "while one compiles" covers what that
    compile compiles in turn (numba's own overloads among them) and, the switch being
    the process's, another thread's compile meanwhile; compiles started outside the
    package keep numba's, and so does numba code that imports the function by name
    (``ir_utils``, ``parfors``).
    """
    from numba.core import analysis                       # noqa: PLC0415 -- numba internals

    return _bit_sets_in(analysis, numba.__version__)


def _bit_sets_in(analysis, version) -> bool:
    """Replace ``analysis.compute_live_map`` where numba ``version`` and its source are
    those :data:`LIVE_MAP_SOURCES` knows; True where it does."""
    plain = getattr(analysis, "compute_live_map", None)
    if not _known([plain], LIVE_MAP_SOURCES, version):
        return False

    @functools.wraps(plain)
    def compute_live_map(cfg, blocks, var_use_map, var_def_map):
        if _COLLECTOR.depth == 0:
            return plain(cfg, blocks, var_use_map, var_def_map)
        return _numba_ir.compute_live_map(cfg, blocks, var_use_map, var_def_map)
    analysis.compute_live_map = compute_live_map
    return True


@functools.cache
def _quick_instruction_vars() -> bool:
    """Let numba list the variables an IR instruction names with fewer calls and type
    tests (:func:`sweep.kernels._numba_ir.vars_in`: the same list), while one of this
    package's dispatchers compiles; True where it does.

    ``Inst.list_vars`` walks an instruction's attributes recursively, four ``isinstance``
    tests and a call per value: 3 million calls in the first ``sweep.cor()``, for its
    use-def and live-variable analyses, SSA and ``del`` placement. Applied to the source in
    :data:`LIST_VARS_SOURCES` of the releases in :data:`PATCHED_NUMBA`.
    """
    from numba.core import ir                             # noqa: PLC0415 -- numba internals

    return _quick_vars_in(ir, numba.__version__)


def _quick_vars_in(ir, version) -> bool:
    """Replace ``ir.Inst._rec_list_vars`` (of the module ``ir``) where numba ``version``
    and its source are those :data:`LIST_VARS_SOURCES` knows; True where it does."""
    plain = getattr(getattr(ir, "Inst", None), "_rec_list_vars", None)
    if not _known([plain], LIST_VARS_SOURCES, version):
        return False
    kinds = _numba_ir.Kinds(ir.Var, ir.Inst)

    @functools.wraps(plain)
    def _rec_list_vars(self, val):
        # The nest itself, not the depth property: this runs 3 million times a compile.
        if not _COLLECTOR._nest:
            return plain(self, val)
        return _numba_ir.vars_in(val, kinds)
    ir.Inst._rec_list_vars = _rec_list_vars
    return True


@functools.cache
def _abi_sizes_remembered() -> bool:
    """Let numba's questions to LLVM about a type's ABI size and alignment be answered
    from LLVM's first answer during the package's compiles; True where they are.

    llvmlite answers each by parsing a module made for the question: 1,900 times in the
    first ``sweep.cor()``, for 36 types, 0.2 s. An answer is kept per target data and type
    text, for types that name no other (an identified structure's text is only its name:
    those are asked each time). Applied to llvmlite's sources in
    :data:`ABI_SIZE_SOURCES` under the releases in :data:`PATCHED_NUMBA`.
    """
    from llvmlite.ir import types as ir_types              # noqa: PLC0415 -- numba internals

    return _remembered_in(ir_types.Type, numba.__version__)


def _remembered_in(type_class, version) -> bool:
    """Wrap ``type_class.get_abi_size`` and ``get_abi_alignment``
    (:func:`_abi_sizes_remembered`) where their sources are those of
    :data:`ABI_SIZE_SOURCES` under ``version``."""
    plain = [getattr(type_class, name, None) for name in ("get_abi_size", "get_abi_alignment")]
    if not _known(plain, ABI_SIZE_SOURCES, version):
        return False
    for query in plain:
        setattr(type_class, query.__name__, _remembered(query))
    return True


def _remembered(plain):
    """``plain(type, target_data)`` kept per target data and type text during the
    package's compiles (:func:`_abi_sizes_remembered`)."""
    known: dict = {}

    @functools.wraps(plain)
    def query(self, target_data, context=None):
        if context is not None or _COLLECTOR.depth == 0:
            return plain(self, target_data, context)
        text = str(self)
        if "%" in text:                      # names an identified structure
            return plain(self, target_data, context)
        key = (target_data, text)            # the target data kept alive: no reused id
        value = known.get(key)
        if value is None:
            value = known[key] = plain(self, target_data, context)
        return value
    return query


#: The llvmlite IR modules handed to code libraries (``add_ir_module``) during the package's
#: compile now running, taken apart when it ends (:func:`_llvm_ir_taken_apart`).
_HANDED: weakref.WeakSet = weakref.WeakSet()


@functools.cache
def _llvm_ir_taken_apart() -> bool:
    """Let the llvmlite IR that the package's compile handed to numba's code libraries be
    taken apart when the compile ends, so that reference counting frees it; True where
    that applies.

    numba builds each function's LLVM IR as llvmlite objects, which a code library turns
    into text and LLVM's own module (``add_ir_module``); nothing reads the objects after
    that. They form reference cycles (a block holds its instructions, each instruction its
    block), about 500,000 objects after the first ``sweep.cor()``, which the cyclic
    collector freed in one collection of 0.65-0.73 s in a later call (in the start-up
    figure, ``auto``'s first call). Taken apart (0.07 s at the compile's end, the objects
    freed in it), the collection after that compile finds 31,000 objects and takes
    0.17-0.21 s. Applied to the source of :data:`ADD_IR_SOURCES` of the releases in
    :data:`PATCHED_NUMBA`.
    """
    from numba.core import codegen                         # noqa: PLC0415 -- numba internals

    return _handed_recorded_in(codegen.CPUCodeLibrary, numba.__version__)


def _handed_recorded_in(library_class, version) -> bool:
    """Wrap ``library_class.add_ir_module`` to record, during the package's compiles, the
    module it is handed in :data:`_HANDED`, where its source is one of
    :data:`ADD_IR_SOURCES` under ``version``."""
    plain = getattr(library_class, "add_ir_module", None)
    if not _known([plain], ADD_IR_SOURCES, version):
        return False

    @functools.wraps(plain)
    def add_ir_module(self, ir_module):
        plain(self, ir_module)
        if _COLLECTOR.depth:
            _HANDED.add(ir_module)
    library_class.add_ir_module = add_ir_module
    return True


def _take_apart(modules: weakref.WeakSet) -> None:
    """Break the reference cycles of the llvmlite IR ``modules`` (and empty the set): the
    attributes of their globals (functions and their arguments, blocks, instructions,
    variables) are dropped, whatever refers to what among them."""
    for module in list(modules):
        for value in list(module.globals.values()):
            parts = [*getattr(value, "args", ())]
            for block in getattr(value, "blocks", ()):
                parts += block.instructions
                parts.append(block)
            for part in (*parts, value):
                vars(part).clear()
        module.globals.clear()
    modules.clear()
