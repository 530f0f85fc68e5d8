"""``python -m viz history run.h5 -o history.png``: A_n and sigma_n of a run against n (log n axis).

The history of an archive (``warpratchet run --out``, group ``/history``): at log-spaced
steps, the mean A_n of Eq. (An) over the chaotic points with its standard error, and their mean
finite-time Lyapunov exponent sigma_n. Marked: n/2 and n, between which the drift of the verdict
is measured, the robust standard error at n, and the closed form of Eqs. (Aa)/(Ab) where the
paper has one (K = 3). The title gives the verdict (:meth:`warpratchet.history.History.convergence`).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from warpratchet import open_archive, theory

from .command import command_name, run
from .figures.canvas import pyplot

__all__ = ["plot_history", "main"]


def plot_history(archive: str | Path, out: str | Path, dpi: int = 150) -> Path:
    """Draw the history of ``archive`` into ``out`` (PNG or PDF, by its suffix); returns ``out``.

    Raises ``ValueError`` (one line) for an archive without a history or without rows yet.
    """
    out = Path(out)
    if out.suffix.lower() not in (".png", ".pdf"):
        raise ValueError(f"-o {out}: the file name must end in .png or .pdf")
    with open_archive(archive) as arc:
        history, params = arc.history, arc.params
    if history is None:
        raise ValueError(f"{archive} has no history (written before warpratchet kept one, or not by run)")
    if not history.rows["step"]:
        raise ValueError(f"{archive}: the history has no rows yet")
    rows = {k: np.asarray(v, dtype=float) for k, v in history.rows.items()}
    verdict = history.convergence()
    n = rows["step"][-1]
    plt = pyplot()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(6.5, 6.5), sharex=True)
    top.fill_between(
        rows["step"], rows["A"] - rows["A_stderr"], rows["A"] + rows["A_stderr"], alpha=0.3, lw=0
    )
    top.plot(rows["step"], rows["A"], "o-", ms=3, lw=1, label=r"$A_n$ $\pm$ standard error")
    if np.isfinite(verdict.A_stderr_robust):
        top.errorbar([n], [rows["A"][-1]], yerr=[verdict.A_stderr_robust], fmt="none", ecolor="C3", capsize=4,
                     label="robust standard error at $n$")  # fmt: skip
    a_theory = theory.summary(params)["A"]
    if a_theory is not None:
        top.axhline(a_theory, color="black", lw=0.8, ls="--", label="Eqs. (Aa)/(Ab)")
    for ax in (top, bottom):
        for at in (n / 2, n):
            ax.axvline(at, color="gray", lw=0.6, ls=":")
    for at, name in ((n / 2, "$n/2$"), (n, "$n$")):  # the two rows the drift verdict compares
        for ax in (top, bottom):
            place = ax.get_xaxis_transform()
            ax.text(at, 0.98, f"{name} ", transform=place, ha="right", va="top", fontsize=8, color="dimgray")
    top.set_ylabel(r"$A_n$ (momentum per kick)")
    late = rows["step"] >= n / 64  # zoom on the settled part: early rows swing over the whole range
    if np.any(late) and np.all(np.isfinite(rows["A"][late])):
        lo, hi = (
            np.min(rows["A"][late] - 3 * rows["A_stderr"][late]),
            np.max(rows["A"][late] + 3 * rows["A_stderr"][late]),
        )
        lo, hi = lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo)
        top.set_ylim(lo, hi)
        # Rows off the zoomed scale are drawn on its edge, pointing the way they left it.
        edges = ((rows["A"] > hi, hi, "^", "above"), (rows["A"] < lo, lo, "v", "below"))
        for off, edge, marker, side in edges:
            if np.any(off):
                count = int(off.sum())
                label = f"{count} early row{'s' if count > 1 else ''} off scale, $A_n$ {side}"
                top.plot(rows["step"][off], np.full(int(off.sum()), edge), marker, color="C0", ms=6,
                         clip_on=False, label=label)  # fmt: skip
    top.legend(fontsize=8, loc="best")
    bottom.plot(rows["step"], rows["sigma"], "o-", ms=3, lw=1, color="C2")
    bottom.set_ylabel(r"$\sigma_n$ (per kick)")
    bottom.set_xlabel(r"$n$ (iterations)")
    bottom.set_xscale("log")
    top.set_title(
        f"K = {params.K}, b1 = {params.b1}, b2 = {params.b2}: A_n - A_n/2 = {verdict.drift:+.2g} "
        f"(z = {verdict.drift_z:+.2f}), {verdict.verdict}",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m viz history ARCHIVE -o FILE``; exit status 2 on bad input."""
    parser = argparse.ArgumentParser(prog=command_name("history"), description=__doc__.split("\n\n")[0])
    parser.add_argument("archive", help="an archive of warpratchet run --out")
    parser.add_argument("-o", "--out", required=True, help="the figure, .png or .pdf")
    parser.add_argument("--dpi", type=int, default=150, help="PNG resolution (default 150)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")

    def body(args: argparse.Namespace) -> int:
        if Path(args.out).exists() and not args.overwrite:
            raise ValueError(f"{args.out} already exists; pass --overwrite or choose another --out")
        print(plot_history(args.archive, args.out, args.dpi))
        return 0

    return run(parser, argv, body)


if __name__ == "__main__":
    sys.exit(main())
