"""What an archive is: format and versions, names and units, and the whole layout built up front.

The one place that names the layout of ``docs/archive.md``: format and versions, groups,
datasets, their units and descriptions. Version 2 (this release) differs
from version 1 (warpratchet 0.1.0, still read) in:

* the file format: HDF5 1.10 object formats (readable by the HDF5 1.10 tools), not "latest";
* ``/settings``: RunSpec's names (``init``, not ``sampler``; a run-dependent default such as the
  threshold or a missing seed is an absent attribute, not NaN or -1);
* the live counters moved from ``/series/n_valid`` and ``/snapshots/n_valid`` to ``/progress``
  (``series_rows``, ``snapshot_rows``), joined by ``target_step``; ``/series`` and
  ``/snapshots`` hold only data, so netCDF readers see their dimensions and no phony ones;
* every dataset has ``units`` and ``long_name``; ``/series/step`` and ``/snapshots/step`` are
  HDF5 dimension scales attached to their groups' datasets, ``/snapshots/indices`` too;
* a closed archive holds exactly its valid rows (trimmed at close);
* ``/@features``: the optional groups present (:data:`KNOWN_FEATURES`).

Minor version 1 of version 2 (root attribute ``format_minor``; absent: 0) only adds what older
readers ignore: CF global attributes (``Conventions``, ``title``, ``history``, ``source``,
``references``) with the map's parameters and the theory's ``A_theory`` at the root and on
``/series``; string attributes as variable-length UTF-8 (h5py reads them as ``str``); the
netCDF dimensions ``point`` (``/initial``, ``/checkpoint``) and ``counter`` (the ``(1,)``
counters), so that no dataset has an unnamed dimension.

Minor version 2 names each snapshot point's ``A_n`` of Eq. (An) ``finite_time_acceleration``, as
the API does, apart from the ensemble's mean ``A`` of ``/series``; earlier files store it as
``/snapshots/A``, which readers map to the new name (:data:`FORMER_NAMES`, :func:`stored_name`).

Building an archive: :func:`settings_attrs` and :func:`read_settings` translate a run's
settings to and from the ``/settings`` attributes (RunSpec's names,
:meth:`warpratchet.spec.RunSpec.to_attrs`, plus the archive's own schedule and the kernel's
constants); :func:`create` builds every group and
dataset of ``docs/archive.md`` in a new file. The writer and the reader use the layout only
through this module.

Every dataset is chunked and carries the Fletcher-32 filter and ``units``/``long_name``
attributes; mutable scalars (the ``/progress`` counters, ``current``, a slot's ``step``) are
``(1,)`` datasets, because SWMR allows no new objects or attribute changes once a writer has
started. String attributes are variable-length UTF-8 (h5py reads them as ``str``); numbers stay
inside the (checksummed) object headers. The root carries CF global attributes
(:func:`global_attrs`), so that netCDF readers and the CF compliance checker see what the
archive holds without this package.
"""

from __future__ import annotations

import functools
import math
import platform
import zlib
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _dist_version
from typing import Any

import h5py
import numpy as np
from h5py import h5a, h5g, h5p, h5s, h5t

from .. import glossary, theory
from .._files import compact_links
from ..ensemble import RENORM_CHECK_EVERY, RENORM_THRESHOLD, STATE_FIELDS
from ..errors import FileFormatError, NonFiniteStateError  # NonFiniteStateError: re-exported
from ..paper import REFERENCE
from ..params import MapParams
from ..spec import LEGACY_NAMES, attr_value, check_setting

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "FORMAT_MINOR",
    "READABLE_VERSIONS",
    "SERIES_FIELDS",
    "INT_SERIES",
    "SNAPSHOT_FIELDS",
    "FORMER_NAMES",
    "stored_name",
    "SLOTS",
    "COUNTERS",
    "HISTORY_COUNTERS",
    "KNOWN_FEATURES",
    "describe",
    "ArchiveError",
    "ArchiveWarning",
    "NonFiniteStateError",
    "RUN_SETTINGS",
    "ARCHIVE_SETTINGS",
    "settings_attrs",
    "run_settings",
    "read_settings",
    "kernel_constants",
    "software_versions",
    "map_attrs",
    "global_attrs",
    "create",
    "seal",
    "TEXT_CHECKSUM",
    "text_checksum",
]


