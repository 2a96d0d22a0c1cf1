"""Fixed-count loops that stay loops in the generated C.

An iteration with a fixed count (the bisection of :func:`armgen.symbolic.steps.min_eigenvalue`)
would otherwise be unrolled into straight-line code, one copy per use: flash grows with the
count. A :class:`Loop` keeps its body once: ``step`` is an SX function ``(state, *constants) →
next state``, and ``function`` applies it ``count`` times (a CasADi ``fold``) behind a
``never_inline`` MX function, so an SX expression that uses it holds one call node. The CasADi
interpreter evaluates that call as the fold; the C emitter writes the step's statements once,
inside ``for (k = 0; k < count; ++k)``, in a static function the calling functions share. Both
run the step's operations in the same order, so double results agree to the bit. A loop may
run fewer times in the float build (``float_count``: where the iteration converges to float's
resolution sooner); the float C is compared with the double reference within its bounds anyway.
A loop may also name a ``stop`` entry of its state: a step whose state has a nonzero ``stop``
entry must return that state unchanged, so leaving the loop there (the C ``break``s, the NumPy
replay stops the finished samples) gives the result of running all ``count`` iterations.
A loop may also let the float C fuse its multiply–adds (``fused_float``): the step is emitted
where the compiler may contract ``a·b + c`` into one fused multiply–add (one rounding instead
of two: a Cortex-M4F's VFMA), for a loop with a time budget on the target; the double build
never does (the C and Python must run the same roundings there).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca


@dataclass(frozen=True, eq=False)  # hashed by identity: one Loop per registered name
class Loop:
    function: ca.Function  # (state, *constants) -> final state; never inlined into SX
    step: ca.Function  # (state, *constants) -> next state, one iteration, SX
    count: int  # iterations (the CasADi function's, and the double C's)
    float_count: int  # iterations of the float C
    stop: int | None = None  # state entry: nonzero = finished, the step is then the identity
    fused_float: bool = False  # the float C may contract a·b + c into fused multiply–adds


_LOOPS: dict[str, Loop] = {}


def fixed_loop(step: ca.Function, count: int, float_count: int | None = None, stop: int | None = None,
               fused_float: bool = False) -> ca.Function:
    """The function applying the SX ``step`` ``count`` times (``float_count`` times in the float
    C), registered by the step's name, which must identify the step: one name, one loop.
    ``stop``: the state entry after which the step is the identity; ``fused_float``: the float C
    may fuse multiply–adds (see the module text)."""
    name = f"{step.name()}_loop"
    if name not in _LOOPS:
        inputs = [ca.MX.sym(step.name_in(k), step.sparsity_in(k).shape) for k in range(step.n_in())]
        constants = [ca.repmat(x, 1, count) for x in inputs[1:]]
        final = step.fold(count)(inputs[0], *constants)
        function = ca.Function(name, inputs, [final], step.name_in(), ["final"], {"never_inline": True})
        _LOOPS[name] = Loop(function, step, count, count if float_count is None else float_count, stop, fused_float)
    return _LOOPS[name].function


def find_loop(name: str) -> Loop | None:
    return _LOOPS.get(name)


def calls_in_order(func: ca.Function) -> list[ca.Function]:
    """The functions ``func``'s call instructions (``OP_CALL``) call, one per instruction, in
    the algorithm's order: each call instruction's own SX node names its function."""
    calls = [k for k in range(func.n_instructions()) if func.instruction_id(k) == ca.OP_CALL]
    if not calls:
        return []
    nodes = func.instructions_sx()
    callees = [nodes[k].which_function() for k in calls]
    if any(len(func.instruction_input(k)) != callee.nnz_in() for k, callee in zip(calls, callees)):
        raise ValueError(f"{func.name()}: cannot match its {len(calls)} call instructions to the calls "
                         f"{[callee.name() for callee in callees]}")
    return callees
