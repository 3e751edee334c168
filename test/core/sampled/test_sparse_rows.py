"""SparseRows: the row builder shared by the limited planner's primal LPs and their duals."""

from __future__ import annotations

import numpy as np

from flexmotion_ros.core.sampled.sparse_rows import NO_META, SparseRows


def test_rows_blocks_entries_metadata_and_offsets():
    rows = SparseRows()
    rows.add([0, 2], [1.0, -2.0], 3.0, meta=(1, 4, 0, -1), s=0.25)
    rows.add_many(
        np.array([[1, 2], [0, 1]]),
        np.array([[5.0, 6.0], [7.0, 8.0]]),
        [9.0, 10.0],
        meta=(2, [5, 6], 1, 1),
        s=[0.5, 0.75],
    )
    rows.add_many(np.array([[3]]), np.array([[4.0]]))  # rhs 0, no metadata
    rows.entry(0, 3, 11.0)  # one more term in the first row
    rows.entry(0, 0, 1.0)  # a repeated entry adds up
    A, b = rows.system(4)
    np.testing.assert_array_equal(
        A.toarray(),
        [[2.0, 0.0, -2.0, 11.0], [0.0, 5.0, 6.0, 0.0], [7.0, 8.0, 0.0, 0.0], [0.0, 0.0, 0.0, 4.0]],
    )
    np.testing.assert_array_equal(b, [3.0, 9.0, 10.0, 0.0])
    np.testing.assert_array_equal(rows.meta_array(), [[1, 4, 0, -1], [2, 5, 1, 1], [2, 6, 1, 1], NO_META])
    np.testing.assert_array_equal(rows.s_array(), [0.25, 0.5, 0.75, 0.0])


def test_no_rows():
    rows = SparseRows()
    rows.add_many(np.zeros((0, 2), int), np.zeros((0, 2)))
    assert rows.n == 0 and rows.system(3) == (None, None)
    assert rows.matrix(3).shape == (0, 3) and rows.meta_array().shape == (0, 4)
