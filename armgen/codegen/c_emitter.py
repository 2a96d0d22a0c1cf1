"""Emit C99 from a CasADi SX ``Function``, instruction by instruction.

CasADi's own ``CodeGenerator`` writes ``sin``/``cos`` and double literals even with
``casadi_real=float``, so armgen walks the SX algorithm itself (``instruction_id`` /
``instruction_input`` / ``instruction_output`` / ``instruction_constant``) and writes each
step through the precision macros of the header: ``<P>_LIT(x)`` pastes an ``f`` suffix in
float mode and ``<P>_SIN`` … map to ``sinf`` …, so one source compiles to true single or
double precision with no promotion. The work vector (already register-allocated by
CasADi) becomes scalar locals, which the C compiler keeps in registers.

A fixed loop's step (:mod:`armgen.symbolic.loops`) is emitted with its selects as branches:
SX has no branches (``if_else(c, x, y)`` is ``if_else_zero(c, x) + if_else_zero(!c, y)``, both
sides computed), so a solver step would compute its restart code at every step. There each
select becomes one ``c ? x : y`` (``+ 0``, as the sum gives +0 for −0), and the statements
that only one side of the selects on one condition reads move into an ``if``/``else``: the
same operations on the same values, run only when taken (the step is taken from CasADi with
one work register per instruction, so that statements can move, and its locals are shared
again afterwards, ``_reused_registers``). The loop copies the next state entry by entry (a
copy loop became a ``memcpy`` call; swapping two buffers instead put a small state, that GCC
kept in registers, in memory), and the step reads its stop entry as 0 (the loop has left
otherwise).
"""

from __future__ import annotations

import heapq
import itertools
import re
from collections import Counter
from dataclasses import dataclass, field
from functools import lru_cache

import casadi as ca

from ..data import render_template
from ..errors import ArmgenError
from ..symbolic.loops import Loop, calls_in_order, find_loop

# op code -> (category for op counts, C template over operand names a, b, the macro prefix P
# and the type prefix p (the lower-case prefix of <p>_real))
_BINARY = {
    ca.OP_ADD: ("add", "{a} + {b}"),
    ca.OP_SUB: ("add", "{a} - {b}"),
    ca.OP_MUL: ("mul", "{a} * {b}"),
    ca.OP_DIV: ("div", "{a} / {b}"),
    ca.OP_POW: ("pow", "{P}_POW({a}, {b})"),
    ca.OP_CONSTPOW: ("pow", "{P}_POW({a}, {b})"),
    ca.OP_ATAN2: ("trig", "{P}_ATAN2({a}, {b})"),
    ca.OP_HYPOT: ("sqrt", "{P}_HYPOT({a}, {b})"),
    ca.OP_FMIN: ("minmax", "{P}_FMIN({a}, {b})"),
    ca.OP_FMAX: ("minmax", "{P}_FMAX({a}, {b})"),
    ca.OP_FMOD: ("div", "{P}_FMOD({a}, {b})"),
    ca.OP_COPYSIGN: ("minmax", "{P}_COPYSIGN({a}, {b})"),
    ca.OP_LT: ("compare", "({p}_real)({a} < {b})"),
    ca.OP_LE: ("compare", "({p}_real)({a} <= {b})"),
    ca.OP_EQ: ("compare", "({p}_real)({a} == {b})"),
    ca.OP_NE: ("compare", "({p}_real)({a} != {b})"),
    ca.OP_AND: ("compare", "({p}_real)(({a} != {P}_LIT(0.0)) && ({b} != {P}_LIT(0.0)))"),
    ca.OP_OR: ("compare", "({p}_real)(({a} != {P}_LIT(0.0)) || ({b} != {P}_LIT(0.0)))"),
    ca.OP_IF_ELSE_ZERO: ("select", "(({a} != {P}_LIT(0.0)) ? {b} : {P}_LIT(0.0))"),
}
_UNARY = {
    ca.OP_ASSIGN: ("copy", "{a}"),
    ca.OP_NEG: ("add", "-{a}"),
    ca.OP_SQ: ("mul", "{a} * {a}"),
    ca.OP_TWICE: ("add", "{a} + {a}"),
    ca.OP_INV: ("div", "{P}_LIT(1.0) / {a}"),
    ca.OP_SQRT: ("sqrt", "{P}_SQRT({a})"),
    ca.OP_SIN: ("trig", "{P}_SIN({a})"),
    ca.OP_COS: ("trig", "{P}_COS({a})"),
    ca.OP_TAN: ("trig", "{P}_TAN({a})"),
    ca.OP_ASIN: ("trig", "{P}_ASIN({a})"),
    ca.OP_ACOS: ("trig", "{P}_ACOS({a})"),
    ca.OP_ATAN: ("trig", "{P}_ATAN({a})"),
    ca.OP_EXP: ("exp", "{P}_EXP({a})"),
    ca.OP_LOG: ("exp", "{P}_LOG({a})"),
    ca.OP_FABS: ("minmax", "{P}_FABS({a})"),
    ca.OP_FLOOR: ("minmax", "{P}_FLOOR({a})"),
    ca.OP_CEIL: ("minmax", "{P}_CEIL({a})"),
    ca.OP_SIGN: ("compare", "(({a} > {P}_LIT(0.0)) ? {P}_LIT(1.0) : (({a} < {P}_LIT(0.0)) ? {P}_LIT(-1.0) : {a}))"),
    ca.OP_NOT: ("compare", "({p}_real)({a} == {P}_LIT(0.0))"),
}

