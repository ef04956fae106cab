"""The kernel cache key (every package module a kernel imports, whatever the import form) and
the compile-time settings of :mod:`sweep.kernels._jit`."""
import gc
import operator
import shutil
import subprocess
import sys
import textwrap
import types
import weakref
from pathlib import Path

import numba
import numba.core.event
import numpy as np
import pytest

import sweep
from sweep.kernels import _jit

ROOT = Path(sweep.__file__).resolve().parent


@pytest.fixture()
def pkg(tmp_path):
    """A copy of the package, to edit."""
    dst = tmp_path / "sweep"
    shutil.copytree(ROOT, dst, ignore=shutil.ignore_patterns("__pycache__"))
    return dst


def _append(path, text):
    path.write_text(path.read_text() + text)


def test_kernel_sources_cover_the_kernels_and_what_they_import():
    names = {p.relative_to(ROOT).as_posix() for p in _jit.kernel_sources()}
    assert {"kernels/integrator.py", "kernels/contact.py", "kernels/approx.py",
            "registry.py"} <= names
    assert not any(n.startswith(("sweeps/", "store/", "reports/")) for n in names)
    assert "cli.py" not in names and "api.py" not in names


def test_editing_a_kernel_helper_changes_the_hash(pkg):
    before = _jit.source_hash(pkg)
    _append(pkg / "kernels" / "contact.py", "\n# an edit\n")
    assert _jit.source_hash(pkg) != before


def test_editing_the_cli_or_store_keeps_the_hash(pkg):
    before = _jit.source_hash(pkg)
    _append(pkg / "cli.py", "\n# an edit\n")
    _append(pkg / "store" / "__init__.py", "\n# an edit\n")
    assert _jit.source_hash(pkg) == before


@pytest.mark.parametrize("form", [
    "from sweep import helper_mod",
    "import sweep.helper_mod",
    "from sweep.helper_mod import VALUE",
    "from .. import helper_mod",
    "from ..helper_mod import VALUE",
    "import sweep.helper_mod as hm",
])
def test_every_import_form_is_followed(pkg, form):
    (pkg / "helper_mod.py").write_text("VALUE = 1\n")
    _append(pkg / "kernels" / "stepper.py", f"\n{form}  # noqa\n")
    assert pkg / "helper_mod.py" in _jit.kernel_sources(pkg)
    before = _jit.source_hash(pkg)
    (pkg / "helper_mod.py").write_text("VALUE = 2\n")
    assert _jit.source_hash(pkg) != before


def test_relative_import_inside_a_function_is_followed(pkg):
    (pkg / "kernels" / "extra.py").write_text("X = 1\n")
    (pkg / "helper_mod.py").write_text("Y = 1\n")
    _append(pkg / "kernels" / "extra.py", textwrap.dedent("""
        def f():
            from ..helper_mod import Y
            return Y
    """))
    assert pkg / "helper_mod.py" in _jit.kernel_sources(pkg)


