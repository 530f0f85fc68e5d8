"""``python -m viz transport``: return-time and flight distributions, and orbits on the torus.

Two figures built on the public API:

* ``python -m viz transport run.json -o transport.png`` (or an archive ``run.h5`` of a
  ``--transport`` run): the distributions ``P(L)`` of return times to B and of flights (each
  sign), per unit length, on log-log axes, from the log2-binned counts; the runs still open at
  the end as hollow markers; the fitted power-law tails ``L^-alpha`` over their fit ranges.
* ``python -m viz transport --orbits --K 3 --b1 0.1 --b2 0.01 --period 1,2,3 -o orbits.png``:
  the periodic orbits of :mod:`warpratchet.orbits` on the torus, marked by kind (elliptic,
  hyperbolic, parabolic), the families as filled polygons (segments as lines), over the orbits of
  an ensemble started in the strip B (the global chaotic region, as in Figs. 1, 2, 4).

matplotlib is an optional dependency (extra ``figures``).
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from warpratchet.params import MapParams

from .command import command_name, run

__all__ = ["distributions", "portrait", "main"]

KIND_STYLE = {
    "elliptic": {"marker": "o", "color": "tab:green"},
    "hyperbolic": {"marker": "x", "color": "tab:red"},
    "parabolic": {"marker": "s", "color": "tab:purple"},
}


def _load_report(path: Path) -> tuple[dict[str, Any], str]:
    """The ``transport`` object and a title, from ``run --json`` output or a transport archive."""
    if path.suffix in (".h5", ".hdf5"):
        from warpratchet import open_archive

        with open_archive(path) as arc:
            ensemble = arc.ensemble()
            if not callable(getattr(ensemble, "report", None)):
                raise ValueError(f"{path} is not an archive of a --transport run (features: {arc.features})")
            p = arc.params
            return (
                ensemble.report(),
                f"K = {p.K}, b1 = {p.b1}, b2 = {p.b2}, {arc.points} points, n = {ensemble.step}",
            )
    report = json.loads(path.read_text())
    if "transport" not in report:
        raise ValueError(f'{path} holds no "transport" object (warpratchet run --transport --json)')
    title = f"K = {report['K']}, b1 = {report['b1']}, b2 = {report['b2']}, {report['points']} points"
    return report["transport"], f"{title}, n = {report['steps']}"


def _density(edges: list[int], counts: list[int], total: int) -> tuple[np.ndarray, np.ndarray]:
    """Geometric bin centres and ``P(L)``: count / (total * integer lengths in the bin)."""
    e = np.asarray(edges, dtype=np.float64)
    c = np.asarray(counts, dtype=np.float64)
    centre = np.sqrt(e[:-1] * (e[1:] - 1.0))
    return centre, c / (max(total, 1) * (e[1:] - e[:-1]))


def _fitted(ax, fit: dict, total: int, color: str) -> None:
    """The fitted power law over its range: each bin's expected ``P(L)`` (the counts it predicts,
    per unit length), on the same abscissae as the data."""
    if fit.get("reason") or fit.get("alpha") is None:
        return
    from warpratchet.transport import bin_masses, edges

    alpha, first, last = fit["alpha"], fit["first_bin"], fit["last_bin"]
    masses = bin_masses(alpha, first, last)
    expected = fit["counts"] * masses / masses.sum()
    x, y = _density(edges(last + 1)[first:], expected.tolist(), total)
    label = rf"fit $L^{{-\alpha}}$, $\alpha = {alpha:.2f} \pm {fit['stderr']:.2f}$ (p = {fit['p_value']:.2g})"
    if not fit.get("power_law", True):
        label += ": not a power law"
    ax.loglog(x, y, color=color, lw=1.2, ls="--", label=label)


def distributions(plt, report: dict[str, Any], title: str):
    """The figure of :func:`main`'s first form (returns the matplotlib figure)."""
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.4))
    rt, fl, tails = report["return_times"], report["flights"], report["tail_exponents"]
    panels = (
        (
            axes[0],
            "return times to B",
            [("gaps", rt["counts"], rt.get("open"), tails["return_times"], "tab:blue")],
        ),
        (
            axes[1],
            "flights",
            [
                ("gain > 0", fl["counts_plus"], fl.get("open_plus"), tails["flights_plus"], "tab:orange"),
                ("gain < 0", fl["counts_minus"], fl.get("open_minus"), tails["flights_minus"], "tab:purple"),
            ],
        ),
    )
    for ax, name, series in panels:
        for label, counts, still_open, fit, color in series:
            total = int(np.sum(counts))
            x, y = _density(rt["edges"], counts, total)
            shown = y > 0
            ax.loglog(x[shown], y[shown], "o-", color=color, ms=4, lw=0.8, label=f"{label} ({total} runs)")
            if still_open is not None and np.any(still_open):
                xo, yo = _density(rt["edges"], still_open, total)
                ax.loglog(
                    xo[yo > 0], yo[yo > 0], "o", mfc="none", color=color, ms=5, label="still open at the end"
                )
            _fitted(ax, fit, total, color)
        _powers_of_two(ax)
        ax.set_xlabel("length L (steps)")
        ax.set_ylabel("P(L) per unit length")
        ax.set_title(name, fontsize=10)
        ax.legend(fontsize=7)
    fig.suptitle(f"{title}; diffusion exponent {mu_label(report)}", fontsize=9)
    fig.tight_layout()
    return fig


