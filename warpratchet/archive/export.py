"""An archive as a ``pandas.DataFrame`` or an ``xarray.Dataset`` (the optional ``xarray`` extra).

Units and descriptions come from the file's ``units``/``long_name`` attributes (format v2) or,
for format v1 files that lack them, from :data:`~warpratchet.archive.names.DESCRIPTIONS`.
The file itself also opens directly: ``xarray.open_dataset(path, group="series",
engine="h5netcdf")`` (format v2).
"""

from __future__ import annotations

from typing import Any

from ..spec import attr_value
from .names import SERIES_FIELDS, SNAPSHOT_FIELDS, describe

__all__ = ["attributes", "series_frame", "dataset"]


def _need(module: str) -> Any:
    try:
        return __import__(module)
    except ImportError:
        raise ImportError(f"this export needs {module}: pip install 'warpratchet[xarray]'") from None


def attributes(arc, group: str, name: str) -> dict[str, str]:
    """``units`` and ``long_name`` of ``/group/name`` as stored (format v1: as documented)."""
    attrs = arc._file[group][name].attrs
    if "units" in attrs and "long_name" in attrs:
        return {"units": str(attr_value(attrs["units"])), "long_name": str(attr_value(attrs["long_name"]))}
    units, long_name = describe(group, name)
    return {"units": units, "long_name": long_name}


def series_frame(arc):
    """``arc.series`` as a DataFrame indexed by ``step``; ``frame.attrs`` holds units and long names."""
    pd = _need("pandas")
    series = arc.series
    frame = pd.DataFrame({name: series[name] for name in SERIES_FIELDS[1:]}, index=series["step"])
    frame.index.name = "step"
    described = {name: attributes(arc, "series", name) for name in SERIES_FIELDS}
    frame.attrs = {
        "units": {name: d["units"] for name, d in described.items()},
        "long_name": {name: d["long_name"] for name, d in described.items()},
        "path": arc.path,
    }
    return frame


def dataset(arc, group: str = "series"):
    """``/series`` (dimension ``step``) or ``/snapshots`` (dimensions ``step``, ``point``) as a Dataset."""
    xr = _need("xarray")
    attrs = {"path": arc.path, **{k: v for k, v in arc.params.as_dict().items()}}
    if group == "series":
        series = arc.series
        coords = {"step": ("step", series["step"], attributes(arc, "series", "step"))}
        data = {name: ("step", series[name], attributes(arc, "series", name)) for name in SERIES_FIELDS[1:]}
        return xr.Dataset(data, coords=coords, attrs=attrs)
    if group == "snapshots":
        snaps = arc.snapshots
        coords = {
            "step": ("step", snaps.steps, attributes(arc, "snapshots", "step")),
            "point": ("point", snaps.indices, attributes(arc, "snapshots", "indices")),
        }
        data = {
            name: (("step", "point"), getattr(snaps, name), attributes(arc, "snapshots", name))
            for name in SNAPSHOT_FIELDS
        }
        return xr.Dataset(data, coords=coords, attrs=attrs)
    raise ValueError(f"group = {group!r} is not 'series' or 'snapshots'")