def test_cached_kernels_live_under_the_source_hash(tmp_path):
    # A fresh process with its own cache directory compiles into <dir>/sweep-numba/<hash>.
    code = ("import sweep, numpy as np; from sweep.kernels import _jit; "
            "sweep.cor(1.5, 1.5, np.full(2, 0.1), 0.1, method='ord1'); print(_jit.cache_dir())")
    env = {"NUMBA_CACHE_DIR": str(tmp_path), "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True).stdout.strip()
    where = Path(out)
    assert where == tmp_path / "sweep-numba" / _jit.source_hash()
    assert any(where.rglob("*.nbi")), "no cache index written"


class _Thresholds(numba.core.event.Listener):
    """Records the GC thresholds at the start of every compile (registered after the
    package's own listener, so it sees what that one set)."""

    def __init__(self):
        self.seen = []

    def on_start(self, event):
        self.seen.append((event.data["dispatcher"].py_func.__name__, gc.get_threshold()))

    def on_end(self, event):
        pass


def _as_if_in(module, fn):
    fn.__module__ = module
    return numba.njit(fn)


@pytest.fixture()
def thresholds():
    rec = _Thresholds()
    numba.core.event.register("numba:compile", rec)
    before = gc.get_threshold()
    yield rec, before
    numba.core.event.unregister("numba:compile", rec)
    gc.set_threshold(*before)


def test_the_collector_is_relaxed_while_a_package_kernel_compiles(thresholds):
    rec, before = thresholds
    assert before != _jit.COMPILE_GC_THRESHOLDS

    def callee(x):
        return x + 1.0

    def kernel(x):
        return inner(x) * 2.0

    inner = _as_if_in("tests.elsewhere", callee)
    outer = _as_if_in("sweep.kernels.fake", kernel)
    assert outer(1.0) == 4.0
    # The package's kernel and what it compiles under it run relaxed; then it is undone.
    assert rec.seen == [("kernel", _jit.COMPILE_GC_THRESHOLDS),
                        ("callee", _jit.COMPILE_GC_THRESHOLDS)]
    assert gc.get_threshold() == before


def test_other_code_compiles_with_the_thresholds_it_has(thresholds):
    rec, _ = thresholds
    gc.set_threshold(500, 7, 9)

    def theirs(x):
        return x - 1.0

    assert _as_if_in("elsewhere", theirs)(1.0) == 0.0
    assert rec.seen == [("theirs", (500, 7, 9))] and gc.get_threshold() == (500, 7, 9)


def test_code_of_no_module_compiles_with_the_thresholds_it_has(thresholds):
    # exec() without __name__ leaves a function's __module__ None: the listener sees
    # every compile in the process once sweep is imported, and must not fail on it.
    rec, _ = thresholds
    gc.set_threshold(500, 7, 9)
    namespace = {}
    exec("def nameless(x):\n    return x * 3.0\n", namespace)
    assert namespace["nameless"].__module__ is None
    assert numba.njit(namespace["nameless"])(2.0) == 6.0
    assert rec.seen == [("nameless", (500, 7, 9))] and gc.get_threshold() == (500, 7, 9)


def test_a_failed_compile_restores_the_thresholds(thresholds):
    rec, before = thresholds

    def broken(x):
        return x + "text"

    with pytest.raises(numba.core.errors.TypingError):
        _as_if_in("sweep.kernels.fake", broken)(1.0)
    assert rec.seen == [("broken", _jit.COMPILE_GC_THRESHOLDS)]
    assert gc.get_threshold() == before


def test_a_called_helper_serves_kernels_and_python_through_a_twin():
    def plus_one(x):
        return x + 1.0

    def twice(x):
        return helper(x) * 2.0

    helper = _jit.jit()(plus_one)
    entry = _jit.jit(entry=True)(twice)
    assert entry(1.5) == 5.0
    (own,) = helper.overloads.values()
    # Compiled without a Python wrapper: a call from Python runs a twin, not a null pointer.
    assert helper(1.5) == 2.5 and helper(0.5) == 1.5
    twin = helper._python_twin
    assert twin is not helper and twin.py_func is plus_one
    assert {k: twin.targetoptions.get(k) for k in _jit.FLAGS} == _jit.FLAGS
    assert list(helper.overloads.values()) == [own]
    inlined = _jit.jit(inline="always")(plus_one)
    assert inlined(1.5) == 2.5


def _increfs(dispatcher):
    """Calls of NRT_incref in a helper's own function, as compiled under a package kernel
    (before the kernel's module passes, whose pruning removes them where it can)."""
    (cres,) = dispatcher.overloads.values()
    ir = cres.library.get_llvm_str()
    start = ir.index(f"@{cres.fndesc.llvm_func_name}(")
    return ir[start:ir.index("\n}", start)].count("@NRT_incref(")


def test_an_uncounted_helper_takes_its_callers_arrays_without_reference_counts():
    if not _jit._leave_helpers_unemitted():
        pytest.skip("numba's codegen is not one EXECUTABLE_SOURCES knows")

    def fill(t, k):
        row = t[1][k]       # a view of an array in a tuple: counted where counted
        for j in range(row.size):
            row[j] = t[0][j] + k
        return row.sum()

    def kernel(a, b):
        return helper((a, b), 1) + counted((a, b), 0)

    helper = _jit.jit(counted=False)(fill)
    counted = _jit.jit()(fill)
    kernel = _as_if_in("sweep.kernels.fake", kernel)
    a, b = np.arange(3.0), np.zeros((2, 3))
    assert kernel(a, b) == (1.0 + 2.0 + 3.0) + (0.0 + 1.0 + 2.0)
    np.testing.assert_array_equal(b, [[0.0, 1.0, 2.0], [1.0, 2.0, 3.0]])
    assert _increfs(helper) == 0 < _increfs(counted)
    # From Python, through its twin, the same.
    assert helper((a, np.zeros((2, 3))), 1) == 6.0


class _Stacks(numba.core.event.Listener):
    """Records, at the start of every compile, whether it runs under
    :func:`_jit.on_own_chunk`'s frame."""

    def __init__(self):
        self.seen = []

    def on_start(self, event):
        frame, under = sys._getframe(), False
        while frame is not None and not under:
            under = frame.f_code is _jit._on_own_chunk.__code__
            frame = frame.f_back
        self.seen.append((event.data["dispatcher"].py_func.__name__, under))

    def on_end(self, event):
        pass


@pytest.fixture()
def stacks():
    rec = _Stacks()
    numba.core.event.register("numba:compile", rec)
    yield rec
    numba.core.event.unregister("numba:compile", rec)


def test_compiles_started_from_python_run_on_a_chunk_of_their_own(stacks, tmp_path,
                                                                   monkeypatch):
    """A first call from Python compiles under a frame that claims OWN_CHUNK_SLOTS stack
    slots, and what it compiles under it too; the results are the function's."""
    def half(x):
        return 0.5 * x

    def twice(x):
        return helper(x) * 4.0

    helper = _jit.jit()(half)
    entry = _jit.jit(entry=True)(twice)
    inlined = _jit.jit(inline="always")(half)
    monkeypatch.setattr(_jit, "cache_dir", lambda: tmp_path)
    cached = _jit.cached_jit()(twice)
    assert entry(3.0) == 6.0 and inlined(3.0) == 1.5 and cached(1.0) == 2.0
    assert helper(3.0) == 1.5          # its Python twin
    assert stacks.seen == [("twice", True), ("half", True), ("half", True),
                           ("twice", True), ("half", True)]
    assert _jit._on_own_chunk.__code__.co_stacksize == _jit.OWN_CHUNK_SLOTS
    # Other code's dispatchers compile where they are called.
    assert numba.njit(half)(2.0) == 1.0 and stacks.seen[-1] == ("half", False)


def test_on_own_chunk_passes_arguments_and_errors_through():
    assert _jit.on_own_chunk(divmod, 7, 2) == (3, 1)
    assert _jit.on_own_chunk(int, "ff", base=16) == 255
    with pytest.raises(ZeroDivisionError):
        _jit.on_own_chunk(divmod, 1, 0)


def test_the_inliner_copies_a_package_callee_with_one_memo(monkeypatch):
    """While a package kernel compiles, numba's inliner copies each callee with one memo
    (``_jit._share_inline_copies``): the blocks of the copy share one copy of the scope, as
    the callee's blocks share theirs. Other code's compiles copy as numba does (a scope per
    block). Inlined twice, the callee still gives each call site its own variables."""
    from numba.core import inline_closurecall as icc

    if not _jit._share_inline_copies():
        pytest.skip("numba's inline_ir is not one INLINE_IR_SOURCES knows")
    seen = []
    check = icc.callee_ir_validator

    def spy(callee_ir):     # numba validates the first copy of the callee
        seen.append(len({id(b.scope) for b in callee_ir.blocks.values()}))
        check(callee_ir)
    monkeypatch.setattr(icc, "callee_ir_validator", spy)

    def clipped(x):
        if x < 0.0:
            return 0.0
        y = x * x
        return y if y < 4.0 else 4.0

    def kernel(a, b):
        return clipped(a) + 10.0 * clipped(b)

    clipped = numba.njit(inline="always")(clipped)
    assert _as_if_in("sweep.kernels.fake", kernel)(-1.0, 1.5) == 22.5
    assert seen == [1, 1]
    assert _as_if_in("elsewhere", kernel)(3.0, 1.0) == 14.0
    assert seen[2] > 1 and seen[3] > 1


def test_the_inliner_splices_a_package_callee_s_fresh_ir_uncopied(monkeypatch):
    """While a package kernel compiles, an ``inline="always"`` callee's IR, built by
    numba's front end for that one call site, is spliced in without numba's two deep
    copies (``_jit._skip_fresh_copies``); other code's compiles copy it."""
    from numba.core import inline_closurecall as icc

    if not (_jit._share_inline_copies() and _jit._skip_fresh_copies()):
        pytest.skip("numba's inliner is not one INLINE_*_SOURCES knows")
    built, validated = [], []
    run_untyped = icc.InlineWorker.run_untyped_passes
    check = icc.callee_ir_validator

    def built_spy(self, func, *args, **kwargs):
        ir = run_untyped(self, func, *args, **kwargs)
        built.append({id(b) for b in ir.blocks.values()})
        return ir

    def validated_spy(callee_ir):     # numba validates the working copy
        validated.append({id(b) for b in callee_ir.blocks.values()})
        check(callee_ir)
    monkeypatch.setattr(icc.InlineWorker, "run_untyped_passes", built_spy)
    monkeypatch.setattr(icc, "callee_ir_validator", validated_spy)

    def halved(x):
        return 0.5 * x if x > 0.0 else 0.0

    def kernel(a, b):
        return halved(a) + halved(b)

    halved = numba.njit(inline="always")(halved)
    assert _as_if_in("sweep.kernels.fake", kernel)(4.0, -1.0) == 2.0
    assert len(built) == 2 and validated == built
    assert _as_if_in("elsewhere", kernel)(2.0, 6.0) == 4.0
    assert len(built) == 4 and not validated[2] & built[2] and not validated[3] & built[3]


def _kernel_calling_a_helper(module):
    """``(helper, kernel)``: a called helper (``x**3``) and a kernel of ``module`` that
    returns ``helper(x) + 1``, neither compiled yet."""
    def cube(x):
        return x * x * x

    def kernel(x):
        return helper(x) + 1.0

    helper = _jit.jit()(cube)
    return helper, _as_if_in(module, kernel)


def test_a_called_helper_is_compiled_without_machine_code_of_its_own(monkeypatch):
    """A called helper compiled under a package kernel leaves its IR for its callers,
    without module passes of its own, and puts nothing in the JIT engine; the kernel that
    links it runs the module passes over both (``_jit._leave_helpers_unemitted``)."""
    if not _jit._leave_helpers_unemitted():
        pytest.skip("numba's codegen is not one EXECUTABLE_SOURCES knows")
    from numba.core.codegen import CPUCodeLibrary

    passes = []
    plain = CPUCodeLibrary._optimize_final_module

    def counted(self):
        passes.append(self.name)
        return plain(self)
    monkeypatch.setattr(CPUCodeLibrary, "_optimize_final_module", counted)
    helper, kernel = _kernel_calling_a_helper("sweep.kernels.fake")
    assert kernel(2.0) == 9.0
    (cres,) = helper.overloads.values()
    engine = cres.library.codegen._engine
    assert cres.library._finalized and "cube" in cres.library.get_llvm_str()
    assert not engine.is_symbol_defined(cres.fndesc.llvm_func_name)
    (kres,) = kernel.overloads.values()
    assert passes == [kres.library.name]
    # The kernel's module passes inlined the helper: its optimised code calls nothing.
    assert cres.fndesc.llvm_func_name not in kres.library.get_llvm_str()
    # Other code's dispatchers are emitted as numba does.
    entry = numba.njit(lambda x: x * 2.0)
    entry(1.0)
    (plain,) = entry.overloads.values()
    assert engine.is_symbol_defined(plain.fndesc.llvm_func_name)


def test_scalar_operators_skip_numpy_s_ufunc_loops(monkeypatch):
    """While a package kernel compiles, numba's array-operator template declines scalar
    operands without matching ufunc loops (``_jit._scalar_operators_skip_ufuncs``); an
    operation on an array types as before, and other code's compiles are numba's own."""
    from numba.core.typing import npydecl

    generic = npydecl.NumpyRulesArrayOperator.generic
    if not _jit._known([getattr(generic, "__wrapped__", generic)],
                       _jit.ARRAY_OPERATOR_SOURCES, numba.__version__):
        pytest.skip("numba's operator typing is not one ARRAY_OPERATOR_SOURCES knows")
    matched = []
    plain = npydecl.ufunc_find_matching_loop

    def counted(ufunc, arg_types):
        matched.append(ufunc.__name__)
        return plain(ufunc, arg_types)

    monkeypatch.setattr(npydecl, "ufunc_find_matching_loop", counted)

    def scalars(x, y):
        return x * y + x - (y < x)

    def arrays(a, x):
        return (a * x + 1.0)[1]

    assert _as_if_in("sweep.kernels.fake", scalars)(2.0, 3.0) == 8.0
    assert matched == []
    assert _as_if_in("sweep.kernels.fake", arrays)(np.arange(3.0), 2.0) == 3.0
    assert matched[:2] == ["multiply", "add"]
    del matched[:]
    assert _as_if_in("elsewhere", scalars)(2.0, 3.0) == 8.0
    assert "multiply" in matched


def test_compile_flags_hash_and_compare_as_numba_s_own(monkeypatch):
    """While a package kernel compiles, compile flags hash to numba's own value and compare
    as numba's ``values()`` do, without building them through the options' properties
    (``_jit._quick_flag_comparisons``); outside, numba's own methods run."""
    from numba.core import cpu, targetconfig
    from numba.core.compiler import Flags

    config = targetconfig.TargetConfig
    plain_hash = getattr(config.__hash__, "__wrapped__", config.__hash__)
    plain_eq = getattr(config.__eq__, "__wrapped__", config.__eq__)
    if not _jit._known([plain_hash, plain_eq, config.values, type(config).__init__],
                       _jit.TARGET_CONFIG_SOURCES, numba.__version__):
        pytest.skip("numba's TargetConfig is not one TARGET_CONFIG_SOURCES knows")
    assert _as_if_in("sweep.kernels.fake", lambda x, y: min(x, y))(2.0, 3.0) == 2.0
    assert config.__hash__.__wrapped__ is plain_hash and config.__eq__.__wrapped__ is plain_eq

    a, b, c = Flags(), Flags(), Flags()
    for f in (a, b):
        f.nrt, f.error_model, f.fastmath = True, "numpy", cpu.FastMathOptions({"contract"})
    c.nrt = True
    d = Flags(c)
    d._values["not_an_option"] = 1        # numba's values() leave it out
    hashes = [plain_hash(f) for f in (a, c, d)]
    built = []
    monkeypatch.setattr(config, "values", lambda self: built.append(self) or
                        {k: getattr(self, k) for k in self.options})
    monkeypatch.setattr(_jit._COLLECTOR, "_nest", [None])     # as in a package compile
    assert [hash(f) for f in (a, c, d)] == hashes
    assert (a == b, a == c, c == d, a == 1) == (True, False, True, False)
    assert built == [d]
    monkeypatch.setattr(_jit._COLLECTOR, "_nest", [])
    assert a == b and not a == c and built[1:] == [a, b, a, c]


@pytest.mark.parametrize("release", ["0.68.0", "0.69.0"])
def test_the_numba_patches_keep_out_of_other_releases(release):
    """Each patch of numba's internals applies to the sources and release it was written
    for, and to no other: on another release the class is left as it was."""
    from numba.core import cpu
    from numba.core import inline_closurecall as icc
    from numba.core.typing import npydecl

    def unwrapped(fn):
        return getattr(fn, "__wrapped__", fn)

    worker = type("Worker", (), {"inline_function":
                                 unwrapped(icc.InlineWorker.inline_function)})
    context = type("Context", (), {"get_executable":
                                   unwrapped(cpu.CPUContext.get_executable)})
    template = type("Template", (), {"generic":
                                     unwrapped(npydecl.NumpyRulesArrayOperator.generic)})
    assert not _jit._mark_fresh_callees(worker, release)
    assert not _jit._unemitted_helpers_in(context, release)
    assert not _jit._declining_scalars_in(template, release)
    assert "__wrapped__" not in vars(worker)["inline_function"].__dict__
    assert "__wrapped__" not in vars(context)["get_executable"].__dict__
    assert "__wrapped__" not in vars(template)["generic"].__dict__
    from numba.core import ssa
    module = types.SimpleNamespace(**{name: unwrapped(getattr(ssa, name)) for name in (
        "_run_ssa", "_fix_ssa_vars", "_run_block_rewrite")})
    assert not _jit._narrowed_in(module, release)
    assert "__wrapped__" not in vars(module._run_ssa)
    config = type("Config", (), {"__hash__": lambda self: 0, "__eq__": lambda self, o: True})
    assert not _jit._quick_comparisons_in(config, [], release)
    assert vars(config)["__hash__"](None) == 0 and "__wrapped__" not in vars(config)
    if numba.__version__ in _jit.PATCHED_NUMBA:
        assert _jit._mark_fresh_callees(worker, numba.__version__)
        assert _jit._unemitted_helpers_in(context, numba.__version__)
        assert _jit._declining_scalars_in(template, numba.__version__)
        assert vars(worker)["inline_function"].__wrapped__ is unwrapped(
            icc.InlineWorker.inline_function)
        assert _jit._narrowed_in(module, numba.__version__)
        assert module._run_ssa.__wrapped__ is unwrapped(ssa._run_ssa)


def test_a_patch_keeps_out_of_other_sources():
    def get_executable(self, library, fndesc, env):
        return None

    context = type("Context", (), {"get_executable": get_executable})
    assert not _jit._unemitted_helpers_in(context, numba.__version__)
    assert vars(context)["get_executable"] is get_executable


def _branchy(a, n):
    x = 0.0
    y = 1.0
    for i in range(n):
        if a[i] > 0.0:
            x = x + a[i]
        else:
            x = x - 1.0
        if i > 2:
            y = y * 0.5
    z = x
    if n > 3:
        z = 2.0 * x + y
    return z


def _ssa_dump(blocks):
    import io
    out = io.StringIO()
    for label in sorted(blocks):
        out.write(f"label {label}:\n")
        blocks[label].dump(file=out)
    return out.getvalue()


def test_ssa_reconstruction_rewrites_only_the_blocks_naming_each_variable(monkeypatch):
    """While a package kernel compiles, numba's SSA reconstruction visits, for each
    variable assigned more than once, only the blocks whose statements name it
    (``_jit._ssa_visits_mentioning_blocks``), and gives the IR numba's own gives: the same
    statements, names and phi nodes, block for block. Other code's compiles visit every
    block, as numba does."""
    from numba.core import compiler, ssa

    if not _jit._ssa_visits_mentioning_blocks():
        pytest.skip("numba's SSA reconstruction is not one SSA_SOURCES knows")
    visits = []
    run_pass = ssa._run_ssa_block_pass

    def spy(states, blk, handler):
        visits.append(states["label"])
        return run_pass(states, blk, handler)
    monkeypatch.setattr(ssa, "_run_ssa_block_pass", spy)
    own = ssa._run_ssa.__wrapped__(compiler.run_frontend(_branchy).blocks)
    n_own = len(visits)
    monkeypatch.setattr(_jit._COLLECTOR, "_nest", ["a package kernel"])
    narrowed = ssa._run_ssa(compiler.run_frontend(_branchy).blocks)
    n_narrowed = len(visits) - n_own
    assert _ssa_dump(narrowed) == _ssa_dump(own)
    assert "phi" in _ssa_dump(own)
    assert n_narrowed < n_own
    monkeypatch.setattr(_jit._COLLECTOR, "_nest", [])      # other code's compile
    elsewhere = ssa._run_ssa(compiler.run_frontend(_branchy).blocks)
    assert _ssa_dump(elsewhere) == _ssa_dump(own)
    assert len(visits) - n_own - n_narrowed == n_own


def _loops(a, n):
    total = 0.0
    i = 0
    while i < n:
        j = 0
        while j < i:
            if a[j] < 0.0:
                break
            total += a[j] * j
            j += 1
        else:
            total -= 1.0
        if total > 1e3:
            return total
        i += 1
    return total * 2.0


def _random_cfg(rng, n_blocks, n_names):
    """A numba CFG of ``n_blocks`` blocks (forward edges and some back edges, every block
    reachable from the entry) with random use and def sets over ``n_names`` names."""
    from numba.core.controlflow import CFGraph

    cfg = CFGraph()
    for label in range(n_blocks):
        cfg.add_node(label)
    for label in range(1, n_blocks):
        cfg.add_edge(int(rng.integers(0, label)), label)
    for _ in range(n_blocks):
        a, b = sorted(rng.integers(0, n_blocks, 2))
        cfg.add_edge(int(b), int(a))       # a back edge (or a self loop)
    cfg.set_entry_point(0)
    cfg.process()
    names = [f"v{i}" for i in range(n_names)]

    def some():
        return {names[i] for i in rng.integers(0, n_names, rng.integers(0, 6))}
    return cfg, dict.fromkeys(range(n_blocks)), {b: some() for b in range(n_blocks)}, {
        b: some() for b in range(n_blocks)}


def _numba_live_map():
    from numba.core import analysis
    return getattr(analysis.compute_live_map, "__wrapped__", analysis.compute_live_map)


def test_live_variables_on_bit_sets_are_numba_s_own():
    """The live variables found on bit sets (``sweep.kernels._numba_ir``) are those of
    numba's own ``compute_live_map``, block for block, in the same order of blocks: on the
    IR of Python functions with loops, breaks and early returns, on a package kernel's
    IR, and on random graphs with back edges and self loops."""
    from numba.core import analysis, compiler

    from sweep.kernels import _numba_ir, lanes
    numba_live_map = _numba_live_map()
    for fn in (_branchy, _loops, lanes.march_lanes.py_func):
        blocks = compiler.run_frontend(fn).blocks
        cfg = analysis.compute_cfg_from_blocks(blocks)
        usedefs = analysis.compute_use_defs(blocks)
        own = numba_live_map(cfg, blocks, usedefs.usemap, usedefs.defmap)
        ours = _numba_ir.compute_live_map(cfg, blocks, usedefs.usemap, usedefs.defmap)
        assert list(ours) == list(own) and ours == own
        assert any(own.values())
    rng = np.random.default_rng(7)
    for n_blocks, n_names in [(1, 3), (2, 1), (8, 5), (40, 30), (200, 120)] * 4:
        cfg, blocks, use, defs = _random_cfg(rng, n_blocks, n_names)
        own = numba_live_map(cfg, blocks, use, defs)
        assert _numba_ir.compute_live_map(cfg, blocks, use, defs) == own


def test_package_compiles_find_live_variables_on_bit_sets(monkeypatch):
    """While a package kernel compiles, numba's post-processor finds live variables on bit
    sets (``_jit._liveness_on_bit_sets``); other code's compiles run numba's own."""
    from numba.core import analysis

    from sweep.kernels import _numba_ir
    if not _jit._liveness_on_bit_sets():
        pytest.skip("numba's compute_live_map is not one LIVE_MAP_SOURCES knows")
    calls = []
    ours = _numba_ir.compute_live_map
    monkeypatch.setattr(_numba_ir, "compute_live_map", lambda *a: calls.append(a) or ours(*a))
    cfg, blocks, use, defs = _random_cfg(np.random.default_rng(1), 20, 10)
    monkeypatch.setattr(_jit._COLLECTOR, "_nest", ["a package kernel"])
    inside = analysis.compute_live_map(cfg, blocks, use, defs)
    assert len(calls) == 1
    monkeypatch.setattr(_jit._COLLECTOR, "_nest", [])      # other code's compile
    outside = analysis.compute_live_map(cfg, blocks, use, defs)
    assert len(calls) == 1 and inside == outside


@pytest.mark.parametrize("release", ["0.68.0", "0.69.0"])
def test_live_variables_on_bit_sets_keep_out_of_other_releases(release):
    module = types.SimpleNamespace(compute_live_map=_numba_live_map())
    assert not _jit._bit_sets_in(module, release)
    assert module.compute_live_map is _numba_live_map()


def _numba_rec_list_vars():
    from numba.core import ir
    return getattr(ir.Inst._rec_list_vars, "__wrapped__", ir.Inst._rec_list_vars)


def _stmt_vars(stmts):
    return [[id(v) for v in s.list_vars()] for s in stmts]


def test_instruction_variables_are_numba_s_own(monkeypatch):
    """The variables an instruction names (``_numba_ir.vars_in``) are numba's own
    ``list_vars``, the same objects in the same order: every statement of the IR of
    Python functions and of a package kernel, and calls whose arguments nest variables
    in lists, tuples and dicts among other values."""
    from numba.core import compiler, ir

    from sweep.kernels import _numba_ir, lanes
    loc = ir.Loc("f", 1)
    scope = ir.Scope(None, loc)
    a, b, c, f = (ir.Var(scope, name, loc) for name in "abcf")
    nested = [ir.Expr.call(f, [a, b], [("k", c), ("j", a)], loc),
              ir.Expr.build_tuple([a, ir.Expr.binop(operator.add, b, c, loc)], loc),
              ir.Assign(ir.Expr.call(f, (), {}, loc), c, loc),
              ir.SetItem(a, b, c, loc), ir.Del("a", loc), ir.Return(a, loc)]
    nested[0]._kws["extra"] = {"x": [(b, 1.0, "s"), {c}], "y": ir.Const(2, loc)}
    stmts = nested + [s for fn in (_branchy, _loops, lanes.march_lanes.py_func)
                      for block in compiler.run_frontend(fn).blocks.values()
                      for s in block.body]
    plain = _numba_rec_list_vars()
    monkeypatch.setattr(ir.Inst, "_rec_list_vars", plain)
    own = _stmt_vars(stmts)
    values = (a, 3.0, None, [], (a, [b, (c,)]), {"k": {"j": a}}, nested[2])
    own_values = [nested[4]._rec_list_vars(value) for value in values]
    kinds = _numba_ir.Kinds(ir.Var, ir.Inst)
    monkeypatch.setattr(ir.Inst, "_rec_list_vars",
                        lambda self, value: _numba_ir.vars_in(value, kinds))
    assert _stmt_vars(stmts) == own
    assert own[0] == [id(v) for v in (f, a, b, c, a, b)]
    assert [_numba_ir.vars_in(value, kinds) for value in values] == own_values
    assert own_values[4] == [a, b, c]
    assert sum(map(len, own)) > 300


def test_package_compiles_list_instruction_variables_quickly(monkeypatch):
    """While a package kernel compiles, ``Inst.list_vars`` walks an instruction with
    ``_numba_ir.vars_in`` (``_jit._quick_instruction_vars``); other code's compiles walk it
    with numba's own."""
    from numba.core import ir

    from sweep.kernels import _numba_ir
    if not _jit._quick_instruction_vars():
        pytest.skip("numba's Inst._rec_list_vars is not one LIST_VARS_SOURCES knows")
    calls = []
    ours = _numba_ir.vars_in
    monkeypatch.setattr(_numba_ir, "vars_in", lambda *a: calls.append(a) or ours(*a))
    loc = ir.Loc("f", 1)
    var = ir.Var(ir.Scope(None, loc), "a", loc)
    stmt = ir.Assign(ir.Expr.binop(operator.add, var, var, loc), var, loc)
    monkeypatch.setattr(_jit._COLLECTOR, "_nest", ["a package kernel"])
    assert stmt.list_vars() == [var, var, var] and len(calls) == 2
    monkeypatch.setattr(_jit._COLLECTOR, "_nest", [])      # other code's compile
    assert stmt.list_vars() == [var, var, var] and len(calls) == 2


@pytest.mark.parametrize("release", ["0.68.0", "0.69.0"])
def test_quick_instruction_variables_keep_out_of_other_releases(release):
    inst = type("Inst", (), {"_rec_list_vars": _numba_rec_list_vars()})
    module = types.SimpleNamespace(Inst=inst, Var=object)
    assert not _jit._quick_vars_in(module, release)
    assert vars(inst)["_rec_list_vars"] is _numba_rec_list_vars()


def _llvmlite_abi_queries():
    from llvmlite.ir import types as ir_types

    return [getattr(getattr(ir_types.Type, name), "__wrapped__", getattr(ir_types.Type, name))
            for name in ("get_abi_size", "get_abi_alignment")]


def test_abi_sizes_are_llvm_s_answers_asked_once_per_type(monkeypatch):
    """During a package compile a type's ABI size and alignment are LLVM's own answers
    (llvmlite's unwrapped queries, asked afresh here), each asked of LLVM once per type
    text; an identified structure, whose text is only its name, is asked every time."""
    if not _jit._abi_sizes_remembered():
        pytest.skip("llvmlite's ABI queries are not ones ABI_SIZE_SOURCES knows")
    from llvmlite import ir

    target_data = numba.core.registry.cpu_target.target_context.target_data
    plain_size, plain_align = _llvmlite_abi_queries()
    f64, i1, i64 = ir.DoubleType(), ir.IntType(1), ir.IntType(64)
    kinds = [i1, ir.IntType(8), i64, f64, ir.FloatType(), ir.PointerType(f64),
             ir.LiteralStructType([f64, i1]), ir.LiteralStructType([i1, f64, i1]),
             ir.LiteralStructType([i64, ir.LiteralStructType([f64, i1]), i1]),
             ir.ArrayType(f64, 3), ir.VectorType(f64, 4), ir.VectorType(i1, 3),
             ir.LiteralStructType([ir.ArrayType(i1, 2), ir.VectorType(f64, 4)])]
    parsed = []
    plain_parse = ir.Type._get_ll_global_value_type

    def counted(self, *args, **kwargs):
        parsed.append(str(self))
        return plain_parse(self, *args, **kwargs)
    monkeypatch.setattr(ir.Type, "_get_ll_global_value_type", counted)
    monkeypatch.setattr(_jit._COLLECTOR, "_nest", ["a package kernel"])
    for round_ in range(3):
        before = len(parsed)
        for t in kinds:
            assert t.get_abi_size(target_data) == plain_size(t, target_data)
            assert t.get_abi_alignment(target_data) == plain_align(t, target_data)
        # The plain queries parse every time; the remembered ones at most in the first round
        # (earlier compiles may have asked about some of these types already).
        if round_:
            assert len(parsed) - before == 2 * len(kinds)
    # Two identified structures of one name in two contexts: each its own answer.
    small = ir.global_context.get_identified_type("sweep_t")
    small.set_body(i1)
    other = ir.context.Context()
    large = other.get_identified_type("sweep_t")
    large.set_body(ir.ArrayType(f64, 8))
    parsed.clear()
    assert small.get_abi_size(target_data) == 1
    assert large.get_abi_size(target_data, other) == 64
    assert small.get_abi_size(target_data) == 1 and len(parsed) == 3


@pytest.mark.parametrize("release", ["0.68.0", "0.69.0"])
def test_remembered_abi_sizes_keep_out_of_other_releases(release):
    plain_size, plain_align = _llvmlite_abi_queries()
    kind = type("Type", (), {"get_abi_size": plain_size, "get_abi_alignment": plain_align})
    assert not _jit._remembered_in(kind, release)
    assert vars(kind)["get_abi_size"] is plain_size
    assert vars(kind)["get_abi_alignment"] is plain_align


def _looping_module():
    """An llvmlite module with a loop (a phi that uses an instruction after it), and weak
    references to its objects."""
    from llvmlite import ir

    module = ir.Module("taken_apart")
    i64 = ir.IntType(64)
    fn = ir.Function(module, ir.FunctionType(i64, [i64]), "count")
    entry, loop, done = (fn.append_basic_block(n) for n in ("entry", "loop", "done"))
    b = ir.IRBuilder(entry)
    b.branch(loop)
    b.position_at_end(loop)
    i = b.phi(i64)
    nxt = b.add(i, ir.Constant(i64, 1))
    i.add_incoming(ir.Constant(i64, 0), entry)
    i.add_incoming(nxt, loop)
    b.cbranch(b.icmp_signed("<", nxt, fn.args[0]), loop, done)
    b.position_at_end(done)
    b.ret(nxt)
    refs = [weakref.ref(x) for x in (module, fn, entry, loop, done, i, nxt)]
    return module, refs


def test_taken_apart_llvmlite_ir_is_freed_without_the_collector():
    """Taken apart, an llvmlite module's functions, blocks and instructions (which hold one
    another in cycles) are freed by reference counting alone; left whole, they wait for
    the cyclic collector."""
    gc.disable()
    try:
        module, refs = _looping_module()
        del module
        assert all(r() is not None for r in refs)         # cycles: nothing freed
        gc.collect()
        module, refs = _looping_module()
        handed = weakref.WeakSet([module])
        _jit._take_apart(handed)
        assert not handed
        del module
        assert [r() for r in refs] == [None] * len(refs)
    finally:
        gc.enable()


def test_a_package_compile_takes_its_llvmlite_ir_apart_when_it_ends(monkeypatch):
    """The llvmlite modules a package kernel's compile handed to numba's code libraries are
    taken apart when the compile ends, after their text went to LLVM: the kernel runs, and
    so do the kernels compiled after it."""
    if not _jit._llvm_ir_taken_apart():
        pytest.skip("numba's add_ir_module is not one ADD_IR_SOURCES knows")
    from numba.core.codegen import CPUCodeLibrary

    handed = []
    recorded = CPUCodeLibrary.add_ir_module

    def add_ir_module(self, ir_module):
        handed.append(ir_module)
        return recorded(self, ir_module)

    helper, kernel = _kernel_calling_a_helper("sweep.kernels.fake_apart")
    monkeypatch.setattr(CPUCodeLibrary, "add_ir_module", add_ir_module)
    assert kernel(2.0) == 9.0
    monkeypatch.undo()
    assert handed and not _jit._HANDED
    assert all(not m.globals for m in handed)
    (kres,) = kernel.overloads.values()
    # LLVM's own module, which the taken-apart llvmlite objects were the source of, stays.
    assert "define" in kres.library.get_llvm_str()
    again = _as_if_in("sweep.kernels.fake_apart", lambda x: helper(x) - 1.0)
    assert again(2.0) == 7.0 and kernel(3.0) == 28.0


@pytest.mark.parametrize("release", ["0.68.0", "0.69.0"])
def test_taking_llvmlite_ir_apart_keeps_out_of_other_releases(release):
    from numba.core.codegen import CPUCodeLibrary

    plain = getattr(CPUCodeLibrary.add_ir_module, "__wrapped__", CPUCodeLibrary.add_ir_module)
    library = type("Library", (), {"add_ir_module": plain})
    assert not _jit._handed_recorded_in(library, release)
    assert vars(library)["add_ir_module"] is plain
