"""Rerun recordings of the phase-space cloud: watch an ensemble fill the chaotic region.

A recording shows, on a ``step`` timeline, the points ``(x, p mod 1)`` of a fixed subsample of
the ensemble in the unit torus ``T^2`` (Sec. III B, Figs. 1, 2 and 4), coloured by their
finite-time Lyapunov exponent or by class (chaotic sea, the L and R accelerator-mode islands of
Sec. III C with ``w = +1`` and ``w = -1``, the normal island with ``w = 0``), next to time series
of the mean acceleration ``A_n`` of Eq. (An) with its standard error, the mean FTLE, the
chaotic fraction and the theory's ``A`` (Eqs. Aa, Ab; K = 3 only) as a reference line.

rerun-sdk is an optional dependency (``pip install 'warpratchet[rerun]'``): it is imported only
when a recording is opened, and :func:`require_rerun` raises a clear :class:`ImportError` when it
is missing. Recordings go to an explicit ``rerun.RecordingStream`` (never the global one), so a
process can write several; a file is written with a file sink and never overwrites an existing
file.

Layout of a recording (entity paths)::

    phase_space                   static Transform3D: flips the 2-D view so that p points up
    phase_space/cloud             Points2D, positions (x, p mod 1) in [0, 1)^2, one row per frame
    series/A/numerics             mean A_n over chaotic points (Eq. An)
    series/A/theory               the paper's A, where it has one
    series/A_stderr               its standard error
    series/lyapunov/mean, /min    FTLE of the chaotic points (per iteration)
    series/chaotic_fraction       fraction of points with FTLE above the threshold
    parameters                    static TextDocument (markdown)
"""

from __future__ import annotations

import math
import time
import uuid
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np

from . import theory
from .ensemble import Ensemble, Observer
from .observables import Summary, acceleration, default_lyapunov_threshold, lyapunov, summarize
from .params import MapParams

__all__ = [
    "RERUN_MISSING",
    "require_rerun",
    "VIRIDIS",
    "ftle_colors",
    "CLASSES",
    "classify",
    "torus_positions",
    "SERIES_KEYS",
    "THEORY_PATH",
    "CLOUD_PATH",
    "DEFAULT_MAX_POINTS",
    "DEFAULT_MAX_FRAMES",
    "frame_every",
    "check_new_file",
    "PhaseSpaceRecording",
    "RecordingSink",
]

RERUN_MISSING = "rerun-sdk is not installed: pip install 'warpratchet[rerun]'"

#: Viridis (matplotlib's perceptually uniform map) at 33 equally spaced nodes, sRGB 0-255.
#: Linear interpolation between the nodes, rounded to integers, stays within 3.5/255 of
#: matplotlib's 256-entry table (checked in tests/test_recording.py), so no matplotlib import is
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

#: Class ids of :func:`classify`: ``id -> (label, sRGB colour)`` (Okabe-Ito, colour-blind safe).
CLASSES: dict[int, tuple[str, tuple[int, int, int]]] = {
    0: ("unclassified (step 0)", UNDEFINED_COLOR),
    1: ("chaotic", (150, 150, 150)),
    2: ("L island (w = +1)", (230, 159, 0)),
    3: ("R island (w = -1)", (0, 158, 115)),
    4: ("normal island (w = 0)", (86, 180, 233)),
    5: ("other regular", (213, 94, 0)),
}

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

#: Default subsample size: ~1.2 MB per frame (float32 positions, RGBA colours), dense enough to
#: show the islands as holes in a view of ~10^3 pixels across.
DEFAULT_MAX_POINTS = 100_000
#: Default cap on the number of frames of a run (keeps a default recording below ~150 MB).
DEFAULT_MAX_FRAMES = 100

