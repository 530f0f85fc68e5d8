"""What an archive contains: format name and version, every group, dataset and attribute.

The one place that names the layout of ``docs/archive.md`` (format ``warpratchet-archive``,
version :data:`FORMAT_VERSION`): :func:`create` builds it in a new file, :func:`settings_attrs`
and :func:`read_settings` translate the run's settings to and from the ``/settings``
attributes, :func:`software_versions` fills ``/versions``. The writer and the reader use these
names only through this module.

Every dataset is chunked and carries the Fletcher-32 filter; mutable scalars (``n_valid``,
``current``, a slot's ``step``) are ``(1,)`` datasets, because SWMR allows no new objects or
attribute changes once a writer has started. Strings are fixed-length attributes, stored inside
the (checksummed) object headers.
"""

from __future__ import annotations

import math
import platform
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _dist_version
from typing import Any

import h5py
import numpy as np
from h5py import h5g, h5p

from ..ensemble import RENORM_CHECK_EVERY, RENORM_THRESHOLD, STATE_FIELDS
from ..errors import FileFormatError
from ..params import MapParams

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "SERIES_FIELDS",
    "SNAPSHOT_FIELDS",
    "SLOTS",
    "ArchiveError",
    "ArchiveWarning",
    "settings_attrs",
    "read_settings",
    "kernel_constants",
    "software_versions",
    "attr",
    "create",
]

#: Format name, root attribute ``format``.
FORMAT = "warpratchet-archive"
#: Layout version, root attribute ``format_version``; readers refuse any other.
FORMAT_VERSION = 1

#: Columns of ``/series`` (one row per chunk); ``step`` and ``chaotic_points`` are int64.
SERIES_FIELDS = (
    "step",
    "A",
    "A_stderr",
    "lyapunov",
    "lyapunov_std",
    "lyapunov_min",
    "chaotic_fraction",
    "chaotic_points",
    "threshold",
    "wall_time",
    "unix_time",
)
INT_SERIES = ("step", "chaotic_points")
#: Per-point arrays of ``/snapshots``, each ``(S, M)``.
SNAPSHOT_FIELDS = ("x", "p", "ftle", "A")
#: The two checkpoint slots, ``/checkpoint/a`` and ``/checkpoint/b`` (``current`` = 0 or 1).
SLOTS = ("a", "b")

#: Initial-state fill values: a field equal to its fill everywhere is not written (costs no space).
FILL = {"x": 0.0, "q": 0.0, "winding": 0, "p0": 0.0, "dx": 1.0, "dp": 0.0, "log_stretch": 0.0}
#: Rows allocated at a time in ``/series`` and ``/snapshots``.
ROW_CHUNK = 256
STATE_CHUNK = 1 << 17  # 1 MiB of float64 per chunk


class ArchiveError(FileFormatError):
    """An archive that cannot be used: missing, truncated, corrupted, incompatible or in use."""


class ArchiveWarning(UserWarning):
    """Something was recovered, e.g. an older checkpoint because the newest one is damaged."""


# -- /settings and /versions ------------------------------------------------------------------------
def settings_attrs(
    *,
    points: int,
    sampler: str,
    seed: int | None,
    threads: int,
    device: str,
    chunk_steps: int,
    checkpoint_every: int,
    snapshot_every: int,
    snapshot_points: int,
    threshold: float | None,
) -> dict[str, Any]:
    """The ``/settings`` attributes of a new archive (no seed: -1; default threshold: NaN).

    The kernel's renormalisation constants are stored too, so that :mod:`.resume` can refuse a
    kernel that would not continue the run bit for bit.
    """
    return {
        "points": points,
        "sampler": sampler,
        "seed": -1 if seed is None else int(seed),
        "threads": threads,
        "device": device,
        "chunk_steps": chunk_steps,
        "checkpoint_every": checkpoint_every,
        "snapshot_every": snapshot_every,
        "snapshot_points": snapshot_points,
        "threshold": math.nan if threshold is None else float(threshold),
        **kernel_constants(),
        "dtype": "float64",
    }


def kernel_constants() -> dict[str, Any]:
    """The running kernel's renormalisation constants, as stored in ``/settings``."""
    return {"renorm_threshold": RENORM_THRESHOLD, "renorm_check_every": RENORM_CHECK_EVERY}


def read_settings(attrs: h5py.AttributeManager) -> dict[str, Any]:
    """``/settings`` as Python values, with the stored markers decoded (seed -1 and threshold NaN
    become None); the inverse of :func:`settings_attrs`."""
    settings = {k: attr(v) for k, v in attrs.items()}
    settings["seed"] = None if settings.get("seed", -1) < 0 else settings["seed"]
    if isinstance(settings.get("threshold"), float) and math.isnan(settings["threshold"]):
        settings["threshold"] = None
    return settings


