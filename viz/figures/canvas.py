"""What every figure shares: matplotlib, the output files with their captions, and common axes."""

from __future__ import annotations

import textwrap
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from warpratchet import paper, theory
from warpratchet.params import MapParams

from .sweeps import Settings, load_or_run_sweep

__all__ = ["pyplot", "Context", "mark_islands", "torus_axes", "plane_axes"]


def pyplot() -> Any:
    """Import matplotlib (non-interactive backend) or fail with a one-line hint."""
    try:
        import matplotlib
    except ImportError:
        raise ValueError("matplotlib is needed for the figures: pip install 'warpratchet[figures]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


@dataclass
class Context:
    """What every figure function needs."""

    plt: Any
    settings: Settings
    out: Path
    sweeps: Path
    formats: tuple[str, ...]
    dpi: int
    progress: bool
    client: Any = None
    written: list[Path] = field(default_factory=list)

    def sweep(self, name: str) -> list[dict]:
        return load_or_run_sweep(name, self.settings, self.sweeps, self.progress, self.client)

    def save(self, fig, name: str, caption: str) -> None:
        """Add the caption under the axes and write ``<out>/<name>.<fmt>`` for each format.

        ``caption`` is prose: its line breaks and indentation become single spaces.
        """
        caption = " ".join(caption.split())
        # About 16 characters of 7-pt text per inch; 0.12 inch per line.
        wrapped = "\n".join(textwrap.wrap(caption, width=int(fig.get_figwidth() * 16)))
        fig.text(0.01, 0.005, wrapped, ha="left", va="bottom", fontsize=7)
        caption_height = (wrapped.count("\n") + 1.5) * 0.12 / fig.get_figheight()
        fig.tight_layout(rect=(0.0, caption_height, 1.0, 1.0))
        for fmt in self.formats:
            path = self.out / f"{name}.{fmt}"
            meta = {"Title": f"{name}: Dana & Roitberg, Weak-Chaos Ratchet Accelerator"}
            meta["Description" if fmt == "png" else "Subject"] = caption
            fig.savefig(path, dpi=self.dpi, metadata=meta)
            self.written.append(path)
        self.plt.close(fig)


def mark_islands(ax, params: MapParams, color: str = "red") -> None:
    """Mark the period-1 accelerator modes (Eq. xp): L for w = 1, R for w = -1, at p = 0 and p = 1."""
    for w, x0 in theory.accelerator_modes(params):
        label = "L" if w == 1 else "R"
        ax.plot([x0, x0], [0.0, 1.0], ls="none", marker="o", ms=4, color=color, clip_on=False, zorder=5)
        ax.annotate(
            label,
            (x0, 0.0),
            xytext=(0, 6),
            textcoords="offset points",
            ha="center",
            color=color,
            fontsize=10,
            fontweight="bold",
            zorder=6,
        )


def torus_axes(ax, title: str) -> None:
    """The unit torus ``0 <= x, p < 1`` of Figs. 1, 2, 4 and 10-12, with ``title``."""
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(0.0, 1.0)
    ax.set_aspect("equal")
    ax.set_xlabel(r"$x$ (position, unit period)")
    ax.set_ylabel(r"$p$ mod 1 (momentum)")
    ax.set_title(title, fontsize=9)


def plane_axes(ax, title: str, legend_size: int | None = None) -> None:
    """The (b1, b2) plane of Figs. 3, 5 and 6, with ``title`` and a legend of ``legend_size`` points."""
    ax.set_xlim(0.0, paper.PLANE_EXTENT)
    ax.set_ylim(0.0, paper.PLANE_EXTENT)
    ax.set_aspect("equal")
    ax.set_xlabel(r"$b_1$ (width of the left hyperbolic strip)")
    ax.set_ylabel(r"$b_2$ (width of the right hyperbolic strip)")
    if legend_size is not None:
        ax.legend(loc="upper right", fontsize=legend_size)
    ax.set_title(title, fontsize=9)