#: Format name, root attribute ``format``.
FORMAT = "warpratchet-archive"
#: Layout version written, root attribute ``format_version``.
FORMAT_VERSION = 2
#: Changes within version 2, root attribute ``format_minor`` (absent: 0; module docstring):
#: 1 adds what older readers ignore, 2 renames ``/snapshots/A`` (:data:`FORMER_NAMES`).
FORMAT_MINOR = 2
#: Layout versions this release reads (and resumes: a resumed version-1 archive is rebuilt as 2).
READABLE_VERSIONS = (1, 2)

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
SNAPSHOT_FIELDS = ("x", "p", "ftle", "finite_time_acceleration")
#: Datasets that files before minor version 2 store under another name, by group: the per-point
#: ``A_n`` of Eq. (An) was ``/snapshots/A``, the name of the ensemble's mean in ``/series``.
FORMER_NAMES = {"snapshots": {"finite_time_acceleration": "A"}}
#: The two checkpoint slots, ``/checkpoint/a`` and ``/checkpoint/b`` (``current`` = 0 or 1).
SLOTS = ("a", "b")

#: Where each live counter is, by format version: the number of valid series rows and snapshots
#: (the writer raises them after the rows are on disk) and the step the running session aims at.
COUNTERS = {
    1: {"series": "series/n_valid", "snapshots": "snapshots/n_valid"},
    2: {
        "series": "progress/series_rows",
        "snapshots": "progress/snapshot_rows",
        "target": "progress/target_step",
    },
}

#: The live counters of the optional ``/history`` group (feature ``history``): valid rows and
#: valid block records, raised after them like the others.
HISTORY_COUNTERS = {"rows": "progress/history_rows", "blocks": "progress/block_rows"}

#: Optional groups a later release may add without a new major version, as named in the root
#: attribute ``features`` (a comma-separated list, empty for none). A reader ignores groups it
#: does not know and reads a feature only when it is listed; a change that an older reader would
#: misread (a reinterpreted dataset) bumps ``format_version`` instead, a renamed dataset (which an
#: older reader cannot find, so does not misread) ``format_minor``, with :data:`FORMER_NAMES`.
KNOWN_FEATURES = {
    "history": "/history: log-spaced rows of A_n, its standard error, sigma, the chaotic fraction "
    "and variances, and block gains of a subsample",
    "transport": "/transport: momentum histograms",
}


def stored_name(group: h5py.Group, name: str) -> str:
    """The name under which the archive group ``group`` stores dataset ``name``: ``name``, or in
    a file written before it was named so, its :data:`FORMER_NAMES` entry."""
    former = FORMER_NAMES.get(group.name.lstrip("/"), {}).get(name)
    return former if former is not None and name not in group and former in group else name


def describe(group: str, name: str) -> tuple[str, str]:
    """``(units, long_name)`` of dataset ``name`` of ``group`` (``"initial"``, ``"checkpoint/a"``, ...).

    Worded in :mod:`warpratchet.glossary`, with the sweep files' columns.
    """
    if group.startswith("checkpoint/"):
        group = "checkpoint"  # both slots hold the same datasets
    return glossary.describe(group, name)


class ArchiveError(FileFormatError):
    """An archive that cannot be used: missing, truncated, corrupted, incompatible or in use."""


class ArchiveWarning(UserWarning):
    """Something was recovered, e.g. an older checkpoint because the newest one is damaged."""


#: The RunSpec settings an archive stores (``steps`` is progress, ``/progress/target_step``:
#: a resume moves it).
RUN_SETTINGS = (
    "K",
    "b1",
    "b2",
    "init",
    "points",
    "seed",
    "indicator",
    "threshold",
    "threshold_rule",
    "threads",
    "device",
    "knots",
    "values",
)
#: The archive's own settings besides ``chunk_steps`` (a RunSpec setting) and the kernel's.
ARCHIVE_SETTINGS = (
    "chunk_steps",
    "checkpoint_every",
    "checkpoint_seconds",
    "snapshot_every",
    "snapshot_points",
)

