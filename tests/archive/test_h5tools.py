"""Archives and sweep files open in the tools users have (issue 14.2, 14.3).

* ``h5dump -H`` and ``h5ls -r`` of HDF5 1.10 (Debian's ``hdf5-tools``; ``.ci/run`` installs them
  where it can) print the layout of a fresh archive and sweep file: the files pin HDF5 1.10
  object formats (``warpratchet._files.LIBVER``). Skipped, with the reason, where the tools are absent.
* ``xarray.open_dataset(path, group="series", engine="h5netcdf")`` names the time axis ``step``,
  with units, and invents no phony dimension; ``Archive.to_pandas()``/``to_xarray()`` and
  ``read_sweep(..., as_="pandas")`` carry the same numbers.
"""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from warpratchet import Ensemble, MapParams, open_archive
from warpratchet.archive import SERIES_FIELDS, ArchiveSink
from warpratchet.sweep import SweepSpec, read_sweep, run_sweep

PARAMS = MapParams(3.0, 0.1, 0.01)


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    path = tmp_path_factory.mktemp("tools") / "run.h5"
    ens = Ensemble.sample(PARAMS, 200, "strip", 3)
    with ArchiveSink(path, ens, snapshot_every=100, snapshot_points=20, chunk_steps=50) as sink:
        ens.run(400, [sink], chunk_steps=sink.chunk_steps)
    return path


@pytest.fixture(scope="module")
def sweep_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("tools") / "sweep.h5"
    run_sweep([PARAMS, MapParams(3.0, 0.1, 0.02)], SweepSpec(points=50, steps=100), out=path, progress=False)
    return path


def _tool(name: str) -> str:
    exe = shutil.which(name)
    if exe is None:
        pytest.skip(f"{name} is not installed (Debian/Ubuntu: apt-get install hdf5-tools)")
    return exe


def _run(*argv) -> subprocess.CompletedProcess:
    return subprocess.run(argv, capture_output=True, text=True, timeout=900)


@pytest.mark.parametrize("which", ["archive", "sweep_file"])
def test_h5dump_prints_the_layout(request, which):
    path = request.getfixturevalue(which)
    proc = _run(_tool("h5dump"), "-H", str(path))
    assert proc.returncode == 0 and "error" not in (proc.stdout + proc.stderr).lower(), (
        proc.stdout + proc.stderr
    )
    expect = (
        ["/series/A", "/checkpoint/a/x", "units"] if which == "archive" else ["rows", "parameters", "units"]
    )
    for word in expect:
        assert word.rsplit("/", 1)[-1] in proc.stdout, word
    assert 'GROUP "/"' in proc.stdout


@pytest.mark.parametrize("which", ["archive", "sweep_file"])
def test_h5ls_lists_every_dataset(request, which):
    path = request.getfixturevalue(which)
    proc = _run(_tool("h5ls"), "-r", str(path))
    assert proc.returncode == 0 and "*ERROR*" not in proc.stdout, proc.stdout + proc.stderr
    if which == "archive":
        assert "/series/A                Dataset {8/Inf}" in proc.stdout  # exactly the valid rows
        assert "/snapshots/x             Dataset {4/Inf, 20/Inf}" in proc.stdout
    else:
        assert "/rows" in proc.stdout and "/parameters" in proc.stdout


def test_xarray_opens_the_series_with_a_step_dimension(archive):
    xr = pytest.importorskip("xarray", reason="the xarray extra is not installed")
    pytest.importorskip("h5netcdf", reason="the xarray extra is not installed")
    with xr.open_dataset(archive, group="series", engine="h5netcdf") as ds:
        assert dict(ds.sizes) == {"step": 8}
        assert not any(str(dim).startswith("phony_dim") for dim in ds.dims)
        assert ds["step"].attrs["units"] == "iteration"
        assert ds["A"].attrs["units"] == "1/iteration" and "Eq. (An)" in ds["A"].attrs["long_name"]
        with open_archive(archive) as arc:
            series = arc.series
            assert np.array_equal(ds["step"].values, series["step"])
            assert np.array_equal(ds["A"].values, series["A"], equal_nan=True)
    with xr.open_dataset(archive, group="snapshots", engine="h5netcdf") as ds:
        assert dict(ds.sizes) == {"step": 4, "indices": 20}


def test_archive_exports_to_pandas_and_xarray(archive):
    pytest.importorskip("pandas", reason="the xarray extra is not installed")
    pytest.importorskip("xarray", reason="the xarray extra is not installed")
    with open_archive(archive) as arc:
        series = arc.series
        frame = arc.to_pandas()
        assert list(frame.index) == list(series["step"]) and frame.index.name == "step"
        for name in SERIES_FIELDS[1:]:
            assert np.array_equal(frame[name].to_numpy(), series[name], equal_nan=True), name
        assert frame.attrs["units"]["A"] == "1/iteration"
        ds = arc.to_xarray()
        assert (
            np.array_equal(ds["A"].values, series["A"], equal_nan=True)
            and ds["step"].attrs["units"] == "iteration"
        )
        snaps = arc.to_xarray("snapshots")
        assert snaps["x"].dims == ("step", "indices") and np.array_equal(snaps["x"].values, arc.snapshots.x)


def test_sweep_reads_as_pandas(sweep_file):
    pytest.importorskip("pandas", reason="the xarray extra is not installed")
    rows = read_sweep(sweep_file)
    frame = read_sweep(sweep_file, as_="pandas")
    assert len(frame) == 2 and list(frame["A"]) == [row["A"] for row in rows]
    assert frame.attrs["units"]["A"] == "1/iteration"