def software_versions() -> dict[str, str]:
    """The ``/versions`` attributes: the software of the process creating the archive."""

    def dist(name: str) -> str:
        try:
            return _dist_version(name)
        except PackageNotFoundError:  # pragma: no cover - source tree
            return "unknown"

    import warp

    return {
        "warpratchet": dist("warpratchet"),
        "warp": str(getattr(warp.config, "version", dist("warp-lang"))),
        "numpy": np.__version__,
        "h5py": h5py.__version__,
        "hdf5": h5py.version.hdf5_version,
        "python": platform.python_version(),
    }


def attr(value: Any) -> Any:
    """A Python/NumPy value as read from an HDF5 attribute (bytes -> str, 0-d -> scalar)."""
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value[()]
    if isinstance(value, np.generic):
        return value.item()
    return value


# -- the whole layout, created up front -----------------------------------------------------------
def create(
    f: h5py.File,
    *,
    params: MapParams,
    settings: dict[str, Any],
    versions: dict[str, str],
    created: str,
    initial: dict[str, np.ndarray],
    initial_step: int,
    indices: np.ndarray,
) -> None:
    """Create the whole layout of ``docs/archive.md`` in ``f`` (SWMR allows no new objects later).

    ``settings`` are the ``/settings`` attributes (:func:`settings_attrs`), ``initial`` the state
    at ``initial_step`` (keys ``STATE_FIELDS``), ``indices`` the snapshot subsample ``(M,)``.
    Series and snapshots start empty, both checkpoint slots unused.
    """
    n = int(settings["points"])
    m = int(indices.size)
    _set_attrs(f, {"format": FORMAT, "format_version": FORMAT_VERSION, "created": created})
    _set_attrs(_group(f, "params"), params.as_dict())
    _set_attrs(_group(f, "settings"), settings)
    _set_attrs(_group(f, "versions"), versions)

    def state_dataset(group: h5py.Group, name: str, fill: float | int | None = None) -> h5py.Dataset:
        dtype = np.int64 if name == "winding" else np.float64
        kw = {} if fill is None else {"fillvalue": dtype(fill)}
        return group.create_dataset(
            name, shape=(n,), dtype=dtype, chunks=(min(n, STATE_CHUNK),), fletcher32=True, **kw
        )

    def counter(group: h5py.Group, name: str, value: int) -> None:
        # Mutable scalars are (1,) chunked datasets: checksummed, and writable under SWMR.
        group.create_dataset(name, data=np.array([value], np.int64), chunks=(1,), fletcher32=True)

    g = _group(f, "initial")
    _set_attrs(g, {"step": int(initial_step)})
    for name in STATE_FIELDS:
        ds = state_dataset(g, name, FILL[name])
        values = np.asarray(initial[name])
        if np.any(values != FILL[name]):  # a uniform field stays a fill value, no storage
            ds.write_direct(np.ascontiguousarray(values, dtype=ds.dtype))

    g = _group(f, "series")
    for name in SERIES_FIELDS:
        g.create_dataset(
            name,
            shape=(0,),
            maxshape=(None,),
            chunks=(ROW_CHUNK,),
            dtype=np.int64 if name in INT_SERIES else np.float64,
            fletcher32=True,
        )
    counter(g, "n_valid", 0)

    g = _group(f, "snapshots")
    g.create_dataset(
        "indices",
        data=indices.astype(np.int64),
        maxshape=(None,),
        chunks=(max(1, min(m, STATE_CHUNK)),),
        fletcher32=True,
    )
    g.create_dataset(
        "step", shape=(0,), maxshape=(None,), chunks=(ROW_CHUNK,), dtype=np.int64, fletcher32=True
    )
    for name in SNAPSHOT_FIELDS:
        g.create_dataset(
            name,
            shape=(0, m),
            maxshape=(None, None),
            chunks=(1, max(1, min(m, STATE_CHUNK))),
            dtype=np.float64,
            fletcher32=True,
        )
    counter(g, "n_valid", 0)

    g = _group(f, "checkpoint")
    counter(g, "current", -1)
    for slot in SLOTS:
        s = _group(g, slot)
        counter(s, "step", -1)
        for name in STATE_FIELDS:
            state_dataset(s, name)


def _group(parent: h5py.Group, name: str) -> h5py.Group:
    """A group whose attributes all live in its (checksummed) object header, not in dense storage."""
    gcpl = h5p.create(h5p.GROUP_CREATE)
    gcpl.set_attr_phase_change(64, 32)
    h5g.create(parent.id, name.encode(), gcpl=gcpl)
    return parent[name]


def _set_attrs(obj: h5py.HLObject, values: dict[str, Any]) -> None:
    """Attributes, strings as fixed-length UTF-8 (stored in the checksummed header, unlike the
    variable-length strings h5py writes by default, which live in an unchecked global heap)."""
    for key, value in values.items():
        obj.attrs[key] = np.bytes_(value.encode()) if isinstance(value, str) else value