# The math macros every generated header defines, in both precisions.
MATH_MACROS = ("SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN", "ATAN2", "SQRT", "HYPOT", "POW", "EXP", "LOG",
               "FABS", "FLOOR", "CEIL", "FMIN", "FMAX", "FMOD", "COPYSIGN")


def c_literal(value: float, macro_prefix: str) -> str:
    """A literal through the precision macro; shortest round-trip decimal of the double."""
    if value != value or value in (float("inf"), float("-inf")):
        raise ArmgenError(f"non-finite constant {value} in a symbolic expression")
    text = repr(abs(float(value)))
    if "." not in text and "e" not in text:
        text += ".0"
    if "e" in text and "." not in text.split("e")[0]:
        mantissa, exponent = text.split("e")
        text = f"{mantissa}.0e{exponent}"
    lit = f"{macro_prefix}_LIT({text})"
    return f"(-{lit})" if value < 0 else lit


@dataclass
class EmittedFunction:
    name: str
    body: str
    op_counts: Counter = field(default_factory=Counter)
    work_reals: int = 0
    loops: tuple[str, ...] = ()  # the loop functions (symbolic.loops) the body calls

    @property
    def flops(self) -> int:
        return sum(v for k, v in self.op_counts.items() if k not in ("copy", "const", "input", "output"))


# Operations a trigonometric argument may be built of for the sin/cos table (joint angle plus
# offsets, a sign): anything else keeps sin/cos inline. No product, so that a compiler that
# contracts within an expression (clang's default) cannot fuse the one-line angle into an FMA
# that the one-operation-per-statement body never allows. Longer argument expressions (C text)
# are not worth a table slot.
_ANGLE_OPS = {ca.OP_ADD, ca.OP_SUB, ca.OP_NEG, ca.OP_ASSIGN, ca.OP_TWICE}
_ANGLE_TEXT_MAX = 160


def _input_text(arg_names: list[str], arg_scalar: list[bool], ins: list[int]) -> str:
    """The C that reads an input instruction's value: ``x`` for a scalar, ``x[nz]`` else."""
    return arg_names[ins[0]] if arg_scalar[ins[0]] else f"{arg_names[ins[0]]}[{ins[1]}]"


def _trig_table(func: ca.Function, arg_names: list[str], arg_scalar: list[bool],
                macro_prefix: str) -> tuple[dict[int, int], list[str]]:
    """Slots of a sin/cos table: {instruction of a sin or cos: slot} and each slot's angle as a
    C expression of the inputs (the same operations as the SX, so the same value). A sin or cos
    of anything else (a solver's computed angle) has no slot and stays inline."""
    text: dict[int, str | None] = {}
    slots: dict[str, int] = {}
    table: dict[int, int] = {}
    p = macro_prefix.lower()
    for k in range(func.n_instructions()):
        op, ins, outs = func.instruction_id(k), func.instruction_input(k), func.instruction_output(k)
        if op == ca.OP_OUTPUT:
            continue
        value = None
        if op == ca.OP_INPUT:
            value = _input_text(arg_names, arg_scalar, ins)
        elif op == ca.OP_CONST:
            value = c_literal(func.instruction_constant(k), macro_prefix)
        elif op in (ca.OP_SIN, ca.OP_COS):
            angle = text.get(ins[0])
            if angle is not None:
                table[k] = slots.setdefault(angle, len(slots))
        elif op in _ANGLE_OPS:
            operands = [text.get(i) for i in ins[:2 if op in _BINARY else 1]]
            if None not in operands:
                template = (_BINARY if op in _BINARY else _UNARY)[op][1]
                value = "(" + template.format(a=operands[0], b=operands[-1], P=macro_prefix, p=p) + ")"
                value = value if len(value) <= _ANGLE_TEXT_MAX else None
        for o in outs:
            if o >= 0:
                text[o] = value
    return table, list(slots)


def _whole_input(func: ca.Function, arg_names: list[str], arg_scalar: list[bool], angles: list[str]) -> str | None:
    """The name of the vector input whose first len(angles) entries are exactly the table's
    angles, if any (then the table reads it in place)."""
    if not angles:
        return None
    for k, (name, scalar) in enumerate(zip(arg_names, arg_scalar)):
        if (not scalar and func.sparsity_in(k).nnz() >= len(angles)
                and set(angles) == {f"{name}[{i}]" for i in range(len(angles))}):
            return name
    return None


@dataclass(frozen=True)
class _Statement:
    """The C of one SX instruction, with the work registers it writes and reads."""

    lines: list[str]
    writes: tuple[int, ...]
    reads: tuple[int, ...]
    op: int = -1  # the SX operation (OP_*); -1 for a call, an input, an output or a table read
    constant: float | None = None  # the value an OP_CONST writes


def _live(statements: list[_Statement]) -> list[_Statement]:
    """The statements without dead stores: a register written and then written again (or never
    read) before any read. The SX algorithm has none; reading sin and cos from the table leaves
    the instructions that only fed them (a joint angle's load, its offset) without a reader."""
    live: set[int] = set()
    kept = []
    for statement in reversed(statements):
        if statement.writes and live.isdisjoint(statement.writes):
            continue  # every instruction but an output is pure: nothing else sees it
        kept.append(statement)
        live.difference_update(statement.writes)
        live.update(statement.reads)
    return kept[::-1]


