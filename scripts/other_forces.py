"""The worked example of docs/other_forces.md: a four-piece force whose sum rule is carried by a
chain of period-2 accelerator islands.

The force (knots 0, 0.25, 0.75, 0.95; values -0.2, 0.3, 0, -0.66; zero mean) at K = 3 has no
stable orbit of period 1 (its four are hyperbolic), an elliptic period-2 orbit with w = 1
(nu = 1/2) and one of period 4 with w = 1 (nu = 1/4), each inside an island chain.
This script prints, as JSON with ``--json``:

* the exact elliptic periodic orbits of periods 1, 2 and 4 with w != 0 and their residues
  (:func:`warpratchet.orbits.enumerate_orbits`);
* the island census and Eq. (sum) (:func:`warpratchet.sumrule.census`): the areas, A_sumrule,
  A_direct and A_force with their standard errors, and the share of each island class in
  ``sum_j S_j nu_j``;

and draws ``docs/img/other_forces.png``: the force, and the census classes of a lattice on the
torus with the exact elliptic orbits of w != 0 on top.

Usage::

    python scripts/other_forces.py            # 2e5 points x 13824 steps, a 240^2 lattice (~1-2 min)
    python scripts/other_forces.py --quick    # 2e4 points, a 100^2 lattice
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from _options import options

from warpratchet import MapParams
from warpratchet.force import Force
from warpratchet.orbits import enumerate_orbits
from warpratchet.sumrule import census, classify, lattice

KNOTS = ["0", "0.25", "0.75", "0.95"]
VALUES = ["-0.2", "0.3", "0", "-0.66"]
K = 3.0
FIGURE = Path(__file__).resolve().parent.parent / "docs" / "img" / "other_forces.png"


def _orbits(params: MapParams) -> list[dict]:
    out = []
    for period in (1, 2, 4):
        for orbit in enumerate_orbits(params, period).orbits:
            if orbit.winding != 0 and orbit.kind == "elliptic":
                out.append(
                    {
                        "period": period,
                        "winding": orbit.winding,
                        "kind": orbit.kind,
                        "residue": orbit.residue,
                        "x": orbit.x.tolist(),
                        "p": orbit.p.tolist(),
                    }
                )
    return out


def _figure(params: MapParams, side: int, steps: int, orbits: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    x0, p0 = lattice(side)
    pc = classify(params, x0, p0, steps)
    nu = np.where(pc.island, pc.w / np.maximum(pc.m, 1), np.nan)
    fig, (left, right) = plt.subplots(1, 2, figsize=(8.0, 3.6), gridspec_kw={"width_ratios": [1, 1.25]})
    x = np.linspace(0.0, 1.0, 1001)[:-1]
    left.plot(x, params.force(x), color="k", lw=1.2)
    left.plot(
        [float(k) for k in params.table.knots], [float(v) for v in params.table.values], "o", color="k", ms=3
    )
    left.axhline(0.0, color="0.7", lw=0.6)
    left.set(xlabel="x", ylabel="f(x)", title="the force (4 pieces, mean 0)", xlim=(0, 1))
    # class codes on the lattice (row-major in p: node (i, j) is element j * side + i)
    code = np.zeros(x0.shape, dtype=int)  # 0: regular, w = 0
    code[pc.in_C] = 1
    code[np.isclose(nu, 0.25)] = 2
    code[np.isclose(nu, 0.5)] = 3
    cmap = ListedColormap(["0.92", "0.6", "tab:blue", "tab:red"])
    right.imshow(
        code.reshape(side, side),
        origin="lower",
        extent=(0, 1, 0, 1),
        cmap=cmap,
        vmin=0,
        vmax=3,
        interpolation="nearest",
    )
    for orbit in orbits:
        if orbit["kind"] == "elliptic":
            right.plot(orbit["x"], orbit["p"], "+", color="k", ms=7, mew=0.8)
    right.set(xlabel="x", ylabel="p (mod 1)", xlim=(0, 1), ylim=(0, 1), aspect="equal")
    right.set_title(
        "C (grey), nu = 1/2 (red), nu = 1/4 (blue), regular w = 0 (light);\n"
        "+: exact elliptic orbits with w = 1",
        fontsize=8,
    )
    fig.tight_layout()
    fig.savefig(FIGURE, dpi=90)
    plt.close(fig)


SIZES = {
    "--points": ("census points", 200_000, 20_000),
    "--steps": ("iterations per point", 13_824, 13_824),
    "--side": ("lattice side of the figure", 240, 100),
}


def main(argv: list[str] | None = None) -> int:
    _, args = options(__doc__, argv, quick="2e4 points and a 100^2 lattice", seed=0, sizes=SIZES)
    params = MapParams(K, table=Force.from_knots(KNOTS, VALUES))
    orbits = _orbits(params)
    result = census(params, args.steps, points=args.points, seed=args.seed)
    total = sum(item.area * item.nu for item in result.islands)
    classes = [
        {
            "nu": item.nu,
            "w": item.w,
            "m": item.m,
            "area": item.area,
            "area_stderr": item.area_stderr,
            "share_of_sum": item.area * item.nu / total if total else None,
        }
        for item in result.islands
    ]
    out = {
        "K": K,
        "knots": ",".join(KNOTS),
        "values": ",".join(VALUES),
        "points": result.points,
        "steps": result.steps,
        "S_C": result.S_C,
        "S_C_stderr": result.S_C_stderr,
        "classes": classes,
        "unidentified_area": result.unidentified_area,
        "A_sumrule": result.A_sumrule,
        "A_sumrule_stderr": result.A_sumrule_stderr,
        "A_direct": result.A_direct,
        "A_direct_stderr": result.A_direct_stderr,
        "A_force": result.A_force,
        "A_force_stderr": result.A_force_stderr,
        "orbits": orbits,
    }
    _figure(params, args.side, args.steps, orbits)
    if args.json:
        json.dump(out, sys.stdout)
        print()
    else:
        print(f"K = {K}, knots = {out['knots']}, values = {out['values']}: {result.points} points")
        print(f"  x {result.steps} steps")
        for orbit in orbits:
            print(
                f"  elliptic orbit of period {orbit['period']}, w = {orbit['winding']:+d}: "
                f"R = {orbit['residue']:.6g}"
            )
        print(f"  S_C = {result.S_C:.6f} +- {result.S_C_stderr:.2g}")
        for item in classes:
            print(
                f"  nu = {item['nu']:+.4f} (w {item['w']}, m {item['m']}): area {item['area']:.6f} "
                f"+- {item['area_stderr']:.2g}, share of the sum {item['share_of_sum']:.3f}"
            )
        print(f"  A_sumrule = {result.A_sumrule:.6g} +- {result.A_sumrule_stderr:.2g}")
        print(f"  A_direct  = {result.A_direct:.6g} +- {result.A_direct_stderr:.2g}")
        print(f"  A_force   = {result.A_force:.6g} +- {result.A_force_stderr:.2g}")
        print(f"  figure: {FIGURE}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
