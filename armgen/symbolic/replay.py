"""The NumPy replay of a CasADi SX function, over a whole batch at a time.

A batch is evaluated by replaying the SX function's instruction list once with NumPy arrays in
place of scalars: every instruction becomes one vectorised NumPy operation over the batch. The
expression graph is the one the C code is generated from, so the numbers are the same
operations in the same order; the cost per sample falls with the batch size (no Python loop
per sample and no compiler needed). :mod:`armgen.symbolic.numeric` and the IK
(:mod:`armgen.symbolic.ik`) evaluate their batches with it; it imports neither.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import casadi as ca
import numpy as np

from .loops import calls_in_order, find_loop


def _flag(test: Callable[[Any, Any], Any]) -> Callable[[Any, Any], Any]:
    return lambda x, y: test(x, y).astype(float)


# NumPy's arctan2 is its own SIMD code, off from the C library's atan2 by an ulp on ~8 % of
# inputs; the C library's (which CasADi and the generated C call), element by element, keeps
# the replay bit-identical (atan2 is rare: one per IK step).
_LIBM_ATAN2 = np.frompyfunc(math.atan2, 2, 1)


def _atan2(y: Any, x: Any) -> Any:
    return np.asarray(_LIBM_ATAN2(y, x), dtype=float)


_UNARY: dict[int, Callable[[Any], Any]] = {
    ca.OP_NEG: np.negative, ca.OP_SQRT: np.sqrt, ca.OP_SQ: np.square, ca.OP_TWICE: lambda x: x + x,
    ca.OP_SIN: np.sin, ca.OP_COS: np.cos, ca.OP_TAN: np.tan, ca.OP_ASIN: np.arcsin, ca.OP_ACOS: np.arccos,
    ca.OP_ATAN: np.arctan, ca.OP_SINH: np.sinh, ca.OP_COSH: np.cosh, ca.OP_TANH: np.tanh, ca.OP_EXP: np.exp,
    ca.OP_LOG: np.log, ca.OP_FABS: np.abs, ca.OP_SIGN: np.sign, ca.OP_FLOOR: np.floor, ca.OP_CEIL: np.ceil,
    ca.OP_INV: np.reciprocal, ca.OP_NOT: lambda x: np.equal(x, 0).astype(float), ca.OP_ASSIGN: lambda x: x,
}
_BINARY: dict[int, Callable[[Any, Any], Any]] = {
    ca.OP_ADD: np.add, ca.OP_SUB: np.subtract, ca.OP_MUL: np.multiply, ca.OP_DIV: np.divide,
    ca.OP_POW: np.power, ca.OP_CONSTPOW: np.power, ca.OP_FMIN: np.fmin, ca.OP_FMAX: np.fmax,
    ca.OP_ATAN2: _atan2, ca.OP_COPYSIGN: np.copysign, ca.OP_FMOD: np.fmod, ca.OP_HYPOT: np.hypot,
    ca.OP_LT: _flag(np.less), ca.OP_LE: _flag(np.less_equal), ca.OP_EQ: _flag(np.equal),
    ca.OP_NE: _flag(np.not_equal),
    ca.OP_AND: _flag(lambda x, y: np.logical_and(x != 0, y != 0)),
    ca.OP_OR: _flag(lambda x, y: np.logical_or(x != 0, y != 0)),
    ca.OP_IF_ELSE_ZERO: lambda c, x: np.where(np.not_equal(c, 0), x, 0.0),
}


# Samples replayed together: 4096 doubles (32 KiB) per temporary keep the working set in the
# cache and each allocation below malloc's mmap threshold (several times faster than one pass
# over a 100 000-sample batch), while the Python cost per instruction is spread over 4096.
BATCH_CHUNK = 4096


class BatchFunction:
    """A CasADi SX function evaluated over a batch by replaying its instructions in NumPy."""

    def __init__(self, function: ca.Function):
        self.function = function
        self._program: list[tuple[int, tuple[int, ...], tuple[int, ...], Any]] = []
        calls = iter(calls_in_order(function))
        for k in range(function.n_instructions()):
            op = function.instruction_id(k)
            if op not in _UNARY and op not in _BINARY and op not in (ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST,
                                                                     ca.OP_CALL):
                raise NotImplementedError(f"{function.name()}: CasADi operation {op} has no NumPy equivalent")
            extra = function.instruction_constant(k) if op == ca.OP_CONST else 0.0
            if op == ca.OP_CALL:
                extra = _Call(next(calls))
            self._program.append((op, tuple(function.instruction_input(k)), tuple(function.instruction_output(k)),
                                  extra))

    def __call__(self, inputs: list[np.ndarray], batch: int) -> list[np.ndarray]:
        """``inputs[k]`` has shape (nnz_k, batch), entries column-major; returns the outputs likewise.

        Entry-major layout: every input and output entry is a contiguous row over the batch.
        """
        f = self.function
        outputs = [np.empty((f.nnz_out(k), batch)) for k in range(f.n_out())]
        with np.errstate(all="ignore"):  # IEEE results (inf, nan) as CasADi and the C give, silently
            self._replay(inputs, outputs, batch)
        return outputs

    def _replay(self, inputs: list[np.ndarray], outputs: list[np.ndarray], batch: int) -> None:
        f = self.function
        for start in range(0, batch, BATCH_CHUNK):
            chunk = slice(start, min(start + BATCH_CHUNK, batch))
            work: list[Any] = [0.0] * f.sz_w()
            for op, args, res, constant in self._program:
                if op == ca.OP_INPUT:
                    work[res[0]] = inputs[args[0]][args[1], chunk]
                elif op == ca.OP_OUTPUT:
                    outputs[res[0]][res[1], chunk] = work[args[0]]
                elif op == ca.OP_CONST:
                    work[res[0]] = constant
                elif op == ca.OP_CALL:
                    constant(work, args, res, chunk.stop - chunk.start)
                elif op in _BINARY:
                    work[res[0]] = _BINARY[op](work[args[0]], work[args[1]])
                else:
                    work[res[0]] = _UNARY[op](work[args[0]])


class _Call:
    """A call instruction: the callee (an SX function, or a fixed loop of an SX step) replayed
    on the batch, its inputs gathered from and its outputs scattered to the work entries."""

    def __init__(self, callee: ca.Function):
        loop = find_loop(callee.name())
        self.callee = callee
        self.body = BatchFunction(loop.step if loop is not None else callee)
        self.count = loop.count if loop is not None else 1
        self.stop = loop.stop if loop is not None else None

    def __call__(self, work: list[Any], args: tuple[int, ...], res: tuple[int, ...], size: int) -> None:
        inputs, start = [], 0
        for k in range(self.callee.n_in()):
            nnz = self.callee.nnz_in(k)
            inputs.append(np.array([np.broadcast_to(work[i], (size,)) for i in args[start:start + nnz]]))
            start += nnz
        if self.count == 1:
            outputs = self.body(inputs, size)
        elif self.stop is None:  # a loop feeds its state (the first input) back
            for _ in range(self.count):
                inputs = [self.body(inputs, size)[0], *inputs[1:]]
            outputs = [inputs[0]]
        else:  # the finished samples are not stepped again: the remaining steps are the identity
            state, active = inputs[0], np.arange(size)
            for _ in range(self.count):
                active = active[state[self.stop, active] == 0]
                if active.size == 0:
                    break
                state[:, active] = self.body([x[:, active] for x in inputs], active.size)[0]
                inputs[0] = state
            outputs = [state]
        flat = np.concatenate(outputs) if len(outputs) > 1 else outputs[0]
        for j, target in enumerate(res):
            if target >= 0:
                work[target] = flat[j]