# The op of a select: fused from CasADi's if_else (if_else_zero(c, x) + if_else_zero(!c, y);
# reads c, x, y) or an if_else_zero(c, x) on its own (reads c, x; else 0).
_SELECT = -2


def _fused_selects(statements: list[_Statement], macro_prefix: str) -> list[_Statement]:
    """CasADi's SX ``if_else(c, x, y)`` is ``if_else_zero(c, x) + if_else_zero(!c, y)``: the sum
    becomes one select ``(c ? x : y) + 0`` (``x + 0`` is x but for −0, which the sum turns
    into +0 as well, so the value is the same to the bit). An ``if_else_zero`` left on its own
    is a select too (``c ? x : 0``, as CasADi evaluates it)."""
    writer = {w: st for st in statements for w in st.writes}
    unsigned = set()  # registers that cannot hold −0 (a select's x + 0)
    fused = []
    for st in statements:
        if st.op == ca.OP_ADD and st.reads[0] != st.reads[1]:
            left, right = writer.get(st.reads[0]), writer.get(st.reads[1])
            if left and right and left.op == right.op == ca.OP_IF_ELSE_ZERO:
                for (cond, then), (negated, other) in ((left.reads, right.reads), (right.reads, left.reads)):
                    if writer.get(negated) is not None and writer[negated].op == ca.OP_NOT \
                            and writer[negated].reads == (cond,):
                        known = writer[cond].constant if cond in writer else None
                        if known is not None:  # a constant condition: the side it takes
                            taken = then if known != 0.0 else other
                            plus = "" if taken in unsigned else f" + {macro_prefix}_LIT(0.0)"
                            st = _Statement([f"w{st.writes[0]} = w{taken}{plus};"], st.writes, (taken,), ca.OP_ASSIGN)
                            unsigned.add(st.writes[0])
                            break
                        text = (f"w{st.writes[0]} = ((w{cond} != {macro_prefix}_LIT(0.0)) ? w{then} : w{other})"
                                f" + {macro_prefix}_LIT(0.0);")
                        st = _Statement([text], st.writes, (cond, then, other), _SELECT)
                        unsigned.add(st.writes[0])
                        break
        fused.append(st)
    return [_Statement(st.lines, st.writes, st.reads, _SELECT) if st.op == ca.OP_IF_ELSE_ZERO else st
            for st in _live(fused)]


def _branched(body: list[_Statement], macro_prefix: str) -> list[str]:
    """The statements (selects fused, :func:`_fused_selects`) with each select's sides as an
    ``if``/``else``: a statement whose value only one side of the selects on one condition
    reads (directly or through other such statements) moves into that side, so it runs only
    when that side is taken (the restart code of a solver step: once per restart instead of
    every step). The same operations on the same operands, so the same values. The selects
    on one condition share one block; blocks and statements keep their order but where a
    reader must follow a block."""
    writes = [w for st in body for w in st.writes]
    if len(writes) != len(set(writes)):
        raise ArmgenError("internal: branched emission needs each work register written once")
    plain: set[int] = set()  # selects emitted as one line
    while True:
        owner, groups = _owners(body, plain)
        owning = {key[1] for key in owner if key is not None}
        empty = {k for group, members in groups.items() if group not in owning for k in members}
        if empty:
            plain |= empty
            continue
        try:
            return _emit_level(body, owner, groups, None, macro_prefix)
        except _Unordered as err:
            plain |= set(groups[err.group])


class _Unordered(Exception):
    """A select group's block would have to come both before and after another statement."""

    def __init__(self, group: tuple):
        super().__init__(group)
        self.group = group


def _owners(body: list[_Statement], plain: set[int]) -> tuple[list, dict]:
    """Each statement's owner, ``(side, group)`` or None (top level), and each group's selects
    (positions, in order); a group is ``(its selects' owner, condition register)``. Outputs
    and calls stay at the top level."""
    users: dict[int, list[int]] = {}
    for k, st in enumerate(body):
        for r in set(st.reads):
            users.setdefault(r, []).append(k)
    owner: list = [None] * len(body)
    group_of: dict[int, tuple] = {}
    groups: dict[tuple, list[int]] = {}
    for k in reversed(range(len(body))):  # every reader of statement k comes after it
        st = body[k]
        if st.writes and st.op != -1:
            value, keys = st.writes[0], set()
            for u in users.get(value, []):
                if u in group_of:
                    cond, then, *rest = body[u].reads
                    other = rest[0] if rest else None
                    side = "then" if value == then and value not in (cond, other) else \
                        "else" if value == other and value not in (cond, then) else None  # other None: 0
                    keys.add((side, group_of[u]) if side else None)
                else:
                    keys.add(owner[u])
            owner[k] = keys.pop() if len(keys) == 1 else None
        if st.op == _SELECT and k not in plain:
            group_of[k] = (owner[k], st.reads[0])
            groups.setdefault(group_of[k], []).insert(0, k)
    return owner, groups