def _powers_of_two(ax) -> None:
    """Length ticks at the log2 bins' edges, written as plain numbers (1, 2, 4, ...): matplotlib's
    log axis would label a range under a decade with minor ticks such as ``2 x 10^0``."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter, NullLocator

    lo, hi = ax.get_xlim()
    powers = [2.0**k for k in range(0, 64) if lo <= 2.0**k <= hi]
    step = max(1, math.ceil(len(powers) / 8))  # at most ~8 labels
    ax.xaxis.set_major_locator(FixedLocator(powers[::step]))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:.0f}"))
    ax.xaxis.set_minor_locator(NullLocator())
    ax.xaxis.set_minor_formatter(NullFormatter())


def mu_label(report: dict) -> str:
    """``mu = value +- error`` of a ``"transport"`` report, with the first sentence of the fit's
    reason when it flags the value (a flagged mu is never shown bare)."""
    mu = report.get("mu")
    reason = (report.get("mu_fit") or {}).get("reason")
    if mu is None or math.isnan(mu):
        return f"mu = n/a ({reason})" if reason else "mu = n/a"
    text = f"mu = {mu:.3f} +- {report.get('mu_stderr') or float('nan'):.3f}"
    return f"{text} ({reason.split('. ')[0].rstrip('.')})" if reason else text


def _background(params: MapParams, points: int, steps: int, pixels: int) -> np.ndarray:
    """Visited pixels of ``points`` orbits started in B (the global chaotic region)."""
    from warpratchet import Ensemble

    ens = Ensemble.sample(params, points, "strip", seed=0)
    image = np.zeros((pixels, pixels), dtype=bool)
    for _ in range(steps):
        ens.run(1, chunk_steps=1)
        ix = np.minimum((ens.array("x") * pixels).astype(int), pixels - 1)
        iy = np.minimum((ens.array("q") * pixels).astype(int), pixels - 1)
        image[iy, ix] = True
    return image


def portrait(plt, params: MapParams, periods: Sequence[int], background: int = 2000):
    """The figure of :func:`main`'s ``--orbits`` form (returns the matplotlib figure)."""
    from matplotlib.patches import Polygon, Rectangle

    from warpratchet.orbits import enumerate_orbits

    fig, ax = plt.subplots(figsize=(6.0, 7.4))
    steps = 300
    if background:
        image = _background(params, background, steps, 400)
        ax.imshow(
            image, origin="lower", extent=(0, 1, 0, 1), cmap="Greys", vmin=0, vmax=3, interpolation="nearest"
        )
        # The grey pixels in the legend: what they are, not only that they are there.
        sea = f"grey: the chaotic sea ({background} orbits from B, {steps} steps)"
        ax.add_patch(Rectangle((0, 0), 0, 0, fc=plt.get_cmap("Greys")(1 / 3), lw=0, label=sea))
    seen = set()
    for period in periods:
        result = enumerate_orbits(params, period)
        for family in result.families:
            v = family.vertices
            if family.shape == "polygon":
                label = None if "polygon" in seen else "cyan areas: periodic points with DM^m = I"
                ax.add_patch(
                    Polygon(v, closed=True, fc="tab:cyan", ec="tab:blue", alpha=0.5, lw=0.5, label=label)
                )
            else:
                label = (
                    None
                    if "segment" in seen
                    else "blue segments: lines of periodic points, DM^m a shear (trace 2, not I)"
                )
                ax.plot(v[:, 0], v[:, 1], color="tab:blue", lw=1.0, label=label)
            seen.add(family.shape if family.shape == "polygon" else "segment")
        for orbit in result.orbits:
            style = KIND_STYLE[orbit.kind]
            label = orbit.kind if orbit.kind not in seen else None
            seen.add(orbit.kind)
            ax.plot(
                orbit.x, orbit.p, ls="none", ms=5 if orbit.kind != "hyperbolic" else 3, label=label, **style
            )
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("p mod 1")
    shown = ", ".join(str(m) for m in periods)
    ax.set_title(
        f"periodic orbits of period {shown}: K = {params.K}, b1 = {params.b1}, b2 = {params.b2}", fontsize=9
    )
    # Below the torus, not over it: the legend must not hide orbits.
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=1, frameon=False)
    fig.tight_layout()
    return fig


