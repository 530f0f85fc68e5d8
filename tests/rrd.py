"""Reading rerun recordings back for the tests: frames, series and ``rerun rrd verify``."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

CLOUD = "/phase_space/cloud"


# -- reading recordings back ---------------------------------------------------------------------
def read_rrd(path: Path) -> dict[str, dict[object, dict[str, object]]]:
    """``entity -> {step (None if static): {component column: value}}`` of a recording."""
    from rerun.chunk import RrdReader

    out: dict[str, dict[object, dict[str, object]]] = {}
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        names = [n for n in batch.schema.names if n not in ("rerun.controls.RowId", "step", "log_time")]
        steps = batch.column("step").to_pylist() if "step" in batch.schema.names else [None] * batch.num_rows
        columns = {n: batch.column(n).to_pylist() for n in names}
        rows = out.setdefault(chunk.entity_path, {})
        for i, step in enumerate(steps):
            rows.setdefault(step, {}).update({n: columns[n][i] for n in names})
    return out


def cloud_frames(rrd: dict) -> dict[int, dict[str, np.ndarray]]:
    """Frames of the cloud: ``step -> {"positions": (m, 2), "colors" or "class_ids": (m,)}``."""
    frames = {}
    for step, row in rrd[CLOUD].items():
        frame = {"positions": np.array(row["Points2D:positions"], dtype=np.float32).reshape(-1, 2)}
        for key in ("colors", "class_ids"):
            if row.get(f"Points2D:{key}") is not None:
                frame[key] = np.array(row[f"Points2D:{key}"], dtype=np.int64)
        frames[step] = frame
    return frames


def series(rrd: dict, entity: str) -> tuple[np.ndarray, np.ndarray]:
    """``(steps, values)`` of a scalar series."""
    rows = sorted((s, r["Scalars:scalars"][0]) for s, r in rrd["/" + entity].items() if s is not None)
    return np.array([s for s, _ in rows]), np.array([v for _, v in rows], dtype=np.float64)


def packed(rgb: np.ndarray) -> np.ndarray:
    """sRGB rows as rerun's packed 0xRRGGBBAA colours (opaque)."""
    rgb = rgb.astype(np.int64)
    return (rgb[:, 0] << 24) | (rgb[:, 1] << 16) | (rgb[:, 2] << 8) | 255


def verify(path: Path) -> None:
    """``rerun rrd verify`` (the CLI bundled with rerun-sdk) must accept the file."""
    done = subprocess.run(
        [sys.executable, "-m", "rerun_cli", "rrd", "verify", str(path)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stdout + done.stderr
