"""An archive as a ``pandas.DataFrame`` or an ``xarray.Dataset`` (the optional ``xarray`` extra).

Units and descriptions come from the file's ``units``/``long_name`` attributes (format v2) or,
for format v1 files that lack them, from :mod:`warpratchet.glossary`.
The file itself also opens directly: ``xarray.open_dataset(path, group="series",
engine="h5netcdf")`` (format v2). Both routes give the same dimension names (the names netCDF
readers give the file's dimension scales: ``step``, ``indices``, ``block_step``,
``block_indices``) and decode ``unix_time`` alike (``datetime64``, CF time units).
:func:`dataset` adds one derived variable to the snapshots, the unwrapped momentum
``p_unwrapped`` (:func:`unwrapped_momentum`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..history import HISTORY_FIELDS
from ..spec import attr_value
from ._format import SERIES_FIELDS, SNAPSHOT_FIELDS, describe

__all__ = ["attributes", "series_frame", "dataset", "unwrapped_momentum"]


def _need(module: str) -> Any:
    try:
        return __import__(module)
    except ImportError:
        raise ImportError(f"this export needs {module}: pip install 'warpratchet[xarray]'") from None


def attributes(arc, group: str, name: str) -> dict[str, str]:
    """``units`` and ``long_name`` of ``/group/name`` as stored (format v1: as documented)."""
    attrs = arc.h5[group][name].attrs
    if "units" in attrs and "long_name" in attrs:
        return {"units": str(attr_value(attrs["units"])), "long_name": str(attr_value(attrs["long_name"]))}
    units, long_name = describe(group, name)
    return {"units": units, "long_name": long_name}


def _history(arc):
    """The archive's :class:`~warpratchet.history.History` (ValueError for an archive without one)."""
    history = arc.history
    if history is None:
        raise ValueError(f"{arc.path} has no history (its features: {', '.join(arc.features) or 'none'})")
    return history


def _rows(arc, group: str) -> tuple[dict, tuple[str, ...]]:
    """The rows of ``series`` or ``history`` and their field names (``step`` first)."""
    if group == "series":
        return arc.series, SERIES_FIELDS
    if group == "history":
        return {k: np.asarray(v) for k, v in _history(arc).rows.items()}, HISTORY_FIELDS
    raise ValueError(f"group = {group!r} is not 'series' or 'history'")


def series_frame(arc, group: str = "series"):
    """``arc.series`` (or the history rows) as a DataFrame indexed by ``step``; ``frame.attrs`` holds
    units and long names."""
    pd = _need("pandas")
    series, fields = _rows(arc, group)
    frame = pd.DataFrame({name: series[name] for name in fields[1:]}, index=series["step"])
    frame.index.name = "step"
    described = {name: attributes(arc, group, name) for name in fields}
    frame.attrs = {
        "units": {name: d["units"] for name, d in described.items()},
        "long_name": {name: d["long_name"] for name, d in described.items()},
        "path": arc.path,
    }
    return frame


def unwrapped_momentum(p0: np.ndarray, steps: np.ndarray, p: np.ndarray, A: np.ndarray) -> np.ndarray:
    """The momentum ``p_n`` of snapshot points, not reduced mod 1: ``p0 + n A_n`` (Eq. An).

    ``p0`` ``(M,)`` is the points' initial momentum (``/initial/p0`` at ``/snapshots/indices``),
    ``steps`` ``(S,)``, ``p`` (mod 1) and ``A`` ``(S, M)`` the snapshots'. ``p0 + n A_n`` carries
    the rounding of ``A_n``; its whole part is exact once rounded against the stored ``p`` mod 1,
    so the result is ``round(p0 + n A_n - p) + p``, the stored fraction unchanged.
    """
    approx = p0[None, :] + steps[:, None].astype(np.float64) * A
    return np.round(approx - p) + p


def _dataset_attrs(arc) -> dict[str, Any]:
    """The Dataset's attributes: the file's CF global attributes (format 2.1) and the map's parameters."""
    skip = {"format", "format_version", "format_minor", "features", "text_crc32"}
    stored = {k: attr_value(v) for k, v in arc.h5.attrs.items() if k not in skip}
    return {**stored, "path": arc.path, **arc.params.as_dict()}


def dataset(arc, group: str = "series"):
    """``/series`` (dimension ``step``), ``/snapshots`` (``step``, ``indices``) or ``/history``
    (``step``; block gains on ``block_step``, ``block_indices``) as a Dataset, named and decoded as
    ``xarray.open_dataset(path, group=group, engine="h5netcdf")`` names and decodes the file."""
    xr = _need("xarray")
    attrs = _dataset_attrs(arc)
    if group == "series":
        series = arc.series
        coords = {"step": ("step", series["step"], attributes(arc, "series", "step"))}
        data = {name: ("step", series[name], attributes(arc, "series", name)) for name in SERIES_FIELDS[1:]}
        return xr.decode_cf(xr.Dataset(data, coords=coords, attrs=attrs))
    if group == "snapshots":
        snaps = arc.snapshots
        dims = ("step", "indices")
        coords = {
            "step": ("step", snaps.steps, attributes(arc, "snapshots", "step")),
            "indices": ("indices", snaps.indices, attributes(arc, "snapshots", "indices")),
        }
        data = {
            name: (dims, getattr(snaps, name), attributes(arc, "snapshots", name)) for name in SNAPSHOT_FIELDS
        }
        p0 = arc.initial["p0"][snaps.indices]
        units, long_name = describe("snapshots", "p_unwrapped")
        data["p_unwrapped"] = (
            dims,
            unwrapped_momentum(p0, snaps.steps, snaps.p, snaps.A),
            {"units": units, "long_name": long_name},
        )
        return xr.Dataset(data, coords=coords, attrs=attrs)
    if group == "history":
        history = _history(arc)
        rows, blocks = history.rows, history.block_rows
        coords = {
            "step": ("step", np.asarray(rows["step"]), attributes(arc, "history", "step")),
            "block_step": (
                "block_step",
                np.asarray(blocks["block_step"]),
                attributes(arc, "history", "block_step"),
            ),
            "block_indices": (
                "block_indices",
                np.asarray(history.block_indices),
                attributes(arc, "history", "block_indices"),
            ),
        }
        width = len(history.block_indices)
        data = {
            name: ("step", np.asarray(rows[name]), attributes(arc, "history", name))
            for name in HISTORY_FIELDS[1:]
        }
        for name in ("block_gain", "block_ftle"):
            values = np.asarray(blocks[name], dtype=np.float64).reshape(len(blocks["block_step"]), width)
            data[name] = (("block_step", "block_indices"), values, attributes(arc, "history", name))
        return xr.Dataset(data, coords=coords, attrs=attrs)
    raise ValueError(f"group = {group!r} is not 'series', 'snapshots' or 'history'")