def _periods(text: str) -> list[int]:
    try:
        periods = [int(item) for item in text.split(",") if item.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid period list: {text!r} (e.g. 1,2,3)") from None
    if not periods or any(not 1 <= m <= 9 for m in periods):
        raise argparse.ArgumentTypeError(f"periods = {text!r}: each must be in the range 1 <= m <= 9")
    return periods


def _parser(prog: str) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=prog, description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "source", nargs="?", type=Path, help="run --transport --json output, or its archive (.h5)"
    )
    parser.add_argument(
        "-o", "--out", type=Path, required=True, help="output image (.png or .pdf); must not exist"
    )
    parser.add_argument("--orbits", action="store_true", help="draw periodic orbits on the torus instead")
    parser.add_argument("--K", type=float, help="with --orbits: kick strength")
    parser.add_argument("--b1", type=float, help="with --orbits: left strip width")
    parser.add_argument("--b2", type=float, help="with --orbits: right strip width")
    parser.add_argument(
        "--period", type=_periods, default=[1, 2, 3], help="with --orbits: periods, e.g. 1,2,3"
    )
    parser.add_argument(
        "--background", type=int, default=2000, help="with --orbits: strip orbits drawn behind (0: none)"
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Draw one figure; 0 on success, 2 on bad input (one line), 130 after Ctrl-C."""

    def draw(args: argparse.Namespace) -> int:
        from .figures.canvas import pyplot

        if args.out.exists():
            raise ValueError(f"{args.out} already exists; choose another --out")
        if args.out.suffix not in (".png", ".pdf"):
            raise ValueError(f"--out {args.out}: the format is the suffix, .png or .pdf")
        plt = pyplot()
        if args.orbits:
            if None in (args.K, args.b1, args.b2):
                raise ValueError("--orbits needs --K, --b1 and --b2")
            fig = portrait(plt, MapParams(args.K, args.b1, args.b2), args.period, args.background)
        else:
            if args.source is None:
                raise ValueError("give a run --transport --json output or its archive, or --orbits")
            report, title = _load_report(args.source)
            fig = distributions(plt, report, title)
        fig.savefig(args.out, dpi=150)
        plt.close(fig)
        print(args.out)
        return 0

    return run(_parser(command_name("transport")), argv, draw)