def _emit_level(body: list[_Statement], owner: list, groups: dict, key, macro_prefix: str) -> list[str]:
    """The lines of the statements owned by ``key`` (None: the top level), each select group
    as one block: in their order, but a statement that reads a block's select comes after it
    (a stable topological order; a block that cannot be placed raises _Unordered)."""
    member_group = {k: group for group, members in groups.items() for k in members}
    items = []  # (position, reads, writes, group or statement position)
    for k, st in enumerate(body):
        if owner[k] != key:
            continue
        if k in member_group:
            group = member_group[k]
            if k == groups[group][0]:
                inner = [i for i in range(len(body)) if _within(owner, i, group)] + groups[group]
                written = {w for i in inner for w in body[i].writes}
                read = {r for i in inner for r in body[i].reads} - written
                items.append((groups[group][-1], read, {body[m].writes[0] for m in groups[group]}, group))
            continue
        items.append((k, set(st.reads), set(st.writes), k))
    producer = {w: n for n, item in enumerate(items) for w in item[2]}
    waiting = [sum(1 for r in item[1] if r in producer) for item in items]
    readers: dict[int, list[int]] = {}
    for n, item in enumerate(items):
        for r in item[1]:
            if r in producer:
                readers.setdefault(producer[r], []).append(n)
    ready = [(items[n][0], n) for n in range(len(items)) if waiting[n] == 0]
    heapq.heapify(ready)
    lines: list[str] = []
    while ready:
        _, n = heapq.heappop(ready)
        what = items[n][3]
        lines += body[what].lines if isinstance(what, int) else _block(body, owner, groups, what, macro_prefix)
        for reader in readers.get(n, []):
            waiting[reader] -= 1
            if waiting[reader] == 0:
                heapq.heappush(ready, (items[reader][0], reader))
    stuck = [items[n][3] for n in range(len(items)) if waiting[n] > 0 and not isinstance(items[n][3], int)]
    if stuck:
        raise _Unordered(stuck[0])
    return lines


def _within(owner: list, k: int, group: tuple) -> bool:
    """Whether statement k sits in one of the group's sides (at any depth)."""
    key = owner[k]
    while key is not None:
        if key[1] == group:
            return True
        key = key[1][0]
    return False


def _block(body: list[_Statement], owner: list, groups: dict, group: tuple, macro_prefix: str) -> list[str]:
    """``if (c) { then side; selects = then operands } else { … }``."""
    zero = f"{macro_prefix}_LIT(0.0)"
    members = groups[group]
    lines = [f"if (w{group[1]} != {zero}) {{"]
    for side, operand in (("then", 1), ("else", 2)):
        if side == "else":
            lines.append("} else {")
        inner = _emit_level(body, owner, groups, (side, group), macro_prefix)
        inner += [_assignment(body[m], operand, zero) for m in members]
        lines += ["  " + line for line in inner]
    lines.append("}")
    return lines


_REGISTER = re.compile(r"\bw(\d+)\b")
_DEFINITION = re.compile(r"\s*w(\d+) = ")
_SELF_ASSIGNMENT = re.compile(r"\s*(w\d+) = \1;")


def _reused_registers(lines: list[str]) -> tuple[list[str], set[int]]:
    """The lines with their work registers renamed so that values whose lifetimes do not
    overlap share one (linear scan over the lines in order; a value's lifetime runs from its
    first assignment to its last read). Branched emission starts from one register per
    instruction, thousands of locals that cppcheck's analysis takes minutes over; a value
    assigned in a branch is read only there or, for a select, assigned in both branches, so
    the order of the lines bounds every lifetime. Returns the lines and the registers used."""
    first: dict[int, int] = {}
    last: dict[int, int] = {}
    for k, line in enumerate(lines):
        match = _DEFINITION.match(line)
        if match:
            first.setdefault(int(match.group(1)), k)
        for register in _REGISTER.findall(line[match.end():] if match else line):
            last[int(register)] = k
    rename: dict[int, int] = {}
    free: list[int] = []  # registers no value holds any more (a heap: the lowest first)
    held: list[tuple[int, int]] = []  # (last read, register) of the values holding one
    for value in sorted(first, key=first.get):
        start = first[value]
        while held and held[0][0] <= start:  # read last at or before this assignment
            heapq.heappush(free, heapq.heappop(held)[1])
        rename[value] = heapq.heappop(free) if free else len(held)
        heapq.heappush(held, (last.get(value, start), rename[value]))
    renamed = [_REGISTER.sub(lambda m: f"w{rename[int(m.group(1))]}", line) for line in lines]
    # a select's side that passes on a value read last there now names one register twice
    return [line for line in renamed if not _SELF_ASSIGNMENT.fullmatch(line)], set(rename.values())


# A statement that only reads an input entry or writes a literal: its text goes into each
# reader instead (an input is re-read where it is used rather than held in a register).
_LEAF = re.compile(r"w(\d+) = ((?:\w+(?:\[\d+\])?)|(?:\(?-?\w+_LIT\([^()]*\)\)?));")


