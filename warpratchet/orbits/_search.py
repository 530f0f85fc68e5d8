"""Tree search for the itineraries of length ``m`` that some point of the torus follows.

Depth-first over symbols (:mod:`~warpratchet.orbits._symbols`): a node is a prefix of ``i``
symbols with its composite ``z0 -> z_i`` (:class:`~warpratchet.orbits._exact.Composite`) and its
exact cell (:mod:`~warpratchet.orbits._cells`). A child cuts the cell by the half-planes of the
next symbol pulled back to ``z0``; an empty cell prunes the whole subtree. The number of
admissible itineraries grows like ``e^(h m)`` (about ``3.3^m`` at K = 3, b1 = 0.1, b2 = 0.01),
far below the ``30^m`` words of a brute-force enumeration. Everything is exact, so the leaves
are exactly the necklace itineraries whose (closed) cells are not empty.

Each cycle is wanted once, as the least rotation of its itinerary (symbol order): prefixes
that cannot start one are pruned with the FKM algorithm (Fredricksen, Kessler and Maiorana,
as in Ruskey's "Combinatorial Generation"): ``root`` is the length of the longest Lyndon
prefix, a symbol below ``word[i - root]`` ends the branch, and a complete word is a necklace
iff ``root`` divides ``m``, a primitive one (Lyndon word) iff ``root = m``.

Pure: no Warp, no I/O.
"""

from __future__ import annotations

from collections.abc import Callable

from ._cells import Cell, advance, clip, unit_square
from ._exact import Composite, ExactMap
from ._symbols import K_RANGE, j_constraint, k_constraints, piece_constraints

__all__ = ["search"]

#: ``on_leaf(word, root, cell, composite)``
LeafHandler = Callable[[tuple[int, ...], int, Cell, Composite], None]


def search(em: ExactMap, period: int, on_leaf: LeafHandler) -> int:
    """Call ``on_leaf`` for every necklace itinerary of length ``period`` with a non-empty cell.

    Returns the number of tree nodes visited (the cost).
    """
    edges = [edge for edge, _ in em.edges]
    pieces = [(s, em.L[s], em.ka_L[s], em.kd_L[s], piece_constraints(s, edges)) for s in range(em.pieces)]
    word: list[int] = []
    nodes = 0

    def cut(cell, comp, constraints):
        for constraint in constraints:
            cell = clip(cell, constraint, comp)
            if cell is None:
                return None
        return cell

    def visit(cell: Cell, comp: Composite, root: int) -> None:
        nonlocal nodes
        nodes += 1
        depth = len(word)
        if depth == period:
            if period % root == 0:
                on_leaf(tuple(word), root, cell, comp)
            return
        # FKM: no symbol below word[depth - root]; skip what could only make such symbols.
        least = word[depth - root] if depth else 0
        for s, L, ka, kd, piece_halfplanes in pieces:
            if 10 * s + 9 < least:
                continue
            P = cut(cell, comp, piece_halfplanes)
            if P is None:
                continue
            # t = q_i + K f at the vertices, as L sw t = ka xv + L qv + kd sw: it gives the
            # k's (floor t) and the sides of the k and j half-planes without another product.
            ts, units = _t_values(P, ka, kd, L)
            ks = [t // unit for t, unit in zip(ts, units, strict=True)]
            uniform = min(ks) == max(ks)  # every vertex has floor(t) = k: no k half-plane cuts
            for k in range(max(min(ks), K_RANGE[0]), min(max(ks), K_RANGE[-1]) + 1):
                if 10 * s + 2 * (k + 2) + 1 < least:
                    continue
                Pk, tk, uk = P, ts, units
                if not uniform:
                    Pk = cut(P, comp, k_constraints(ka, kd, k, L))
                    if Pk is None:
                        continue
                    tk, uk = _t_values(Pk, ka, kd, L)
                # x_i + q' - 1 = x_i + t - k - 1, times L sw
                sides = [L * v[3] + t - (k + 1) * u for v, t, u in zip(Pk[0], tk, uk, strict=True)]
                low, high = min(sides), max(sides)
                for j in (0, 1):
                    symbol = 10 * s + 2 * (k + 2) + j
                    if symbol < least:  # FKM: only prefixes of least rotations
                        continue
                    if depth:
                        new_root = root if symbol == least else depth + 1
                    else:
                        new_root = 1
                    # j = 0 keeps sides <= 0, j = 1 keeps sides >= 0 (closures)
                    if (high <= 0) if j == 0 else (low >= 0):
                        Pj = Pk
                    elif (low > 0) if j == 0 else (high < 0):
                        continue
                    else:
                        signed = [-v for v in sides] if j == 0 else sides
                        Pj = clip(Pk, j_constraint(ka, kd, k, j, L), comp, signed)
                        if Pj is None:
                            continue
                    word.append(symbol)
                    visit(advance(em, Pj, symbol), em.extend(comp, symbol), new_root)
                    word.pop()

    visit(unit_square(), em.identity(), 1)
    return nodes


def _t_values(cell: Cell, ka: int, kd: int, L: int) -> tuple[list[int], list[int]]:
    """``L sw t`` and ``L sw`` at each vertex, ``t = q_i + K f`` on the piece ``(ka, kd)``."""
    ts, units = [], []
    for _, _, _, xv, qv, sw in cell[0]:
        ts.append(ka * xv + L * qv + kd * sw)
        units.append(L * sw)
    return ts, units