# Cost model of one frame, measured with benchmarks/recording_overhead.py on the 2-core CPU:
# ~2 ms fixed, ~45 ns per recorded point (gather, FTLE, colours, serialisation) and ~35 ns per
# ensemble point (the full-ensemble summary). At ~9e8 point-steps/s, keeping a frame below 5% of the
# run time between frames (half the 10% budget, for noise and file writing) needs an interval
# of at least 20 x 9e8 x cost point-steps.
_NS_PER_RECORDED_POINT = 45.0
_NS_PER_ENSEMBLE_POINT = 35.0
_FRAME_FIXED_SECONDS = 2.0e-3
_POINT_STEPS_PER_SECOND = 9.0e8
_OVERHEAD_BUDGET = 0.05


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


def classify(ftle: np.ndarray, acc: np.ndarray, threshold: float) -> np.ndarray:
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


def frame_every(
    points: int,
    steps: int,
    max_points: int = DEFAULT_MAX_POINTS,
    max_frames: int = DEFAULT_MAX_FRAMES,
) -> int:
    """Default steps between frames of a live recording.

    The larger of (i) the interval after which one frame (``min(points, max_points)`` recorded
    points plus a summary of all ``points``) costs at most 5% of the CPU run time, from the cost
    model measured by ``benchmarks/recording_overhead.py``, and (ii) ``steps / max_frames``.
    On a GPU the run is faster and the same interval costs relatively more: pass ``every``.

    Parameters
    ----------
    points : int
        Ensemble size.
    steps : int
        Iterations of the run.
    max_points : int
        Points drawn per frame (the subsample size ``M``).
    max_frames : int
        Upper bound on the number of frames (besides the first and the last).

    Returns
    -------
    int
        Steps between frames, ``>= 1``. Examples on 2 CPU cores: 10^4 points x 1.2e5 steps ->
        5041 (25 frames); 10^6 points x 1200 steps -> 748.
    """
    recorded = min(points, max_points)
    frame_seconds = (
        _NS_PER_RECORDED_POINT * 1e-9 * recorded
        + _NS_PER_ENSEMBLE_POINT * 1e-9 * points
        + _FRAME_FIXED_SECONDS
    )
    by_cost = math.ceil(frame_seconds * _POINT_STEPS_PER_SECOND / (_OVERHEAD_BUDGET * points))
    by_count = math.ceil(steps / max_frames) if max_frames > 0 else 1
    return max(1, by_cost, by_count)


def check_new_file(path: str | Path) -> Path:
    """``path`` as a Path, if it does not exist and its folder does.

    Raises
    ------
    FileExistsError, FileNotFoundError
        A recording never overwrites a file, and needs an existing folder.
    """
    path = Path(path)
    if path.exists() or path.is_symlink():
        raise FileExistsError(f"{path} exists; refusing to overwrite it (remove it or choose another path)")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"folder {path.parent} of the recording {path} does not exist")
    return path


def _check_int(name: str, value: object, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name} = {value!r} is outside the allowed range {name} >= {low}")
    return int(value)


def _markdown_parameters(params: MapParams, extra: Mapping[str, object]) -> str:
    summary = theory.summary(params)
    rows = [
        ("K (kick strength, Eq. cpem)", params.K),
        ("b1, b2 (strip widths, Eq. fx)", f"{params.b1!r}, {params.b2!r}"),
        ("l1, l2, c (Eq. mmc)", f"{params.l1:.6g}, {params.l2:.6g}, {params.c:.6g}"),
        ("alpha (Eq. eig)", f"{params.alpha:.6g} rad"),
        ("islands (Fig. 3 domain)", summary["domain"]),
        ("theory A (Eqs. Aa, Ab)", "n/a (K != 3)" if summary["A"] is None else f"{summary['A']:.6g}"),
    ]
    rows += [(str(k), v) for k, v in extra.items()]
    lines = ["| quantity | value |", "|---|---|"] + [f"| {k} | {v} |" for k, v in rows]
    return "\n".join(lines)


