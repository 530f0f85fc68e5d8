"""What a recording shows: entity paths, colours, classes and the default blueprint.

A recording shows, on a ``step`` timeline, the points ``(x, p mod 1)`` of a fixed subsample of
the ensemble in the unit torus ``T^2`` (Sec. III B, Figs. 1, 2 and 4), coloured by their
finite-time Lyapunov exponent or by class (chaotic sea, the L and R accelerator-mode islands of
Sec. III C with ``w = +1`` and ``w = -1``, the normal island with ``w = 0``), next to time series
of the mean acceleration ``A_n`` of Eq. (An) with its standard error, the mean FTLE, the
chaotic fraction and the theory's ``A`` (Eqs. Aa, Ab; K = 3 only) as a reference line.

Layout of a recording (entity paths)::

    phase_space                   static Transform3D: flips the 2-D view so that p points up
    phase_space/cloud             Points2D, positions (x, p mod 1) in [0, 1)^2, one row per frame
    phase_space/axes              static: the unit square, ticks at 0, 0.5, 1 and the labels x, p mod 1
    series/A/numerics             mean A_n over chaotic points (Eq. An)
    series/A/theory               the paper's A, where it has one
    series/A_stderr               its standard error
    series/lyapunov/mean, /min    FTLE of the chaotic points (per iteration)
    series/chaotic_fraction       fraction of points with FTLE above the threshold
    parameters                    static TextDocument (markdown)

rerun-sdk is an optional dependency (``pip install 'warpratchet[rerun]'``): it is imported only
when a recording is opened (:func:`require_rerun` raises a clear :class:`ImportError` when it
is missing); everything else here is plain NumPy.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from .. import theory
from ..params import MapParams

__all__ = [
    "RERUN_MISSING",
    "require_rerun",
    "VIRIDIS",
    "UNDEFINED_COLOR",
    "CLASSES",
    "COLOR_BY",
    "SERIES_KEYS",
    "SERIES_NAMES",
    "THEORY_PATH",
    "CLOUD_PATH",
    "PHASE_SPACE_PATH",
    "PARAMETERS_PATH",
    "AXES_PATH",
    "PLAYBACK_SECONDS",
    "ftle_colors",
    "class_ids",
    "torus_positions",
    "markdown_parameters",
    "blueprint",
]

RERUN_MISSING = "rerun-sdk is not installed: pip install 'warpratchet[rerun]'"

#: Viridis (matplotlib's perceptually uniform map) at 33 equally spaced nodes, sRGB 0-255.
#: Linear interpolation between the nodes, rounded to integers, stays within 3.5/255 of
#: matplotlib's 256-entry table (checked in tests/recording/test_recording.py), so no matplotlib import is
#: needed here.
VIRIDIS = np.array(
    [
        [68, 1, 84], [71, 13, 96], [72, 24, 106], [72, 35, 116], [71, 45, 123], [69, 55, 129],
        [66, 64, 134], [62, 73, 137], [59, 82, 139], [55, 91, 141], [51, 99, 141], [47, 107, 142],
        [44, 114, 142], [41, 122, 142], [38, 130, 142], [35, 137, 142], [33, 145, 140], [31, 152, 139],
        [31, 160, 136], [34, 167, 133], [40, 174, 128], [50, 182, 122], [63, 188, 115], [78, 195, 107],
        [94, 201, 98], [112, 207, 87], [132, 212, 75], [152, 216, 62], [173, 220, 48], [194, 223, 35],
        [216, 226, 25], [236, 229, 27], [253, 231, 37],
    ],
    dtype=np.float64,
)  # fmt: skip
# A 256-entry table interpolated once, so colouring a frame is one table lookup per point.
_VIRIDIS_256 = np.stack(
    [
        np.interp(np.linspace(0.0, 1.0, 256), np.linspace(0.0, 1.0, len(VIRIDIS)), VIRIDIS[:, k])
        for k in range(3)
    ],
    axis=1,
)
_VIRIDIS_256 = np.round(_VIRIDIS_256).astype(np.uint8)
#: Colour of points at step 0, where the FTLE is not defined yet.
UNDEFINED_COLOR = (200, 200, 200)

#: Class ids of :func:`class_ids`: ``id -> (label, sRGB colour)`` (Okabe-Ito, colour-blind safe).
CLASSES: dict[int, tuple[str, tuple[int, int, int]]] = {
    0: ("unclassified (step 0)", UNDEFINED_COLOR),
    1: ("chaotic", (150, 150, 150)),
    2: ("L island (w = +1)", (230, 159, 0)),
    3: ("R island (w = -1)", (0, 158, 115)),
    4: ("normal island (w = 0)", (86, 180, 233)),
    5: ("other regular", (213, 94, 0)),
}

#: Ways to colour the cloud: by FTLE (:func:`ftle_colors`) or by class (:func:`class_ids`).
COLOR_BY = ("ftle", "class")

#: Scalar series of a recording, by the key of :class:`~warpratchet.observables.Summary` and of
#: an archive's ``series``, with their entity paths.
SERIES_KEYS: dict[str, str] = {
    "A": "series/A/numerics",
    "A_stderr": "series/A_stderr",
    "lyapunov": "series/lyapunov/mean",
    "lyapunov_min": "series/lyapunov/min",
    "chaotic_fraction": "series/chaotic_fraction",
}
THEORY_PATH = "series/A/theory"
CLOUD_PATH = "phase_space/cloud"

#: Legend names of the series in the viewer.
SERIES_NAMES: dict[str, str] = {
    "A": "mean A_n (chaotic points)",
    "A_stderr": "standard error of A_n",
    "lyapunov": "mean FTLE",
    "lyapunov_min": "min FTLE",
    "chaotic_fraction": "chaotic fraction",
}
PHASE_SPACE_PATH = "phase_space"
PARAMETERS_PATH = "parameters"
AXES_PATH = "phase_space/axes"
#: Pressing play in the viewer runs through the whole recording in about this many seconds.
PLAYBACK_SECONDS = 60.0


def require_rerun() -> Any:
    """Import and return the ``rerun`` module.

    Raises
    ------
    ImportError
        With the message :data:`RERUN_MISSING` when rerun-sdk is not installed.
    """
    try:
        import rerun
    except ImportError as exc:
        raise ImportError(RERUN_MISSING) from exc
    return rerun


# -- per-point colours and classes -----------------------------------------------------------------
def ftle_colors(ftle: np.ndarray, ftle_range: tuple[float, float] = (1.0e-3, 10.0)) -> np.ndarray:
    """Viridis colours of FTLEs on a log scale, shape ``(n, 3)`` uint8 sRGB.

    Parameters
    ----------
    ftle : ndarray, shape (n,)
        Finite-time Lyapunov exponents (per iteration, natural log), see
        :func:`warpratchet.observables.lyapunov`.
    ftle_range : (float, float)
        ``(lo, hi)`` mapped to the dark and bright ends; values outside (including the zero or
        slightly negative FTLEs of regular orbits) are clipped to the ends.
    """
    lo, hi = ftle_range
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (np.log(np.clip(ftle, lo, hi)) - math.log(lo)) / (math.log(hi) - math.log(lo))
    index = np.rint(np.nan_to_num(t, nan=0.0) * 255.0).astype(np.intp)
    return _VIRIDIS_256[index]


def class_ids(ftle: np.ndarray, acc: np.ndarray, threshold: float) -> np.ndarray:
    """Class ids of :data:`CLASSES` per point, shape ``(n,)`` uint16.

    Chaotic if ``ftle > threshold`` (as :func:`warpratchet.observables.chaotic_mask`); a regular
    point is in the L island if ``round(A_n) == +1``, the R island if ``-1`` and the normal island
    if ``0`` (Sec. III C: the period-1 accelerator modes of Eq. (xp) have ``w = +-1``, Eq. (wK)),
    and "other regular" otherwise. For short runs the default threshold is large (see
    :func:`~warpratchet.observables.default_lyapunov_threshold`) and weakly chaotic points show
    up as regular.

    Parameters
    ----------
    ftle, acc : ndarray, shape (n,)
        FTLE and ``A_n`` (Eq. An) per point.
    threshold : float
        Chaos threshold on the FTLE.
    """
    winding = np.rint(acc)
    ids = np.full(ftle.shape, 5, dtype=np.uint16)
    ids[winding == 1.0] = 2
    ids[winding == -1.0] = 3
    ids[winding == 0.0] = 4
    ids[ftle > threshold] = 1
    return ids


def torus_positions(x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``(x, p mod 1)`` as float32 positions in ``[0, 1)^2``, shape ``(n, 2)``.

    A float64 just below 1 rounds to exactly 1.0 in float32; on the torus that is 0, so such
    values are wrapped instead of leaving the unit square.
    """
    pos = np.empty((len(x), 2), dtype=np.float32)
    pos[:, 0] = x
    pos[:, 1] = np.mod(p, 1.0)
    pos[pos >= 1.0] = 0.0
    return pos


