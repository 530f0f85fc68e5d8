"""All ``30^m`` itineraries at once, in float64: the brute force the tree search replaces.

For cost comparisons (``benchmarks/orbits.py``) and as the prefilter of the brute-force check in
``tests/analyses/test_orbits.py``; nothing here is exact, and :func:`~warpratchet.orbits.enumerate_orbits`
does not use it. Pure: no Warp, no I/O.
"""

from __future__ import annotations

import itertools

import numpy as np

__all__ = ["SYMBOLS", "all_words", "compose", "fixed_points"]

#: ``(piece, k, j)`` of each symbol code, shape ``(30, 3)`` (:mod:`~warpratchet.orbits.symbols`).
SYMBOLS = np.array(list(itertools.product(range(3), range(-2, 3), range(2))))


def all_words(m: int) -> np.ndarray:
    """Every word of ``m`` symbol codes, shape ``(30^m, m)``."""
    return np.array(list(itertools.product(range(len(SYMBOLS)), repeat=m)))


def compose(words: np.ndarray, kicks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``z -> A z + b`` of each word (applied left to right), shapes ``(n, 2, 2)`` and ``(n, 2)``.

    ``kicks`` has shape ``(3, 2)``: ``(K a_s, K d_s)`` per piece, ``K f = K a_s x + K d_s``.
    """
    n = len(words)
    A = np.broadcast_to(np.eye(2), (n, 2, 2)).copy()
    b = np.zeros((n, 2))
    for column in words.T:
        s, k, j = SYMBOLS[column].T
        ka, kd = kicks[s, 0], kicks[s, 1]
        S = np.stack([np.stack([1 + ka, np.ones(n)], -1), np.stack([ka, np.ones(n)], -1)], -2)
        A = S @ A
        b = np.einsum("nij,nj->ni", S, b) + np.stack([kd - k - j, kd - k], -1)
    return A, b


def fixed_points(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(x, q, det)``: the solutions of ``(A - I) z = -b`` (nan/inf where ``det(A - I) = 0``)."""
    M = A - np.eye(2)
    det = M[:, 0, 0] * M[:, 1, 1] - M[:, 0, 1] * M[:, 1, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        x = -(M[:, 1, 1] * b[:, 0] - M[:, 0, 1] * b[:, 1]) / det
        q = -(-M[:, 1, 0] * b[:, 0] + M[:, 0, 0] * b[:, 1]) / det
    return x, q, det