# -- the recording -----------------------------------------------------------------------------------
class PhaseSpaceRecording:
    """A rerun recording of phase-space clouds and ensemble series for one map.

    Parameters
    ----------
    params : MapParams
        The map; its parameters and the theory's ``A`` are logged.
    path : str or Path, optional
        ``.rrd`` file to write. Must not exist (never overwritten); its folder must exist.
    spawn : bool
        Also spawn a rerun viewer and stream to it (needs a display; never in tests).
    color_by : {"ftle", "class"}
        Colour points by FTLE (viridis, log scale over ``ftle_range``) or by class
        (:data:`CLASSES`, via an annotation context).
    ftle_range : (float, float)
        FTLE range of the colour map, ``0 < lo < hi`` (per iteration).
    trail : bool
        Default view shows every frame up to the time cursor (the union of the iterates, as in
        Fig. 2) instead of the current frame only.
    title : str, optional
        Recording name shown by the viewer.
    info : mapping, optional
        Extra rows for the parameters document (e.g. points, seed, sampler).
    application_id : str
        rerun application id (recordings with one id share blueprints in the viewer).

    Raises
    ------
    ValueError
        Bad ``color_by``/``ftle_range``, or neither ``path`` nor ``spawn``.
    FileExistsError, FileNotFoundError
        ``path`` exists, or its folder does not.
    ImportError
        rerun-sdk is not installed.
    """

    def __init__(
        self,
        params: MapParams,
        path: str | Path | None = None,
        *,
        spawn: bool = False,
        color_by: Literal["ftle", "class"] = "ftle",
        ftle_range: tuple[float, float] = (1.0e-3, 10.0),
        trail: bool = False,
        title: str | None = None,
        info: Mapping[str, object] | None = None,
        application_id: str = "warpratchet",
    ) -> None:
        if color_by not in ("ftle", "class"):
            raise ValueError(f"color_by = {color_by!r} is not one of 'ftle', 'class'")
        lo, hi = (float(v) for v in ftle_range)
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
            raise ValueError(f"ftle_range = {ftle_range!r} is outside the allowed range 0 < lo < hi")
        if path is None and not spawn:
            raise ValueError("a recording needs a path, spawn=True, or both")
        if path is not None:
            path = check_new_file(path)
        rr = require_rerun()
        self._rr = rr
        self.params = params
        self.path = path
        self.color_by = color_by
        self.ftle_range = (lo, hi)
        self.theory_A = theory.summary(params)["A"]
        self.frames: list[int] = []
        self.closed = False

        rec = rr.RecordingStream(application_id, recording_id=uuid.uuid4())
        # The step timeline is the only clock that means anything here (replays have no
        # meaningful wall time).
        rec.set_log_time_enabled(False)
        blueprint = self._blueprint(trail)
        if spawn:
            rec.spawn(connect=False)
            sinks = [rr.GrpcSink()] + ([rr.FileSink(str(path))] if path is not None else [])
            rec.set_sinks(*sinks, default_blueprint=blueprint)
        else:
            rec.save(str(path), default_blueprint=blueprint)
        self._rec = rec
        if title is not None:
            rec.send_recording_name(title)
        self._log_static(title, dict(info or {}))

    # -- setup ------------------------------------------------------------------------------------
    def _blueprint(self, trail: bool) -> Any:
        import rerun.blueprint as rrb

        rr = self._rr
        time_ranges = None
        if trail:
            time_ranges = rr.VisibleTimeRange(
                "step", start=rr.TimeRangeBoundary.infinite(), end=rr.TimeRangeBoundary.cursor_relative()
            )
        phase_space = rrb.Spatial2DView(
            name="phase space (x, p mod 1)",
            origin="/",
            contents="phase_space/**",
            visual_bounds=rrb.VisualBounds2D(x_range=[0.0, 1.0], y_range=[0.0, 1.0]),
            time_ranges=time_ranges,
        )
        series = rrb.Vertical(
            rrb.TimeSeriesView(name="A_n (Eq. An) and theory", origin="series/A"),
            rrb.TimeSeriesView(name="standard error of A_n", origin="series/A_stderr"),
            rrb.TimeSeriesView(name="FTLE of chaotic points", origin="series/lyapunov"),
            rrb.TimeSeriesView(name="chaotic fraction", origin="series/chaotic_fraction"),
            rrb.TextDocumentView(name="parameters", origin="parameters"),
        )
        return rrb.Blueprint(rrb.Horizontal(phase_space, series, column_shares=[3, 2]), collapse_panels=True)

    def _log_static(self, title: str | None, info: dict[str, object]) -> None:
        rr, rec = self._rr, self._rec
        # rerun's 2-D views put y downwards; flip so that p increases upwards as in the paper.
        rec.log(
            "phase_space", rr.Transform3D(translation=[0.0, 1.0, 0.0], scale=[1.0, -1.0, 1.0]), static=True
        )
        if self.color_by == "class":
            rec.log(
                "phase_space",
                rr.AnnotationContext([(cid, label, color) for cid, (label, color) in CLASSES.items()]),
                static=True,
            )
        else:
            lo, hi = self.ftle_range
            info.setdefault("colour", f"FTLE, viridis on a log scale from {lo:g} (dark) to {hi:g} (bright)")
        text = (f"# {title}\n\n" if title else "") + _markdown_parameters(self.params, info)
        rec.log("parameters", rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN), static=True)
        names = {
            "A": "mean A_n (chaotic points)",
            "A_stderr": "standard error of A_n",
            "lyapunov": "mean FTLE",
            "lyapunov_min": "min FTLE",
            "chaotic_fraction": "chaotic fraction",
        }
        for key, entity in SERIES_KEYS.items():
            rec.log(entity, rr.SeriesLines(names=names[key]), static=True)
        if self.theory_A is not None:
            rec.log(
                THEORY_PATH, rr.SeriesLines(names="theory A (Eqs. Aa, Ab)", colors=[230, 159, 0]), static=True
            )

    # -- logging ----------------------------------------------------------------------------------
    def log_cloud(
        self,
        step: int,
        x: np.ndarray,
        p: np.ndarray,
        ftle: np.ndarray | None = None,
        acc: np.ndarray | None = None,
        threshold: float | None = None,
    ) -> None:
        """Log one frame of the cloud at ``step``.

        Parameters
        ----------
        step : int
            Iteration number (the ``step`` timeline).
        x, p : ndarray, shape (m,)
            Positions and momenta (any momentum; ``p mod 1`` is drawn).
        ftle : ndarray, shape (m,), optional
            FTLE per point; ``None`` (e.g. at step 0) draws every point in a neutral grey.
        acc : ndarray, shape (m,), optional
            ``A_n`` per point, needed with ``color_by="class"``.
        threshold : float, optional
            Chaos threshold for the classes (default
            :func:`~warpratchet.observables.default_lyapunov_threshold` of ``step``).
        """
        rr, rec = self._rr, self._rec
        rec.set_time("step", sequence=int(step))
        radii = rr.Radius.ui_points(1.0)
        positions = torus_positions(x, p)
        if ftle is None:
            if self.color_by == "class":
                points = rr.Points2D(positions, class_ids=np.zeros(len(x), np.uint16), radii=radii)
            else:
                points = rr.Points2D(positions, colors=UNDEFINED_COLOR, radii=radii)
        elif self.color_by == "class":
            if acc is None:
                raise ValueError("color_by='class' needs the per-point acceleration A_n")
            if threshold is None:
                threshold = default_lyapunov_threshold(step)
            points = rr.Points2D(positions, class_ids=classify(ftle, acc, threshold), radii=radii)
        else:
            points = rr.Points2D(positions, colors=ftle_colors(ftle, self.ftle_range), radii=radii)
        rec.log(CLOUD_PATH, points)
        self.frames.append(int(step))

    def log_summary(self, step: int, values: Mapping[str, float]) -> None:
        """Log one value of each series in :data:`SERIES_KEYS` (and the theory's A) at ``step``."""
        rr, rec = self._rr, self._rec
        rec.set_time("step", sequence=int(step))
        for key, entity in SERIES_KEYS.items():
            rec.log(entity, rr.Scalars(float(values[key])))
        if self.theory_A is not None:
            rec.log(THEORY_PATH, rr.Scalars(float(self.theory_A)))

    def send_series(self, steps: np.ndarray, series: Mapping[str, np.ndarray]) -> None:
        """Log whole series at once (columnar): ``series[key]`` has the shape of ``steps``."""
        rr, rec = self._rr, self._rec
        steps = np.asarray(steps, dtype=np.int64)
        index = [rr.TimeColumn("step", sequence=steps)]
        for key, entity in SERIES_KEYS.items():
            values = np.asarray(series[key], dtype=np.float64)
            if values.shape != steps.shape:
                raise ValueError(f"series {key!r} has shape {values.shape}, expected {steps.shape}")
            rec.send_columns(entity, indexes=index, columns=rr.Scalars.columns(scalars=values))
        if self.theory_A is not None:
            theory_line = np.full(steps.shape, float(self.theory_A))
            rec.send_columns(THEORY_PATH, indexes=index, columns=rr.Scalars.columns(scalars=theory_line))

    def close(self) -> None:
        """Flush everything to the sinks and close the file (idempotent)."""
        if not self.closed:
            self.closed = True
            self._rec.flush()
            self._rec.disconnect()

    def __enter__(self) -> PhaseSpaceRecording:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# -- the observer --------------------------------------------------------------------------------------