def _scheduled(statements: list[_Statement]) -> tuple[list[str], set[int]]:
    """Straight-line statements reordered to keep few values live, the order in which a
    Cortex-M4F build spills least: the same operations on the same operands, so the same
    values (tests/test_codegen.py compares with CasADi to the bit). Every value gets its own
    name first (CasADi's work registers are reused, which would order every reader of a
    register before its next writer); a read of an input entry or a literal goes into its
    readers' text (the compiler loads it where it is used: no register held, no spill); then
    a list schedule takes, among the statements whose operands are ready, the one that ends
    the most values' lifetimes less the values it starts, the earliest in CasADi's order on a
    tie (measured on modular8, M4 -Os float: 8 % less text in the criteria and the steps,
    ~690 fewer instructions in the fault-tolerant tick; CasADi's order is depth-first, and a
    Sethi-Ullman order or other tie rules gave less). Locals are then shared again
    (:func:`_reused_registers`)."""
    value_of: dict[int, int] = {}  # work register -> its current value
    leaf: dict[int, str] = {}  # value -> the C text that stands for it
    nodes: list[tuple[list[str], tuple[int, ...], tuple[int, ...]]] = []  # (lines, writes, reads) by value
    fresh = 0
    for st in statements:
        reads = {r: value_of[r] for r in st.reads}
        writes = {}
        for w in st.writes:
            writes[w] = fresh
            fresh += 1
        match = _LEAF.fullmatch(st.lines[0]) if len(st.lines) == 1 and not st.reads and len(st.writes) == 1 else None
        if match and not match.group(2).startswith(("trig_", "call_")):
            leaf[writes[st.writes[0]]] = match.group(2)
        else:
            lines = []
            for line in st.lines:
                head = _DEFINITION.match(line)
                target = int(head.group(1)) if head else -1
                rest = line[head.end():] if head and target in writes else line
                rest = _REGISTER.sub(lambda m: (leaf.get(reads[int(m.group(1))]) or f"w{reads[int(m.group(1))]}")
                                     if int(m.group(1)) in reads else m.group(0), rest)
                lines.append(f"{line[:head.start(1) - 1]}w{writes[target]} = {rest}" if head and target in writes else rest)
            nodes.append((lines, tuple(writes.values()), tuple(sorted({v for v in reads.values() if v not in leaf}))))
        value_of.update(writes)
    producer = {v: k for k, node in enumerate(nodes) for v in node[1]}
    readers: dict[int, list[int]] = {}
    for k, (_, _, reads) in enumerate(nodes):
        for v in reads:
            readers.setdefault(v, []).append(k)
    uses_left = {v: len(ks) for v, ks in readers.items()}
    waiting = [sum(1 for v in node[2] if v in producer) for node in nodes]
    done = [False] * len(nodes)

    def score(k: int) -> int:
        return sum(1 for v in nodes[k][2] if uses_left[v] == 1) - len(nodes[k][1])

    ready = [(-score(k), k) for k, count in enumerate(waiting) if count == 0]
    heapq.heapify(ready)
    lines: list[str] = []
    while ready:
        negative, k = heapq.heappop(ready)
        if done[k] or -negative != score(k):
            continue  # a stale entry: scheduled already, or its score rose since
        done[k] = True
        lines += nodes[k][0]
        for v in nodes[k][2]:
            uses_left[v] -= 1
            if uses_left[v] == 1:  # the value's last reader now ends it: its score rose
                last = next(j for j in readers[v] if not done[j])
                if waiting[last] == 0:
                    heapq.heappush(ready, (-score(last), last))
        for v in nodes[k][1]:
            for j in readers.get(v, ()):
                waiting[j] -= 1
                if waiting[j] == 0:
                    heapq.heappush(ready, (-score(j), j))
    if not all(done):
        raise ArmgenError("internal: the statement schedule left statements out")
    return _reused_registers(lines)


def _assignment(select: _Statement, operand: int, zero: str) -> str:
    """A select's value on one side: a fused select's operand + 0, a lone one's x or 0."""
    out = select.writes[0]
    if len(select.reads) == 3:
        return f"w{out} = w{select.reads[operand]} + {zero};"
    return f"w{out} = w{select.reads[1]};" if operand == 1 else f"w{out} = {zero};"


def emit_body(func: ca.Function, arg_names: list[str], arg_scalar: list[bool], res_names: list[str],
              res_scalar: list[bool], macro_prefix: str, indent: str = "  ", trig_table: bool = False,
              branches: bool = False, zero_entries: frozenset = frozenset()) -> EmittedFunction:
    """The statements of ``func``'s SX algorithm as C; inputs/outputs by the given names.

    Outputs must be dense (see ``casadi.densify``); the nonzero index then equals the
    column-major element index. A scalar input is a value, a scalar output ``x`` is ``*x``.
    ``trig_table``: the sin and cos of every angle come first, from one call of the header's
    ``<p>_sincos_table`` (a loop a compiler may vectorise), and the body reads them.
    ``branches``: the selects become ``if``/``else`` blocks that compute what only one side
    reads (:func:`_branched`); ``func`` must write each work register once
    (``live_variables`` off). ``zero_entries``: (input, nonzero) pairs the caller guarantees
    to be zero where the body runs (a loop's stop entry), read as the constant.
    """
    if not func.is_a("SXFunction"):
        raise ArmgenError(f"function {func.name()} is not an SX function")
    for k in range(func.n_out()):
        if func.sparsity_out(k).nnz() != func.sparsity_out(k).numel():
            raise ArmgenError(f"output {func.name_out(k)} of {func.name()} is sparse; densify it before emitting")
    table, angles = _trig_table(func, arg_names, arg_scalar, macro_prefix) if trig_table else ({}, [])
    angle_input = _whole_input(func, arg_names, arg_scalar, angles)
    if angle_input is not None:  # the angles are an input vector, entry by entry: no copy
        entry = {f"{angle_input}[{i}]": i for i in range(len(angles))}
        table = {k: entry[angles[slot]] for k, slot in table.items()}
    translator = _Translator(func, arg_names, arg_scalar, res_names, res_scalar, macro_prefix, table, zero_entries)
    statements, counts, loops = translator.translate()
    if branches:
        ordered, used = _reused_registers(_branched(_fused_selects(_live(statements), macro_prefix), macro_prefix))
    else:
        ordered, used = _scheduled(_live(statements))
    lines = (_declarations(func, arg_names, used, angles, angle_input, macro_prefix)
             + _sincos_lines(angles, angle_input, branches, macro_prefix) + ordered)
    body = "\n".join(indent + line for line in lines)
    return EmittedFunction(func.name(), body, counts, len(used) + (2 if angle_input else 3) * len(angles), tuple(sorted(loops)))


