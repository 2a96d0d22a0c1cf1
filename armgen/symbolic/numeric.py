"""NumPy evaluation of the symbolic model, one sample or a whole batch at a time.

A batch goes through the NumPy replay of the model's SX functions (:mod:`armgen.symbolic.replay`):
the same operations in the same order as the generated C. A single sample is passed to CasADi
directly, which is faster than the replay when there is nothing to vectorise.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .model import SymbolicModel
from .replay import BatchFunction


def _shaped(value: np.ndarray, batch_shape: tuple[int, ...], rows: int, cols: int) -> np.ndarray:
    """(rows*cols, batch) column-major → batch_shape + (rows, cols), (rows,) for a column, () for a scalar."""
    matrix = value.reshape(cols, rows, -1).transpose(2, 1, 0)
    if rows == 1 and cols == 1:
        return matrix.reshape(batch_shape)
    if cols == 1:
        return matrix.reshape(batch_shape + (rows,))
    return matrix.reshape(batch_shape + (rows, cols))


def _squeezed(matrix: np.ndarray) -> np.ndarray:
    """A single sample's output: (rows, cols), (rows,) for a column, () for a scalar."""
    rows, cols = matrix.shape
    if cols == 1:
        return matrix.reshape(()) if rows == 1 else matrix.reshape(rows)
    return matrix


class NumericModel:
    """NumPy access to a symbolic model's functions with leading batch axes (the replays built
    on first use and kept)."""

    def __init__(self, model: SymbolicModel):
        self.model = model
        self.robot = model.robot
        self._batch: dict[str, BatchFunction] = {}

    def evaluate(self, name: str, q: ArrayLike, **parameters: ArrayLike) -> dict[str, np.ndarray]:
        """Evaluate function ``name`` at ``q`` of shape ``(n,)`` or ``(..., n)``.

        The other inputs are given by name; each is broadcast against the batch (a vector
        input may also carry the batch axes). Returns the outputs by name, with the batch
        axes in front of each output's own shape.
        """
        f = self.model.function(name)
        q = np.asarray(q, dtype=float)
        n = self.robot.n
        if q.ndim == 0 or q.shape[-1] != n:
            raise ValueError(f"q must have shape ({n},) or (..., {n}) for robot '{self.robot.name}', got {q.shape}")
        names_in = f.name_in()
        if set(parameters) != set(names_in[1:]):
            raise TypeError(f"{name}: inputs {names_in[1:]} expected, got {sorted(parameters)}")
        if q.ndim == 1:
            raw = f.call([q] + [np.asarray(parameters[k], dtype=float) for k in names_in[1:]])
            return {f.name_out(k): _squeezed(raw[k].full()) for k in range(f.n_out())}
        batch_shape = q.shape[:-1]
        size = int(np.prod(batch_shape, dtype=int))
        inputs = [q.reshape(size, n).T]
        for k, input_name in enumerate(names_in[1:], start=1):
            own = (f.nnz_in(k),) if f.nnz_in(k) > 1 else ()
            value = np.broadcast_to(np.asarray(parameters[input_name], dtype=float), batch_shape + own)
            inputs.append(value.reshape(size, f.nnz_in(k)).T)
        if name not in self._batch:
            self._batch[name] = BatchFunction(f)
        values = self._batch[name]([np.ascontiguousarray(x) for x in inputs], size)
        return {f.name_out(k): _shaped(values[k], batch_shape, *f.size_out(k)) for k in range(f.n_out())}
