"""``python -m viz scenes -o DIR``: the paper's phase-space pictures as rerun recordings.

Each scene starts a cloud of points uniform in the hyperbolic strip B of Eq. (B) and records it
as it spreads (one ``.rrd`` per scene, layout of :mod:`warpratchet.recording`):

* ``fig1a``, ``fig1b``, ``fig1c`` -- Fig. 1: ``b1 = 0.05``, ``b2 = 0.02`` and the three rotation
  angles of Eq. (eig), ``alpha = 2 pi/3`` (K = 3), ``6 pi/5`` (K = 2 - 2 cos(6 pi/5) ~ 3.618) and
  ``pi (sqrt 5 - 1)/2`` (K ~ 2.7247). The cloud fills the global chaotic region C of Eq. (C);
  the accelerator-mode islands L and R (Sec. III C) and the normal island stay empty.
* ``fig2a``, ``fig2b``, ``fig2c`` -- Fig. 2: the same K with ``b1 = b2 = 1e-7``, close to the
  elliptic sawtooth map of Eq. (saw). Chaos is almost absent (pseudochaos); the cloud runs
  along the iterates of the discontinuity line, and the default view keeps every frame up to
  the time cursor (a trail) so that their union, the paper's picture, builds up.
* ``fig4`` -- Fig. 4: K = 3, ``b1 = 0.226``, ``b2 = 0.02`` (domain R of Fig. 3, Eq. cb): only
  the right island exists.

Frames: every step at first (the spreading is fast, the Lyapunov exponent is of order 0.1-1 per
step for Figs. 1 and 4), then geometrically spaced (ratio 1.15) up to ``--steps``; the trail
scenes of Fig. 2 record every step.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from warpratchet import Ensemble, MapParams, paper
from warpratchet.recording import (
    DEFAULT_MAX_BYTES,
    RecordingSink,
    check_new_file,
    points_within_budget,
    require_rerun,
)

from .command import command_name, run

__all__ = ["Scene", "SCENES", "frame_steps", "record_scene", "main"]


@dataclass(frozen=True)
class Scene:
    """One of the paper's phase-space pictures.

    Attributes
    ----------
    name : str
        File stem, e.g. ``"fig1a"``.
    title : str
        Recording name.
    params : MapParams
        The map.
    trail : bool
        Record every step and show all frames up to the cursor (Fig. 2).
    points, steps : int
        Default ensemble size and number of iterations.
    """

    name: str
    title: str
    params: MapParams
    trail: bool
    points: int
    steps: int


def _scenes() -> dict[str, Scene]:
    scenes = {}
    # Figs. 1 and 2 share their three rotation angles; Fig. 2's cloud leaves a trail.
    for figure, maps, widths, trail, points, steps in (
        ("1", paper.FIG1, f"b1 = {paper.FIG1_WIDTHS[0]}, b2 = {paper.FIG1_WIDTHS[1]}", False, 50_000, 2_000),
        ("2", paper.FIG2, f"b1 = b2 = {paper.FIG2_WIDTHS[0]:g} (near the ESM)", True, 20_000, 200),
    ):
        for rotation, params in zip(paper.ROTATIONS, maps, strict=True):
            name = f"fig{figure}{rotation.panel}"
            title = f"Fig. {figure}({rotation.panel}): alpha = {rotation.text}, K = {params.K:.6g}, {widths}"
            scenes[name] = Scene(name, title, params, trail=trail, points=points, steps=steps)
    p = paper.FIG4
    scenes["fig4"] = Scene(
        "fig4",
        f"Fig. 4: K = {p.K:g}, b1 = {p.b1}, b2 = {p.b2} (only the R island exists)",
        p,
        trail=False,
        points=50_000,
        steps=2_000,
    )
    return scenes


SCENES: dict[str, Scene] = _scenes()


def frame_steps(steps: int, every_step_until: int = 16, ratio: float = 1.15) -> np.ndarray:
    """Steps of the frames: ``0, 1, ..., every_step_until``, then geometric, always ending at ``steps``.

    Returns
    -------
    ndarray, shape (F,), int64
        Strictly increasing, from 0 to ``steps``.
    """
    head = np.arange(min(every_step_until, steps) + 1)
    tail = []
    s = float(every_step_until)
    while s < steps:
        s *= ratio
        tail.append(min(round(s), steps))
    return np.unique(np.concatenate([head, np.asarray(tail, dtype=np.int64), [steps]])).astype(np.int64)


def record_scene(
    scene: Scene,
    path: str | Path,
    *,
    points: int | None = None,
    steps: int | None = None,
    seed: int = 0,
    color_by: str = "ftle",
    spawn: bool = False,
    max_bytes: int = DEFAULT_MAX_BYTES,
) -> RecordingSink:
    """Run ``scene`` from the strip B and record it to ``path``; returns the (closed) sink.

    Every frame draws the same subsample of the ensemble, as many points as let all frames fit
    in ``max_bytes`` (:func:`warpratchet.recording.points_within_budget`).
    """
    points = scene.points if points is None else points
    steps = scene.steps if steps is None else steps
    schedule = np.arange(steps + 1) if scene.trail else frame_steps(steps)
    ensemble = Ensemble.sample(scene.params, points, "strip", seed)
    drawn = points_within_budget(len(schedule), points, points, max_bytes)
    sink = RecordingSink(
        path,
        spawn=spawn,
        max_points=drawn,
        max_bytes=max_bytes,
        steps=steps,
        color_by=color_by,
        seed=seed,
        trail=scene.trail,
        title=scene.title,
        info={
            "scene": scene.name,
            "frames": f"{len(schedule)} (steps 0 to {steps}), {drawn} of the {points} points each",
        },
    )
    try:
        sink.log_frame(ensemble)  # step 0: the strip B
        for target in schedule[1:]:
            ensemble.run(int(target) - ensemble.step)
            sink.log_frame(ensemble)
    finally:
        sink.close()
    return sink


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    """The options of ``python -m viz scenes``."""
    parser = argparse.ArgumentParser(
        prog=command_name("scenes") if prog is None else prog, description=__doc__.splitlines()[0]
    )
    parser.add_argument("-o", "--out-dir", default=None, help="folder for NAME.rrd (created if missing)")
    parser.add_argument(
        "--only", nargs="+", metavar="NAME", help=f"scenes to record (default all: {', '.join(SCENES)})"
    )
    parser.add_argument("--list", action="store_true", help="list the scenes and exit")
    parser.add_argument(
        "--points", type=int, default=None, help="ensemble size (default per scene: 50000, Fig. 2: 20000)"
    )
    parser.add_argument(
        "--steps", type=int, default=None, help="iterations (default per scene: 2000, Fig. 2: 200)"
    )
    parser.add_argument("--seed", type=int, default=0, help="NumPy seed of the strip ensemble (default 0)")
    parser.add_argument(
        "--color", choices=["ftle", "class"], default="ftle", help="colour by FTLE or by class"
    )
    parser.add_argument("--spawn", action="store_true", help="also stream each scene to a spawned viewer")
    parser.add_argument(
        "--max-mb",
        type=float,
        default=DEFAULT_MAX_BYTES / 1e6,
        help="size budget of each recording in MB: fewer points per frame to stay below it (default 10)",
    )
    return parser


def _record(args: argparse.Namespace) -> int:
    if args.list:
        for scene in SCENES.values():
            print(f"{scene.name:6s} {scene.title}")
        return 0
    if args.out_dir is None:
        raise ValueError("give -o DIR (the folder for the .rrd files), or --list")
    names = args.only or list(SCENES)
    unknown = [n for n in names if n not in SCENES]
    if unknown:
        raise ValueError(f"unknown scene {unknown[0]!r}; choose from {', '.join(SCENES)}")
    for flag, value in (("--points", args.points), ("--steps", args.steps)):
        if value is not None and value < 1:
            raise ValueError(f"{flag} = {value} is outside the allowed range >= 1")
    if args.seed < 0:
        raise ValueError(f"--seed = {args.seed} is outside the allowed range >= 0")
    if not 0 < args.max_mb < 1e6:
        raise ValueError(f"--max-mb = {args.max_mb} is outside the allowed range 0 < MB < 1e6")
    require_rerun()
    folder = Path(args.out_dir)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {name: check_new_file(folder / f"{name}.rrd") for name in names}  # all before any work
    for name in names:
        start = time.perf_counter()
        sink = record_scene(
            SCENES[name],
            paths[name],
            points=args.points,
            steps=args.steps,
            seed=args.seed,
            color_by=args.color,
            spawn=args.spawn,
            max_bytes=int(args.max_mb * 1e6),
        )
        print(f"wrote {paths[name]}: {len(sink.frames)} frames in {time.perf_counter() - start:.1f} s")
    return 0


def main(argv: list[str] | None = None, prog: str | None = None) -> int:
    """Entry point; returns the exit status (2 with one line on stderr for bad input, 130 after Ctrl-C)."""
    kept = "the scene being recorded holds the frames written so far"
    return run(build_parser(prog), argv, _record, interrupted=kept)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