#: Initial-state fill values: a field equal to its fill everywhere is not written (costs no space).
FILL = {"x": 0.0, "q": 0.0, "winding": 0, "p0": 0.0, "dx": 1.0, "dp": 0.0, "log_stretch": 0.0}
#: Rows allocated at a time in ``/series`` and ``/snapshots`` (trimmed to the valid rows at close).
#: It is also the chunk of the 1-D row datasets, rewritten in place at every append: 256 rows of
#: 8 bytes and the 4-byte checksum fit one file page (``warpratchet._h5.PAGE_SIZE``), so a kill
#: cannot tear the rewrite; a chunk over a page would span two and could be torn again.
ROW_CHUNK = 256
STATE_CHUNK = 1 << 17  # 1 MiB of float64 per chunk
#: The numeric attribute (in the checksummed object header) that seals a group's string
#: attributes: their text lives in HDF5's global heap, which carries no checksum of its own.
TEXT_CHECKSUM = "text_crc32"


# -- /settings and /versions ------------------------------------------------------------------------
def settings_attrs(values: dict[str, Any]) -> dict[str, Any]:
    """The ``/settings`` attributes of ``values`` (keys :data:`RUN_SETTINGS` + :data:`ARCHIVE_SETTINGS`).

    RunSpec's settings are checked by RunSpec's own validators and stored as
    :meth:`RunSpec.to_attrs` stores them: a ``None`` (a run-dependent default, or no seed) is an
    absent attribute. An ensemble built from arrays has ``init = "user"``, which no sampler
    reproduces. The kernel's renormalisation constants are stored too, so that a resume can
    refuse a kernel that would not continue the run bit for bit.
    """
    out: dict[str, Any] = {}
    for name in RUN_SETTINGS + ARCHIVE_SETTINGS:
        value = values.get(name)
        if value is None:
            continue
        if name in RUN_SETTINGS + ("chunk_steps",) and not (name == "init" and value == "user"):
            value = check_setting(name, value)
        out[name] = value
    return {**out, **kernel_constants(), "dtype": "float64"}


def run_settings(
    ensemble: Any,
    *,
    threshold: float | None,
    threshold_rule: str = "strict",
    chunk_steps: int,
    checkpoint_every: int,
    checkpoint_seconds: float,
    snapshot_every: int,
    snapshot_points: int,
) -> dict[str, Any]:
    """The settings of a new archive of ``ensemble`` under RunSpec's names (:func:`read_settings`' form)."""
    return {
        **ensemble.params.as_dict(derived=False),
        "init": ensemble.init,
        "points": ensemble.points,
        "seed": ensemble.seed,
        "indicator": "ftle",
        "threshold": threshold,
        "threshold_rule": threshold_rule,
        "threads": ensemble.threads,
        "device": ensemble.device,
        "chunk_steps": chunk_steps,
        "checkpoint_every": checkpoint_every,
        "checkpoint_seconds": checkpoint_seconds,
        "snapshot_every": snapshot_every,
        "snapshot_points": snapshot_points,
    }


def read_settings(attrs: h5py.AttributeManager, version: int) -> dict[str, Any]:
    """``/settings`` as Python values under RunSpec's names, every setting present (``None``: absent).

    Version 1 wrote ``sampler`` for ``init``, -1 for no seed and NaN for the default threshold;
    all three read as version 2 stores them.
    """
    settings = {LEGACY_NAMES.get(k, k): attr_value(v) for k, v in attrs.items() if k != TEXT_CHECKSUM}
    if version == 1:
        if settings.get("seed", -1) < 0:
            settings["seed"] = None
        if isinstance(settings.get("threshold"), float) and math.isnan(settings["threshold"]):
            settings["threshold"] = None
        settings.setdefault("indicator", "ftle")
    settings.setdefault("threshold_rule", "strict")  # archives written before the rule existed
    for name in RUN_SETTINGS + ARCHIVE_SETTINGS:
        settings.setdefault(name, None)
    return settings