class RecordingSink(Observer):
    """An :class:`~warpratchet.ensemble.Observer` recording a run as it goes.

    A frame (the cloud of a fixed subsample plus the ensemble summary of
    :func:`~warpratchet.observables.summarize`) is logged when the run starts, after every chunk
    that reaches the next multiple of ``every`` steps, and when it ends. Frames can only fall on
    chunk boundaries: run with ``chunk_steps=sink.every`` (what ``warpratchet run --rerun``
    does) for frames at exact multiples. Recording never changes the run's results.

    Parameters
    ----------
    path : str or Path, optional
        ``.rrd`` file (must not exist).
    spawn : bool
        Stream to a newly spawned viewer as well (needs a display).
    max_points : int
        Subsample size ``M``: at most this many points are drawn per frame, the same points in
        every frame (chosen once with ``seed``).
    every : int, optional
        Steps between frames; default :func:`frame_every` of the run (set at the first
        :meth:`begin`).
    color_by : {"ftle", "class"}
        See :class:`PhaseSpaceRecording`.
    threshold : float, optional
        Chaos threshold for the summary and the classes (default
        :func:`~warpratchet.observables.default_lyapunov_threshold`).
    seed : int
        Seed of the subsample.
    **options
        Passed to :class:`PhaseSpaceRecording` (``ftle_range``, ``trail``, ``title``, ``info``).

    Attributes
    ----------
    summaries : list of Summary
        The summaries logged, in order (one per frame after step 0).
    frame_seconds : list of float
        Wall time spent in each :meth:`log_frame` (the recording's cost to the run).
    indices : ndarray, shape (M,)
        Indices of the recorded points (set at the first frame).
    """

    def __init__(
        self,
        path: str | Path | None = None,
        *,
        spawn: bool = False,
        max_points: int = DEFAULT_MAX_POINTS,
        every: int | None = None,
        color_by: Literal["ftle", "class"] = "ftle",
        threshold: float | None = None,
        seed: int = 0,
        **options: Any,
    ) -> None:
        self.max_points = _check_int("max_points", max_points, 1)
        self.every = None if every is None else _check_int("every", every, 1)
        if color_by not in ("ftle", "class"):
            raise ValueError(f"color_by = {color_by!r} is not one of 'ftle', 'class'")
        if path is None and not spawn:
            raise ValueError("a recording needs a path, spawn=True, or both")
        if path is not None:
            check_new_file(path)  # here as well, so that a bad path fails before the run
        require_rerun()
        self.path = path
        self.spawn = spawn
        self.color_by = color_by
        self.threshold = threshold
        self.seed = seed
        self.options = options
        self.summaries: list[Summary] = []
        self.frame_seconds: list[float] = []
        self.indices: np.ndarray | None = None
        self.recording: PhaseSpaceRecording | None = None
        self._next_frame = 0

    @property
    def frames(self) -> list[int]:
        """Steps of the frames logged so far."""
        return [] if self.recording is None else list(self.recording.frames)

    def open(self, ensemble: Ensemble) -> None:
        """Open the recording for ``ensemble`` (done by :meth:`begin`; idempotent)."""
        if self.recording is not None:
            if self.recording.closed:
                raise ValueError("this RecordingSink is closed (it records one run): make a new one")
            return
        n = ensemble.points
        if n <= self.max_points:
            self.indices = np.arange(n)
        else:
            # Sorted, so that gathering walks memory forwards.
            rng = np.random.default_rng(self.seed)
            self.indices = np.sort(rng.choice(n, size=self.max_points, replace=False))
        info = {
            "points": f"{n} ({ensemble.sampler}, seed {ensemble.seed})",
            "recorded points": f"{len(self.indices)} (fixed subsample, seed {self.seed})",
            "chaos threshold": "10 (1 + ln n)/n" if self.threshold is None else self.threshold,
        }
        info.update(self.options.pop("info", {}) or {})
        self.recording = PhaseSpaceRecording(
            ensemble.params, self.path, spawn=self.spawn, color_by=self.color_by, info=info, **self.options
        )

    def log_frame(self, ensemble: Ensemble) -> None:
        """Log the cloud and (after step 0) the summary of ``ensemble`` at its current step."""
        start = time.perf_counter()
        self._log_frame(ensemble)
        self.frame_seconds.append(time.perf_counter() - start)

    def _log_frame(self, ensemble: Ensemble) -> None:
        self.open(ensemble)
        assert self.recording is not None and self.indices is not None
        step = ensemble.step
        # Zero-copy views on the CPU; only the subsample and the summary are computed from them.
        state = {
            name: ensemble.array(name) for name in ("x", "q", "winding", "p0", "dx", "dp", "log_stretch")
        }
        whole = len(self.indices) == ensemble.points
        sub = state if whole else {k: v[self.indices] for k, v in state.items()}
        if step == 0:
            self.recording.log_cloud(0, sub["x"], sub["q"])
            return
        ftle = lyapunov(sub, step)
        acc = acceleration(sub, step) if self.color_by == "class" else None
        threshold = self.threshold if self.threshold is not None else default_lyapunov_threshold(step)
        self.recording.log_cloud(step, sub["x"], sub["q"], ftle, acc, threshold)
        summary = summarize(state, step, self.threshold)
        self.recording.log_summary(step, summary.as_dict())
        self.summaries.append(summary)

    def close(self) -> None:
        """Flush and close the recording (idempotent)."""
        if self.recording is not None:
            self.recording.close()

    # -- Observer -------------------------------------------------------------------------------
    def begin(self, ensemble: Ensemble, target_step: int) -> None:
        if self.every is None:
            self.every = frame_every(ensemble.points, target_step - ensemble.step, self.max_points)
        if not self.frames or self.frames[-1] != ensemble.step:
            self.log_frame(ensemble)
        self._next_frame = (ensemble.step // self.every + 1) * self.every

    def after_chunk(self, ensemble: Ensemble, seconds: float) -> None:
        if ensemble.step >= self._next_frame:
            self.log_frame(ensemble)
            self._next_frame = (ensemble.step // self.every + 1) * self.every

    def end(self, ensemble: Ensemble) -> None:
        if self.frames and self.frames[-1] != ensemble.step:
            self.log_frame(ensemble)
        self.close()