def _sincos_lines(angles: list[str], angle_input: str | None, branches: bool, macro_prefix: str) -> list[str]:
    """The lines that fill the sin/cos table: the angles copied into ``trig_angle`` unless an
    input vector holds them, then the table call."""
    p = macro_prefix.lower()
    lines = [f"trig_angle[{slot}] = {angle};" for slot, angle in enumerate(angles)] if angle_input is None else []
    source = angle_input or "trig_angle"
    if angles and branches:  # a loop step: entry by entry, no loop (a loop over the angles cost
        # the IK ~100 instructions a step on the M4, 3 steps of its 1 ms budget)
        lines += [f"{p}_sincos_table(&{source}[{i}], &trig_sin[{i}], &trig_cos[{i}], 1);" for i in range(len(angles))]
    elif angles:
        lines.append(f"{p}_sincos_table({source}, trig_sin, trig_cos, {len(angles)});")
    return lines


def _declarations(func: ca.Function, arg_names: list[str], used: set[int], angles: list[str],
                  angle_input: str | None, macro_prefix: str) -> list[str]:
    """The body's locals (the sin/cos table, the work registers ``used``), then a ``(void)``
    for each input the body does not read."""
    p = macro_prefix.lower()
    read_args = {func.instruction_input(k)[0] for k in range(func.n_instructions())
                 if func.instruction_id(k) == ca.OP_INPUT}
    # an input the expression does not depend on (e.g. q of a constant criterion) is still
    # part of the fixed API; mark it used for -Wunused-parameter
    decl = [f"(void){arg_names[k]};" for k in range(func.n_in()) if k not in read_args]
    if used:
        names = [f"w{i}" for i in sorted(used)]
        for start in range(0, len(names), 12):
            decl.insert(0, f"{p}_real {', '.join(names[start:start + 12])};")
    if angles:
        decl.insert(0, f"{p}_real trig_sin[{len(angles)}], trig_cos[{len(angles)}];")
        if angle_input is None:
            decl.insert(0, f"{p}_real trig_angle[{len(angles)}];")
    return decl


