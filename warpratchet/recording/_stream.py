"""A rerun recording of one map: :class:`PhaseSpaceRecording` writes frames and series to a file.

Recordings go to an explicit ``rerun.RecordingStream`` (never the global one), so a process can
write several; a file is written with a file sink and never overwrites an existing file
(:func:`check_new_file`, built on :func:`warpratchet._files.check_new_path`). What is drawn
where, and in which colours, is :mod:`._scene`.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import uuid
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Literal

import numpy as np

from .. import theory
from .._files import check_new_path, storage_errors
from ..errors import check_choice
from ..observables import default_lyapunov_threshold
from ..params import MapParams
from ._scene import (
    CLASSES,
    CLOUD_PATH,
    COLOR_BY,
    PARAMETERS_PATH,
    PHASE_SPACE_PATH,
    SERIES_KEYS,
    SERIES_NAMES,
    THEORY_PATH,
    UNDEFINED_COLOR,
    axes,
    blueprint,
    class_ids,
    ftle_colors,
    markdown_parameters,
    require_rerun,
    torus_positions,
)

__all__ = ["check_new_file", "display_available", "ViewerUnavailable", "PhaseSpaceRecording"]


class ViewerUnavailable(RuntimeError):
    """A viewer cannot be spawned here (no display); the recording to a file still works."""


def display_available() -> bool:
    """Whether a spawned rerun viewer can open a window: on Linux, an X11 or Wayland display.

    Without one the viewer exits at once and the recording stream waits for it, then fails.
    macOS and Windows always have a desktop session to open it in.
    """
    if not sys.platform.startswith("linux"):
        return True
    return any(os.environ.get(name) for name in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"))


def check_new_file(path: str | Path) -> Path:
    """``path`` as a Path, if it does not exist and its folder does.

    Raises
    ------
    FileExistsError, FileNotFoundError
        A recording never overwrites a file, and needs an existing folder.
    """
    check_new_path(path, hint=" (remove it or choose another path)")
    return Path(path)


def _claim_new_file(path: Path) -> None:
    """Create ``path`` empty (rerun's file sink then writes it), or one StorageError line.

    rerun reports a file it cannot create (read-only folder, disk full) only once it has buffered
    the recording's first data, and then warns about the dropped data when the process exits;
    creating the file first refuses it cleanly.
    """
    with storage_errors(path, "write"):
        os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))


class PhaseSpaceRecording:
    """A rerun recording of phase-space clouds and ensemble series for one map.

    Parameters
    ----------
    params : MapParams
        The map; its parameters and the theory's ``A`` are logged.
    path : str or Path, optional
        ``.rrd`` file to write. Must not exist (never overwritten); its folder must exist.
    spawn : bool
        Also spawn a rerun viewer and stream to it (needs a display: :class:`ViewerUnavailable`
        otherwise, before anything is written).
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
    steps : int, optional
        Length of the run in steps, for the viewer's playback speed.

    Raises
    ------
    ValueError
        Bad ``color_by``/``ftle_range``, or neither ``path`` nor ``spawn``.
    FileExistsError, FileNotFoundError
        ``path`` exists, or its folder does not.
    ImportError
        rerun-sdk is not installed.
    ViewerUnavailable
        ``spawn=True`` without a display.
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
        steps: int | None = None,
    ) -> None:
        color_by = check_choice("color_by", color_by, COLOR_BY)
        lo, hi = (float(v) for v in ftle_range)
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
            raise ValueError(f"ftle_range = {ftle_range!r} is outside the allowed range 0 < lo < hi")
        if path is None and not spawn:
            raise ValueError("a recording needs a path, spawn=True, or both")
        if path is not None:
            path = check_new_file(path)
        if spawn and not display_available():
            raise ViewerUnavailable(
                "a rerun viewer needs a display (DISPLAY and WAYLAND_DISPLAY are not set); record to "
                "a file and open it with `rerun FILE` (or `rerun --web-viewer FILE`)"
            )
        rr = require_rerun()
        self._rr = rr
        self.params = params
        self.path = path
        self.color_by = color_by
        self.ftle_range = (lo, hi)
        self.theory_A = theory.summary(params)["A"]
        self.frames: list[int] = []
        self.closed = False
        self.spawned = spawn

        if path is not None:
            _claim_new_file(path)  # a refused file fails here, before rerun buffers anything
        rec = rr.RecordingStream(application_id, recording_id=uuid.uuid4())
        # The step timeline is the only clock that means anything here (replays have no
        # meaningful wall time).
        rec.set_log_time_enabled(False)
        view = blueprint(trail, steps)
        # rerun reports a refused file (read-only folder, disk full) as a RuntimeError with the
        # system's words: one StorageError line naming the file (the CLI exits with status 1).
        try:
            with storage_errors(path or "the recording", "write"):
                if spawn:
                    rec.spawn(connect=False)
                    sinks = [rr.GrpcSink()] + ([rr.FileSink(str(path))] if path is not None else [])
                    rec.set_sinks(*sinks, default_blueprint=view)
                else:
                    rec.save(str(path), default_blueprint=view)
        except BaseException:
            if path is not None:
                with contextlib.suppress(OSError):
                    if os.path.getsize(path) == 0:
                        os.unlink(path)  # the empty file claimed above: nothing was recorded
            raise
        self._rec = rec
        if title is not None:
            rec.send_recording_name(title)
        self._log_static(title, dict(info or {}))

    # -- setup ------------------------------------------------------------------------------------
    def _log_static(self, title: str | None, info: dict[str, object]) -> None:
        rr, rec = self._rr, self._rec
        # rerun's 2-D views put y downwards; flip so that p increases upwards as in the paper.
        rec.log(
            PHASE_SPACE_PATH,
            rr.Transform3D(translation=[0.0, 1.0, 0.0], scale=[1.0, -1.0, 1.0]),
            static=True,
        )
        if self.color_by == "class":
            rec.log(
                PHASE_SPACE_PATH,
                rr.AnnotationContext([(cid, label, color) for cid, (label, color) in CLASSES.items()]),
                static=True,
            )
        else:
            lo, hi = self.ftle_range
            info.setdefault("colour", f"FTLE, viridis on a log scale from {lo:g} (dark) to {hi:g} (bright)")
        for entity, archetype in axes(rr):
            rec.log(entity, archetype, static=True)
        text = (f"# {title}\n\n" if title else "") + markdown_parameters(self.params, info)
        rec.log(PARAMETERS_PATH, rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN), static=True)
        for key, entity in SERIES_KEYS.items():
            rec.log(entity, rr.SeriesLines(names=SERIES_NAMES[key]), static=True)
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
            points = rr.Points2D(positions, class_ids=class_ids(ftle, acc, threshold), radii=radii)
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
            try:
                with storage_errors(self.path or "the recording", "write"):
                    self._rec.flush()
            except RuntimeError as exc:  # a spawned viewer that went away: the file is still whole
                if not self.spawned:
                    raise
                warnings.warn(f"the rerun viewer did not receive the recording: {exc}", RuntimeWarning,
                              stacklevel=2)  # fmt: skip
            self._rec.disconnect()

    def __enter__(self) -> PhaseSpaceRecording:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