def kernel_constants() -> dict[str, Any]:
    """The running kernel's renormalisation constants, as stored in ``/settings``."""
    return {"renorm_threshold": RENORM_THRESHOLD, "renorm_check_every": RENORM_CHECK_EVERY}


@functools.cache
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


# -- what a reader without warpratchet sees first -------------------------------------------------
def map_attrs(params: MapParams) -> dict[str, float]:
    """``K``, ``b1``, ``b2`` and, where a closed form holds (K = 3), ``A_theory`` of Eqs. (Aa)/(Ab).

    The root and ``/series`` carry them, so that a series read on its own keeps its context.
    """
    out = dict(params.as_dict(derived=False))
    a_theory = theory.summary(params)["A"]
    return out if a_theory is None else {**out, "A_theory": float(a_theory)}


def global_attrs(params: MapParams, versions: dict[str, str], created: str) -> dict[str, Any]:
    """The root's CF-1.8 global attributes (Sec. 2.6 of the conventions) and :func:`map_attrs`."""
    version = versions.get("warpratchet", "unknown")
    closed_form = (
        "A_theory is A of Eqs. (Aa)/(Ab) at these parameters"
        if params.K == 3.0
        else "no A_theory: the paper's closed forms for A hold at K = 3 only"
    )
    return {
        "Conventions": "CF-1.8",
        "title": (
            f"Weak-chaos ratchet accelerator: ensemble of the map at K = {params.K}, "
            f"b1 = {params.b1}, b2 = {params.b2}"
        ),
        "history": f"{created} created by warpratchet {version}",
        "source": f"warpratchet {version}: NVIDIA Warp {versions.get('warp', 'unknown')} ensemble "
        "of the map Eq. (cpem) with the force of Eq. (fx) and its tangent map",
        "references": REFERENCE,
        "comment": "momenta and positions in units of the map's period, rates per iteration; "
        f"{closed_form}; /series holds A_n of Eq. (An) over the chaotic points with its standard "
        "error; the layout is docs/archive.md of warpratchet",
        **map_attrs(params),
    }


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
    target_step: int = -1,
    history: Any = None,
) -> None:
    """Create the whole layout of ``docs/archive.md`` in ``f`` (SWMR allows no new objects later).

    ``settings`` are the settings under RunSpec's names (:func:`read_settings`' form; stored
    with :func:`settings_attrs`), ``initial`` the state at ``initial_step`` (keys
    ``STATE_FIELDS``), ``indices`` the snapshot subsample ``(M,)``. Series and snapshots start
    empty, both checkpoint slots unused. With a ``history`` (a
    :class:`~warpratchet.history.History` whose block subsample is chosen) the optional group
    ``/history`` is created too, empty, and listed in ``/@features``.
    """
    n = int(settings["points"])
    root = {"format": FORMAT, "format_version": FORMAT_VERSION, "format_minor": FORMAT_MINOR}
    _set_attrs(f, {**root, "created": created, **global_attrs(params, versions, created)})
    features = ["history"] if history is not None else []
    _set_attrs(f, {"features": ",".join(features)})  # names.KNOWN_FEATURES
    _set_attrs(_group(f, "params"), params.as_dict())
    _set_attrs(_group(f, "settings"), settings_attrs(settings))
    _set_attrs(_group(f, "versions"), versions)
    for obj in (f, f["settings"], f["versions"]):  # the string attributes readers act on
        seal(obj)

    g = _group(f, "initial")
    _set_attrs(g, {"step": int(initial_step)})
    point = _dimension(g, "point", n)
    for name in STATE_FIELDS:
        ds = _state_dataset(g, name, n, FILL[name])
        ds.dims[0].attach_scale(point)
        values = np.asarray(initial[name])
        if np.any(values != FILL[name]):  # a uniform field stays a fill value, no storage
            ds.write_direct(np.ascontiguousarray(values, dtype=ds.dtype))

    g = _group(f, "series")
    _set_attrs(g, map_attrs(params))
    _step_rows(g, SERIES_FIELDS, INT_SERIES)
    _sampled_rows(_group(f, "snapshots"), ("indices", "point"), ("step", *SNAPSHOT_FIELDS), indices)

    g = _group(f, "progress")
    counter = _dimension(g, "counter", 1)
    for key, path in COUNTERS[FORMAT_VERSION].items():
        _counter(g, path.split("/")[1], target_step if key == "target" else 0, counter)

    g = _group(f, "checkpoint")
    counter, point = _dimension(g, "counter", 1), _dimension(g, "point", n)
    _counter(g, "current", -1, counter)
    for slot in SLOTS:
        s = _group(g, slot)
        _counter(s, "step", -1, counter)
        for name in STATE_FIELDS:
            _state_dataset(s, name, n).dims[0].attach_scale(point)

    if history is not None:
        _history_group(f, history)


