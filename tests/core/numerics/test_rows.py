"""The growable stacks of the game's strategies against plain numpy stacks."""

from __future__ import annotations

import numpy as np
import pytest

from airl_cli.core.numerics.rows import Matrix, Rows


@pytest.mark.parametrize("seed", range(5))
def test_rows_through_appends_and_keeps_match_a_numpy_stack(seed):
    rng = np.random.default_rng(seed)
    rows, reference = Rows((3, 2)), np.empty((0, 3, 2))
    for _ in range(60):
        if len(reference) and rng.random() < 0.3:
            index = np.flatnonzero(rng.random(len(reference)) < rng.choice([0.2, 0.7, 1.0]))
            rows.keep(index)
            reference = reference[index]
        else:
            row = rng.random((3, 2))
            rows.append(row)
            reference = np.concatenate([reference, row[None]])
        np.testing.assert_array_equal(rows.view, reference)
        assert len(rows) == len(reference)


def test_keeping_every_row_or_a_prefix_moves_nothing():
    rows = Rows((2,))
    for i in range(5):
        rows.append(np.full(2, float(i)))
    buffer = rows._buffer
    rows.keep(np.arange(5))
    rows.keep(np.arange(3))
    assert rows._buffer is buffer
    np.testing.assert_array_equal(rows.view, [[0, 0], [1, 1], [2, 2]])
    rows.keep(np.array([], dtype=np.int64))
    assert rows.view.shape == (0, 2)


@pytest.mark.parametrize("seed", range(3))
def test_matrix_through_rows_columns_and_keeps_matches_numpy(seed):
    rng = np.random.default_rng(seed)
    matrix, reference = Matrix(), np.empty((0, 0))
    for _ in range(50):
        u = rng.random()
        if u < 0.4:
            row = rng.random(reference.shape[1])
            matrix.add_row(row)
            reference = np.vstack([reference, row[None]])
        elif u < 0.8:
            column = rng.random(reference.shape[0])
            matrix.add_column(column)
            reference = np.hstack([reference, column[:, None]])
        else:
            keep_r = np.flatnonzero(rng.random(reference.shape[0]) < 0.7)
            keep_c = np.flatnonzero(rng.random(reference.shape[1]) < 0.7)
            matrix.keep(keep_r, keep_c)
            reference = reference[np.ix_(keep_r, keep_c)]
        np.testing.assert_array_equal(matrix.view, reference)
