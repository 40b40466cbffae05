"""Member lists of splats as CSR arrays, and per-splat (segment) reductions over them.

A set of splats' covered sets ``P_j`` (Botsch 2004, sec. 3) is stored as
``(ptr, idx)``: splat ``j`` holds the sample rows ``idx[ptr[j]:ptr[j + 1]]``.
Sums over ``P_j`` are segment sums over that layout (``np.bincount`` with the
segment id of every member).
"""

from __future__ import annotations

import numpy as np


def csr_take(ptr: np.ndarray, idx: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The member lists of ``rows`` as their own CSR ``(ptr, idx)``."""
    rows = np.asarray(rows, dtype=np.int64)
    out_ptr = np.zeros(len(rows) + 1, dtype=np.int64)
    np.cumsum(ptr[rows + 1] - ptr[rows], out=out_ptr[1:])
    return out_ptr, idx[csr_positions(ptr, rows)]


def csr_positions(ptr: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Positions in the member array of the members of ``rows``, row after row."""
    counts = ptr[rows + 1] - ptr[rows]
    start = np.zeros(len(rows), dtype=np.int64)
    np.cumsum(counts[:-1], out=start[1:])
    return np.arange(int(counts.sum()), dtype=np.int64) + np.repeat(ptr[rows] - start, counts)


def concat_csr(ptrs, idxs):
    """Several member lists ``(ptr, idx)`` one after the other, as one CSR ``(ptr, idx)``."""
    sizes = np.concatenate([np.diff(p) for p in ptrs])
    ptr = np.zeros(len(sizes) + 1, dtype=np.int64)
    np.cumsum(sizes, out=ptr[1:])
    return ptr, np.concatenate(idxs)


def segments(ptr: np.ndarray) -> np.ndarray:
    """(M,) int64: the splat (segment) of every member of the CSR with offsets ``ptr``."""
    return np.repeat(np.arange(len(ptr) - 1, dtype=np.int64), np.diff(ptr))


def segment_sum(values: np.ndarray, seg: np.ndarray, count: int) -> np.ndarray:
    """Per-segment sums of (M,) or (M, c) values."""
    if values.ndim == 1:
        return np.bincount(seg, weights=values, minlength=count)
    return np.stack([np.bincount(seg, weights=values[:, c], minlength=count) for c in range(values.shape[1])],
                    axis=1)


def segment_outer(x: np.ndarray, seg: np.ndarray, count: int) -> np.ndarray:
    """(J, 3, 3) per-segment sums of ``x_i x_i^T``."""
    out = np.empty((count, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            out[:, i, j] = out[:, j, i] = np.bincount(seg, weights=x[:, i] * x[:, j], minlength=count)
    return out