def text_checksum(attrs: dict[str, Any]) -> int:
    """CRC-32 of the string attributes in ``attrs``: ``key=value`` lines sorted by key."""
    lines = sorted(f"{k}={v}" for k, v in attrs.items() if isinstance(v, str) and k != TEXT_CHECKSUM)
    return zlib.crc32("\n".join(lines).encode())


def seal(obj: h5py.Group) -> None:
    """Store the :data:`TEXT_CHECKSUM` of the string attributes of ``obj`` (after their last
    change)."""
    _set_attrs(obj, {TEXT_CHECKSUM: text_checksum(dict(obj.attrs.items()))})


def _history_group(f: h5py.File, history: Any) -> None:
    """``/history`` (feature ``history``) for a :class:`~warpratchet.history.History`, and its counters.

    Rows (dimension ``step``) and block records (dimensions ``block_step``, ``block_point``)
    start empty; the history's settings (rows per decade, blocks, block subsample size) are
    attributes of the group; the subsample's indices are ``block_indices``.
    """
    from ..history import BLOCK_FIELDS, HISTORY_FIELDS, INT_FIELDS

    indices = np.asarray(history.block_indices, dtype=np.int64)
    g = _group(f, "history")
    attrs = {"per_decade": history.per_decade, "blocks": history.blocks, "block_points": int(indices.size)}
    _set_attrs(g, attrs)
    _step_rows(g, HISTORY_FIELDS, INT_FIELDS)
    _sampled_rows(g, ("block_indices", "block_point"), BLOCK_FIELDS, indices)
    progress = f["progress"]
    for path in HISTORY_COUNTERS.values():
        _counter(progress, path.split("/")[1], 0, progress["counter"])


def _step_rows(group: h5py.Group, names: tuple[str, ...], int_names: tuple[str, ...]) -> None:
    """Empty rows ``names`` of ``group``: the first (int64, the step of each row) is their dimension
    scale, the others are int64 if in ``int_names``, float64 otherwise."""
    scale = _rows(group, names[0], np.int64)
    scale.make_scale(names[0])
    for name in names[1:]:
        _rows(group, name, np.int64 if name in int_names else np.float64).dims[0].attach_scale(scale)


def _sampled_rows(
    group: h5py.Group, points: tuple[str, str], names: tuple[str, ...], indices: np.ndarray
) -> None:
    """Empty rows of a fixed subsample of points: ``names[0]`` the step of each row, the others
    float64 ``(rows, M)`` on the steps and on the ``M`` points ``indices``, stored as
    ``points = (name, dimension)``. Both axes are dimension scales, so that netCDF readers name
    them instead of inventing phony ones."""
    width = max(1, min(int(indices.size), STATE_CHUNK))
    kept = _dataset(group, points[0], data=indices.astype(np.int64), maxshape=(None,), chunks=(width,))
    kept.make_scale(points[1])
    scale = _rows(group, names[0], np.int64)
    scale.make_scale(names[0])
    for name in names[1:]:
        ds = _rows(group, name, np.float64, int(indices.size))
        ds.dims[0].attach_scale(scale)
        ds.dims[1].attach_scale(kept)


