"""A stack of equal-shaped rows that grows in amortised constant time.

The solvers of the game add one strategy (one row of marginals, one row or column of a payoff
matrix) per iteration; ``numpy.vstack`` copies the whole stack each time, which at 500 strategies
of 20,480 numbers (a 32 x 32 grid, T = 20) made the copies a tenth of a fit. ``Rows`` doubles its
buffer instead and hands out views of the filled part.
"""

from __future__ import annotations

import numpy as np


class Rows:
    """Rows of shape ``row_shape`` and dtype ``dtype``; ``view`` is (n, *row_shape), the rows kept.

    ``view`` is a view of the buffer: it stays valid until the next ``append`` or ``keep``.
    """

    def __init__(self, row_shape: tuple[int, ...], dtype=np.float64):
        self._buffer = np.empty((4, *row_shape), dtype=dtype)
        self._n = 0

    def __len__(self) -> int:
        return self._n

    @property
    def view(self) -> np.ndarray:
        return self._buffer[: self._n]

    def append(self, row: np.ndarray) -> None:
        """Add one row (converted to the dtype), doubling the buffer when it is full."""
        if self._n == len(self._buffer):
            grown = np.empty((2 * len(self._buffer), *self._buffer.shape[1:]), dtype=self._buffer.dtype)
            grown[: self._n] = self._buffer[: self._n]
            self._buffer = grown
        self._buffer[self._n] = row
        self._n += 1

    def keep(self, index: np.ndarray) -> None:
        """Keep only the rows ``index`` (sorted, unique), in that order.

        Only the rows that move are copied, one by one in place (row i takes row index[i] >= i,
        which no earlier step has overwritten): keeping every row copies nothing, where a gather
        copied the whole stack twice (360 MB of adversary marginals on a 64 x 64 grid, each prune).
        """
        index = np.asarray(index, dtype=np.int64)
        for i in np.flatnonzero(index != np.arange(index.size)):
            self._buffer[i] = self._buffer[index[i]]
        self._n = index.size


class Matrix:
    """An (n, m) matrix grown by whole rows and whole columns, in amortised constant time each."""

    def __init__(self):
        self._buffer = np.empty((4, 4))
        self.n = self.m = 0

    @property
    def view(self) -> np.ndarray:
        return self._buffer[: self.n, : self.m]

    def _reserve(self, n: int, m: int) -> None:
        rows, cols = self._buffer.shape
        if n <= rows and m <= cols:
            return
        grown = np.empty((max(rows, 2 * n if n > rows else rows), max(cols, 2 * m if m > cols else cols)))
        grown[: self.n, : self.m] = self.view
        self._buffer = grown

    def add_row(self, row: np.ndarray) -> None:
        """Append a row (m,)."""
        self._reserve(self.n + 1, self.m)
        self._buffer[self.n, : self.m] = row
        self.n += 1

    def add_column(self, column: np.ndarray) -> None:
        """Append a column (n,)."""
        self._reserve(self.n, self.m + 1)
        self._buffer[: self.n, self.m] = column
        self.m += 1

    def keep(self, rows: np.ndarray, columns: np.ndarray) -> None:
        """Keep only these rows and columns (sorted, unique index arrays)."""
        kept = self.view[np.ix_(np.asarray(rows, dtype=np.int64), np.asarray(columns, dtype=np.int64))]
        self.n, self.m = kept.shape
        self._buffer[: self.n, : self.m] = kept