def markdown_parameters(params: MapParams, extra: Mapping[str, object]) -> str:
    """The parameters document of a recording: a markdown table of the map, its theory and ``extra``."""
    summary = theory.summary(params)
    if params.is_paper:
        force = [
            ("b1, b2 (strip widths, Eq. fx)", f"{params.b1!r}, {params.b2!r}"),
            ("l1, l2, c (Eq. mmc)", f"{params.l1:.6g}, {params.l2:.6g}, {params.c:.6g}"),
        ]
    else:
        force = [("force (knots; values)", "; ".join(params.table.as_strings().values()))]
    rows = [
        ("K (kick strength, Eq. cpem)", params.K),
        *force,
        ("alpha (Eq. eig)", f"{params.alpha:.6g} rad"),
        ("islands (Fig. 3 domain)", summary["domain"]),
        ("theory A (Eqs. Aa, Ab)", "n/a (K != 3)" if summary["A"] is None else f"{summary['A']:.6g}"),
    ]
    rows += [(str(k), v) for k, v in extra.items()]
    lines = ["| quantity | value |", "|---|---|"] + [f"| {k} | {v} |" for k, v in rows]
    return "\n".join(lines)


# -- the default view ------------------------------------------------------------------------------
def axes(rr: Any) -> list[tuple[str, Any]]:
    """Static ``(entity path, archetype)`` pairs drawing the axes of the phase-space panel.

    In the torus's own coordinates (``x`` right, ``p mod 1`` up; the panel's transform flips
    rerun's downward y): the unit square, ticks and labels at 0, 0.5 and 1 on both axes, and
    the axis names below and left of it.
    """
    grey = [120, 120, 120]
    ticks = [[[v, 0.0], [v, -0.02]] for v in (0.0, 0.5, 1.0)] + [
        [[0.0, v], [-0.02, v]] for v in (0.0, 0.5, 1.0)
    ]
    label_at = [[v, -0.05] for v in (0.0, 0.5, 1.0)] + [[-0.06, v] for v in (0.0, 0.5, 1.0)]
    labels = ["0", "0.5", "1"] * 2
    return [
        (f"{AXES_PATH}/square", rr.LineStrips2D([[[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]]], colors=grey)),
        (f"{AXES_PATH}/ticks", rr.LineStrips2D(ticks, colors=grey)),
        (
            f"{AXES_PATH}/labels",
            rr.Points2D(
                label_at + [[0.5, -0.1], [-0.12, 0.5]],
                labels=labels + ["x", "p mod 1"],
                radii=0.0,
                colors=grey,
                show_labels=True,
            ),
        ),
    ]