def _dataset(group: h5py.Group, name: str, **kw: Any) -> h5py.Dataset:
    """A chunked, checksummed dataset with the ``units`` and ``long_name`` of :func:`describe`."""
    ds = group.create_dataset(name, fletcher32=True, **kw)
    units, long_name = describe(group.name.lstrip("/"), name)
    _set_attrs(ds, {"units": units, "long_name": long_name})
    return ds


def _state_dataset(group: h5py.Group, name: str, n: int, fill: float | int | None = None) -> h5py.Dataset:
    dtype = np.int64 if name == "winding" else np.float64
    kw = {} if fill is None else {"fillvalue": dtype(fill)}
    return _dataset(group, name, shape=(n,), dtype=dtype, chunks=(min(n, STATE_CHUNK),), **kw)


def _counter(group: h5py.Group, name: str, value: int, dimension: h5py.Dataset) -> None:
    # Mutable scalars are (1,) chunked datasets: checksummed, and writable under SWMR.
    _dataset(group, name, data=np.array([value], np.int64), chunks=(1,)).dims[0].attach_scale(dimension)


#: netCDF-4's mark of a dimension that is not a variable (a dimension scale's ``NAME``).
_NETCDF_DIMENSION = "This is a netCDF dimension but not a netCDF variable."


def _dimension(group: h5py.Group, name: str, size: int) -> h5py.Dataset:
    """A named dimension of ``size`` without values, as netCDF-4 writes one: an HDF5 dimension
    scale whose chunks are never written (no storage), so that netCDF readers (ncdump, xarray,
    netCDF4) name the axis ``name`` instead of inventing a ``phony_dim``."""
    ds = group.create_dataset(name, shape=(size,), dtype=np.float32, chunks=(min(size, STATE_CHUNK),))
    ds.make_scale(f"{_NETCDF_DIMENSION}{size:10d}")
    return ds


def _rows(group: h5py.Group, name: str, dtype: Any, width: int | None = None) -> h5py.Dataset:
    """An empty, growable dataset of rows (``(0,)``, or ``(0, width)`` for per-point rows)."""
    if width is None:
        return _dataset(group, name, shape=(0,), maxshape=(None,), chunks=(ROW_CHUNK,), dtype=dtype)
    chunks = (1, max(1, min(width, STATE_CHUNK)))
    return _dataset(group, name, shape=(0, width), maxshape=(None, None), chunks=chunks, dtype=dtype)


def _group(parent: h5py.Group, name: str) -> h5py.Group:
    """A group whose links and attributes all live in its (checksummed) object header.

    Past 8 links or attributes HDF5 moves them to "dense" storage, a fractal heap whose blocks
    carry no checksum: a flipped bit there changed a link and crashed HDF5 while listing the group.
    """
    gcpl = h5p.create(h5p.GROUP_CREATE)
    compact_links(gcpl)
    gcpl.set_attr_phase_change(64, 32)
    h5g.create(parent.id, name.encode(), gcpl=gcpl)
    return parent[name]


def _set_attrs(obj: h5py.HLObject, values: dict[str, Any]) -> None:
    """Attributes: numbers in the checksummed header, strings as variable-length UTF-8, the type
    that h5py reads as ``str`` and netCDF as a string (its text lives in HDF5's global heap,
    which carries no checksum: a damaged letter shows in a label, and stored settings such as
    ``init`` are checked against their allowed values when read).

    Written with HDF5's low-level calls: a layout has ~120 attributes, and h5py's ``attrs[key] =``
    for each of them would be a large share of the time it takes to create an archive.
    """
    scalar = h5s.create(h5s.SCALAR)
    for key, value in values.items():
        data = np.array(value, dtype=_UTF8 if isinstance(value, str) else None)
        if data.shape != () or data.dtype.kind not in "biufO":
            obj.attrs[key] = value  # anything else the usual way
            continue
        if h5a.exists(obj.id, key.encode()):
            h5a.delete(obj.id, key.encode())
        # The file's type and the memory's (for a string: the pointer h5py converts from).
        file_type, memory_type = h5t.py_create(data.dtype, logical=True), h5t.py_create(data.dtype)
        h5a.create(obj.id, key.encode(), file_type, scalar).write(data, mtype=memory_type)


_UTF8 = h5py.string_dtype("utf-8")
