"""Two of numba's IR analyses computed faster, with the same results: the variables live
at each block's entry, on bit sets, and the variables an instruction names.

numba recomputes which variables are live at each block's entry after nearly every pass
and every inlined call site (``numba.core.analysis.compute_live_map``, through its IR
post-processor: 2,367 times in the first ``sweep.cor()``). Its sets of names grow to
thousands of variables in the large kernels, and each union copies them: 1.3 s of that
compile. Here each variable is a bit of a Python integer, and a union is one ``|`` of
machine words. The equations and their least fixed point are numba's (variables defined or
used on a path into a block; live ones pushed back to the predecessors that can reach a
definition and do not define them), so the sets hold the same names (iterated in another
order, on which nothing numba compiles depends: the kernels' assembly is byte for byte the
same).

The variables an instruction names (``ir.Inst.list_vars``, which the live variables' use
and def sets, numba's SSA reconstruction and its ``del`` placement all call) are found by a
walk over its attributes, four ``isinstance`` tests and a call for every value, 3 million
calls in the first ``sweep.cor()``. :func:`vars_in` walks the same values in the same order
and gives the same list, deciding each value's kind once per type and recursing only into
containers. ``_jit`` swaps both in for the package's compiles only.

Owns: nothing but these analyses. May import: nothing from ``sweep``.
"""
from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable

import numpy as np

__all__ = ["compute_live_map", "Kinds", "vars_in"]


class _Names:
    """Variable names, each given a bit in the order first seen."""

    def __init__(self) -> None:
        self._index: dict[str, int] = {}
        self._names: list[str] = []

    def bits(self, names: Iterable[str]) -> int:
        """The bit set of ``names``."""
        out = 0
        for name in names:
            i = self._index.get(name)
            if i is None:
                i = self._index[name] = len(self._names)
                self._names.append(name)
            out |= 1 << i
        return out

    def decoder(self):
        """A function from a bit set back to its set of names."""
        nbytes = (len(self._names) + 7) // 8
        names = np.array(self._names, dtype=object)

        def names_of(bits: int) -> set[str]:
            if not bits:
                return set()
            # Set bits found in C (numpy) rather than one big-integer shift at a time.
            raw = np.frombuffer(bits.to_bytes(nbytes, "little"), np.uint8)
            return set(names[np.flatnonzero(np.unpackbits(raw, bitorder="little"))].tolist())
        return names_of


def compute_live_map(cfg, blocks, var_use_map, var_def_map) -> dict:
    """Variables live at the entry of each block (numba's ``compute_live_map``, same
    arguments and result: a dict of block label -> set of names, in ``blocks``' order)."""
    names = _Names()
    use = {label: names.bits(s) for label, s in var_use_map.items()}
    defs = {label: names.bits(s) for label, s in var_def_map.items()}
    order = list(cfg.topo_order())
    reach = _reaching(cfg, order, use, defs)
    live = _pushed_back(cfg, order, {label: use[label] for label in blocks}, defs, reach)
    names_of = names.decoder()
    return {label: names_of(bits) for label, bits in live.items()}


def _reaching(cfg, order, use, defs) -> dict:
    """Variables defined or used on some path into each block, the block's own included
    (numba's ``def_reach``)."""
    reach: dict = defaultdict(int)
    succs = {label: [s for s, _ in cfg.successors(label)] for label in order}
    while True:
        before = dict(reach)
        for label in order:
            here = reach[label] = reach[label] | defs[label] | use[label]
            for s in succs[label]:
                reach[s] |= here
        if reach == before:
            return reach


def _pushed_back(cfg, order, live, defs, reach) -> dict:
    """``live`` (each block's uses to start) grown to the fixed point of numba's
    ``liveness``: what is live at a block's entry is live at the end of each predecessor
    that can have defined it, and at its entry unless it defines it."""
    preds = {label: [p for p, _ in cfg.predecessors(label)] for label in order}
    backward = order[::-1]
    while True:
        before = dict(live)
        for label in backward:
            here = live[label]
            for p in preds[label]:
                live[p] |= here & reach[p] & ~defs[p]
        if live == before:
            return live


_LEAF, _VAR, _INST, _SEQUENCE, _MAPPING = range(5)


class Kinds(dict):
    """Type -> how numba's ``Inst._rec_list_vars`` treats its values, found once per type."""

    def __init__(self, var_type, inst_type) -> None:
        super().__init__()
        self._var, self._inst = var_type, inst_type

    def __missing__(self, kind_of):
        kind = (_VAR if issubclass(kind_of, self._var) else
                _INST if issubclass(kind_of, self._inst) else
                _SEQUENCE if issubclass(kind_of, (list, tuple)) else
                _MAPPING if issubclass(kind_of, dict) else _LEAF)
        self[kind_of] = kind
        return kind


def vars_in(value, kinds: Kinds) -> list:
    """numba's ``Inst._rec_list_vars(value)``: the variables (``kinds``' var type) in
    ``value``, an instruction's (its own ``list_vars``), a list's, tuple's or dict's
    values' in order; a new list."""
    kind = kinds[type(value)]
    if kind == _VAR:
        return [value]
    if kind == _INST:
        return value.list_vars()
    if kind == _LEAF:
        return []
    out = []
    for item in (value if kind == _SEQUENCE else value.values()):
        # One level inline: most values are leaves and variables, not worth a call.
        item_kind = kinds[type(item)]
        if item_kind == _VAR:
            out.append(item)
        elif item_kind == _INST:
            out.extend(item.list_vars())
        elif item_kind != _LEAF:
            out.extend(vars_in(item, kinds))
    return out