def blueprint(trail: bool = False, steps: int | None = None) -> Any:
    """The default view: the torus on the left, the series and the parameters on the right.

    * The time cursor starts at the first step, paused. rerun 0.41's time-panel blueprint has
      no cursor position; a paused panel starts at the *end* while the viewer is "following",
      and any loop mode turns following off, so the panel is paused with ``loop_mode="all"``:
      the cursor then starts at the beginning of the timeline (re_viewer_context,
      ``TimeControl::update``). Play runs the whole recording in :data:`PLAYBACK_SECONDS`.
    * The time-series panels show the whole run, whatever the cursor: their visible range and
      their x axis are the whole ``step`` timeline.
    * ``trail``: the phase-space view shows every frame up to the time cursor (the union of the
      iterates, as in Fig. 2) instead of the current frame only.

    Parameters
    ----------
    trail : bool
        See above.
    steps : int, optional
        Length of the run in steps (sets the playback speed; default: 100 steps per second).
    """
    rr = require_rerun()
    import rerun.blueprint as rrb

    time_ranges = None
    if trail:
        time_ranges = rr.VisibleTimeRange(
            "step", start=rr.TimeRangeBoundary.infinite(), end=rr.TimeRangeBoundary.cursor_relative()
        )
    phase_space = rrb.Spatial2DView(
        name="phase space (x, p mod 1)",
        origin="/",
        contents="phase_space/**",
        # View coordinates put y downwards: p in [-0.14, 1.04] is y in [-0.04, 1.14].
        visual_bounds=rrb.VisualBounds2D(x_range=[-0.16, 1.04], y_range=[-0.04, 1.14]),
        time_ranges=time_ranges,
    )
    everything = rr.TimeRange(start=rr.TimeRangeBoundary.infinite(), end=rr.TimeRangeBoundary.infinite())

    def series(name: str, origin: str) -> Any:
        return rrb.TimeSeriesView(
            name=name,
            origin=origin,
            time_ranges=rr.VisibleTimeRange("step", range=everything),
            axis_x=rrb.TimeAxis(view_range=everything),
        )

    panels = rrb.Vertical(
        series("A_n (Eq. An) and theory", "series/A"),
        series("standard error of A_n", "series/A_stderr"),
        series("FTLE of chaotic points", "series/lyapunov"),
        series("chaotic fraction", "series/chaotic_fraction"),
        rrb.TextDocumentView(name="parameters", origin="parameters"),
    )
    fps = 100.0 if not steps else max(1.0, steps / PLAYBACK_SECONDS)
    return rrb.Blueprint(
        rrb.Horizontal(phase_space, panels, column_shares=[3, 2]),
        rrb.TimePanel(timeline="step", play_state="paused", loop_mode="all", fps=fps),
        collapse_panels=True,
    )