@dataclass(frozen=True)
class _Translator:
    """One C statement per SX instruction of ``func`` (see :func:`emit_body` for the arguments;
    ``table``: {sin/cos instruction: its slot in the sin/cos table})."""

    func: ca.Function
    arg_names: list[str]
    arg_scalar: list[bool]
    res_names: list[str]
    res_scalar: list[bool]
    macro_prefix: str
    table: dict[int, int]
    zero_entries: frozenset

    def translate(self) -> tuple[list[_Statement], Counter, set[str]]:
        """(the statements in the algorithm's order, the op counts, the loop functions called)."""
        func = self.func
        counts: Counter = Counter()
        loops: set[str] = set()
        statements: list[_Statement] = []
        holds: dict[int, tuple[int, int]] = {}  # register -> (argument, entry) of the input it holds
        callees = iter(calls_in_order(func))
        for k in range(func.n_instructions()):
            op = func.instruction_id(k)
            ins = func.instruction_input(k)
            outs = func.instruction_output(k)
            if op == ca.OP_CALL:
                loop = _called_loop(func, next(callees))
                counts.update({category: n * loop.count for category, n in _step_counts(loop).items()})
                loops.add(loop.function.name())
                statements.append(self._call(loop, ins, outs, holds))
            else:
                category, statement = self._instruction(k, op, ins, outs)
                counts[category] += 1
                statements.append(statement)
                if op == ca.OP_INPUT and (ins[0], ins[1]) not in self.zero_entries:
                    holds[outs[0]] = (ins[0], ins[1])
            if op != ca.OP_INPUT:  # after the instruction: a call's results may reuse its arguments' registers
                for o in outs:
                    holds.pop(o, None)
        return statements, counts, loops

    def _instruction(self, k: int, op: int, ins: list[int], outs: list[int]) -> tuple[str, _Statement]:
        """(the op-count category, the statement) of one instruction other than a call."""
        prefix = self.macro_prefix
        if k in self.table:
            return "trig", _Statement([f"w{outs[0]} = trig_{'sin' if op == ca.OP_SIN else 'cos'}[{self.table[k]}];"],
                                      (outs[0],), ())
        if op == ca.OP_INPUT and (ins[0], ins[1]) in self.zero_entries:
            return "input", _Statement([f"w{outs[0]} = {c_literal(0.0, prefix)};"], (outs[0],), (), ca.OP_CONST, 0.0)
        if op == ca.OP_INPUT:
            return "input", _Statement([f"w{outs[0]} = {_input_text(self.arg_names, self.arg_scalar, ins)};"],
                                       (outs[0],), ())
        if op == ca.OP_OUTPUT:
            name = self.res_names[outs[0]]
            target = f"*{name}" if self.res_scalar[outs[0]] else f"{name}[{outs[1]}]"
            return "output", _Statement([f"{target} = w{ins[0]};"], (), (ins[0],))
        if op == ca.OP_CONST:
            value = self.func.instruction_constant(k)
            return "const", _Statement([f"w{outs[0]} = {c_literal(value, prefix)};"], (outs[0],), (), op, value)
        if op in _BINARY:
            category, template = _BINARY[op]
            expr = template.format(a=f"w{ins[0]}", b=f"w{ins[1]}", P=prefix, p=prefix.lower())
            return category, _Statement([f"w{outs[0]} = {expr};"], (outs[0],), (ins[0], ins[1]), op)
        if op in _UNARY:
            category, template = _UNARY[op]
            expr = template.format(a=f"w{ins[0]}", P=prefix, p=prefix.lower())
            return category, _Statement([f"w{outs[0]} = {expr};"], (outs[0],), (ins[0],), op)
        raise ArmgenError(f"function {self.func.name()}: CasADi operation {op} has no C translation in armgen")

    def _call(self, loop: Loop, ins: list[int], outs: list[int], holds: dict[int, tuple[int, int]]) -> _Statement:
        """A call of a loop function: an input whose registers hold a whole array argument of
        the caller is passed as that array, its registers not read."""
        func = self.func
        sizes = [loop.function.sparsity_in(j).nnz() for j in range(loop.function.n_in())]
        whole = _whole_arrays(list(ins), sizes, holds, self.arg_names, self.arg_scalar,
                              [func.sparsity_in(j).nnz() for j in range(func.n_in())])
        passed = {i for j, (start, size) in enumerate(zip(itertools.accumulate([0, *sizes]), sizes)) if j in whole
                  for i in ins[start:start + size]}
        return _Statement(_loop_call(loop, ins, outs, self.macro_prefix, whole), tuple(o for o in outs if o >= 0),
                          tuple(i for i in ins if i >= 0 and i not in passed))


# The operand positions whose NaN/inf makes the result NaN/inf whatever the other operand
# holds (IEEE 754: inf·0 = NaN, inf − inf = NaN, inf/inf = NaN; a denominator is not one,
# x/inf = 0; nor are fmin/fmax, comparisons and selects, which may drop a NaN).
_CARRIES = {ca.OP_ADD: (0, 1), ca.OP_SUB: (0, 1), ca.OP_MUL: (0, 1), ca.OP_DIV: (0,), ca.OP_NEG: (0,),
            ca.OP_SQ: (0,), ca.OP_TWICE: (0,), ca.OP_ASSIGN: (0,), ca.OP_SQRT: (0,), ca.OP_FABS: (0,),
            ca.OP_SIN: (0,), ca.OP_COS: (0,)}


def carried_entries(func: ca.Function) -> set[tuple[int, int]]:
    """The (input, nonzero) pairs with a path to an output through carrying operands only
    (:data:`_CARRIES`): a NaN or inf there makes that output non-finite, so a status that
    checks the outputs needs not scan them. Calls (fixed loops) carry nothing."""
    taint: dict[int, int] = {}  # work register -> bit set over the read entries
    bits: dict[tuple[int, int], int] = {}
    reached = 0
    for k in range(func.n_instructions()):
        op, ins, outs = func.instruction_id(k), func.instruction_input(k), func.instruction_output(k)
        if op == ca.OP_INPUT:
            taint[outs[0]] = 1 << bits.setdefault((ins[0], ins[1]), len(bits))
        elif op == ca.OP_OUTPUT:
            reached |= taint.get(ins[0], 0)
        elif op == ca.OP_CALL:
            for o in outs:
                taint[o] = 0
        else:
            carried = 0
            for position in _CARRIES.get(op, ()):
                carried |= taint.get(ins[position], 0)
            taint[outs[0]] = carried
    return {entry for entry, bit in bits.items() if (reached >> bit) & 1}


def read_entries(func: ca.Function, k: int) -> set[int]:
    """The nonzeros of input ``k`` that ``func``'s SX algorithm reads (a Jacobian entry that is
    constant for the robot is folded into the expression and never read)."""
    return {func.instruction_input(i)[1] for i in range(func.n_instructions())
            if func.instruction_id(i) == ca.OP_INPUT and func.instruction_input(i)[0] == k}


def _called_loop(func: ca.Function, callee: ca.Function) -> Loop:
    """The loop (armgen.symbolic.loops) a call instruction calls: the only calls armgen emits."""
    loop = find_loop(callee.name())
    if loop is None:
        raise ArmgenError(f"function {func.name()} calls {callee.name()}: armgen emits calls of its fixed "
                          "loops (armgen.symbolic.loops) only; call the *_from_jacobian twins inline")
    return loop


