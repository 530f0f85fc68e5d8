"""All itineraries of ``m`` symbols at once, in float64: a brute-force cross-check of the search.

The tree search of :func:`~warpratchet.orbits.enumerate_orbits` visits only the itineraries
with a non-empty cell; the brute force composes every word of the force's alphabet
(``(10 n)^m`` words for a force of ``n`` pieces, ``30^m`` for Eq. fx) and solves each for its
fixed point. It is a check a reader can run independently of the search's cells and exact
arithmetic (the prefilter of the brute-force test of the orbit search), and the yardstick of
its cost (``benchmarks/orbits.py``). Nothing here is exact: a fixed point in float64 is a
candidate, which exact arithmetic must confirm.

The alphabet is that of :mod:`~warpratchet.orbits._symbols`, built from the force's piece table:
word entries are symbol codes, and row ``c`` of :func:`symbol_table` is ``decode(c)``.

Pure: no Warp, no I/O.
"""

from __future__ import annotations

import itertools

import numpy as np

from ..params import MapParams
from ._symbols import alphabet, decode

__all__ = ["symbol_table", "all_words", "word_kicks", "compose", "fixed_points"]


def symbol_table(pieces: int) -> np.ndarray:
    """``(piece, k, j)`` of the symbol codes of a force of ``pieces`` pieces, shape ``(10 pieces, 3)``:
    row ``c`` is :func:`~warpratchet.orbits._symbols.decode` of the code ``c``."""
    codes = alphabet(pieces)
    table = np.zeros((max(codes) + 1, 3), dtype=np.int64)
    table[list(codes)] = [decode(code) for code in codes]
    return table


def all_words(params: MapParams, m: int) -> np.ndarray:
    """Every word of ``m`` symbol codes of the force of ``params``, shape ``((10 n)^m, m)``."""
    codes = alphabet(params.table.n_pieces)
    return np.array(list(itertools.product(codes, repeat=m)), dtype=np.int64).reshape(-1, m)


def word_kicks(params: MapParams) -> np.ndarray:
    """``(K a_s, K d_s)`` per piece ``s`` (``K f = K a_s x + K d_s``), rounded to float64, shape
    ``(n, 2)``: the force's exact kicks (:meth:`~warpratchet.force.Force.exact_kicks`)."""
    return np.array(params.table.exact_kicks(params.K), dtype=np.float64)


def compose(words: np.ndarray, kicks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``z -> A z + b`` of each word (applied left to right), shapes ``(w, 2, 2)`` and ``(w, 2)``.

    ``kicks`` has shape ``(n, 2)``: ``(K a_s, K d_s)`` per piece (:func:`word_kicks`, or any
    other evaluation of the same force); the words' codes belong to a force of ``n`` pieces.
    """
    table = symbol_table(len(kicks))
    n = len(words)
    A = np.broadcast_to(np.eye(2), (n, 2, 2)).copy()
    b = np.zeros((n, 2))
    for column in np.asarray(words).T:
        s, k, j = table[column].T
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