def _whole_arrays(ins: list[int], sizes: list[int], holds: dict[int, tuple[int, int]], arg_names: list[str],
                  arg_scalar: list[bool], arg_nnz: list[int]) -> dict[int, str]:
    """{call input: caller's argument} for each call input whose registers hold a whole
    array argument of the caller, entry by entry (``holds``: register -> (argument, entry) of
    the input read it still holds): the call takes that array as it is, with no copy."""
    whole, start = {}, 0
    for k, size in enumerate(sizes):
        first = holds.get(ins[start]) if ins[start] >= 0 else None
        if first is not None and not arg_scalar[first[0]] and arg_nnz[first[0]] == size and \
                all(i >= 0 and holds.get(i) == (first[0], j) for j, i in enumerate(ins[start:start + size])):
            whole[k] = arg_names[first[0]]
        start += size
    return whole


def _loop_call(loop: Loop, ins: list[int], outs: list[int], macro_prefix: str,
               whole: dict[int, str]) -> list[str]:
    """A block passing the call's work registers to the loop function and reading its result;
    an input that is a whole array of the caller (``whole``) is passed as that array (copying
    the IK's target and rest configuration cost ~200 B of flash and ~50 instructions a call)."""
    p = macro_prefix.lower()
    fn = loop.function
    lines, args, start = ["{"], [], 0
    for k in range(fn.n_in()):
        size = fn.sparsity_in(k).nnz()
        if k in whole:
            args.append(whole[k])
        else:
            lines.append(f"  {p}_real call_in{k}[{size}] = {{{', '.join(f'w{i}' for i in ins[start:start + size])}}};")
            args.append(f"call_in{k}")
        start += size
    lines.append(f"  {p}_real call_out[{len(outs)}];")
    lines.append(f"  {p}_{fn.name()}({', '.join(args)}, call_out);")
    lines += [f"  w{o} = call_out[{j}];" for j, o in enumerate(outs) if o >= 0]
    return lines + ["}"]


@lru_cache(maxsize=None)
def _step_counts(loop: Loop) -> dict[str, int]:
    """The arithmetic of one iteration (for the callers' op counts; emitted once per loop)."""
    counts = emit_loop_step(loop, "K").op_counts
    return {category: n for category, n in counts.items() if category not in ("input", "output", "const", "copy")}


def emit_loop_step(loop: Loop, macro_prefix: str) -> EmittedFunction:
    """The step's statements, its selects as branches (a loop step is where the work a select
    discards costs most): the same SX with one work register per instruction."""
    step = loop.step
    inputs = step.sx_in()
    single = ca.Function(step.name(), inputs, step.call(inputs), step.name_in(), step.name_out(),
                         {"live_variables": False})
    # the loop leaves before a step whose stop entry is nonzero: the body reads it as zero
    stop = frozenset() if loop.stop is None else frozenset({(0, loop.stop)})
    return emit_body(single, ["current", *step.name_in()[1:]], [False] * step.n_in(), ["next"], [False],
                     macro_prefix, indent="    ", trig_table=True, branches=True, zero_entries=stop)


def emit_loop(loop: Loop, macro_prefix: str) -> tuple[str, str]:
    """(header lines, definition) of the loop function: the step's statements once, in a for
    loop of <P>_<NAME>_COUNT iterations (the float build's count under <P>_USE_FLOAT), left
    early once the loop's ``stop`` entry is nonzero (the step is the identity from there).
    Both are blocks of lines without a last line break (templates/codegen/loop_*)."""
    p = macro_prefix.lower()
    fn, step = loop.function, loop.step
    size = step.sparsity_out(0).nnz()
    params = [render_template("codegen/input_array.c", p=p, name=fn.name_in(k), size=fn.sparsity_in(k).nnz())
              for k in range(fn.n_in())]
    signature = render_template("codegen/loop_signature.c", p=p, loop=fn.name(), parameters=", ".join(params), size=size)
    body = emit_loop_step(loop, macro_prefix)
    count = f"{macro_prefix}_{fn.name().upper()}_COUNT"
    stop = [] if loop.stop is None else [render_template("codegen/loop_stop.c", P=macro_prefix, stop=loop.stop)]
    iteration = [*stop, body.body, *(render_template("codegen/loop_next.c", i=i) for i in range(size))]
    definition = render_template("codegen/loop_function.c", p=p, loop=fn.name(), step=step.name(), count=count,
                                 ops=describe_counts(body.op_counts), signature=signature, size=size,
                                 first=fn.name_in(0), body="\n".join(iteration))
    if loop.fused_float:
        # GCC contracts a·b + c across statements only when told to (ISO C modes default to
        # -ffp-contract=off); the float build only, so the double C keeps Python's roundings
        definition = render_template("codegen/loop_fused.c", P=macro_prefix, definition=definition)
    prototype = render_template("codegen/loop_count.h", P=macro_prefix, count=count, float_count=loop.float_count,
                                double_count=loop.count, signature=signature)
    return prototype, definition


def describe_counts(counts: Counter) -> str:
    order = ("add", "mul", "div", "sqrt", "trig", "pow", "exp", "minmax", "compare", "select")
    parts = [f"{counts[k]} {k}" for k in order if counts.get(k)]
    return ", ".join(parts) if parts else "no arithmetic"
