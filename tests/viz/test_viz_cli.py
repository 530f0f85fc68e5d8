"""``python -m viz``: help, bad input, Ctrl-C, and the name it installs under (issue 14, items 6-7)."""

from __future__ import annotations

import ast
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from support import cli, in_process, launch

from warpratchet.sweep import read_sweep

ROOT = Path(__file__).resolve().parents[2]


def _viz(*args: str, cwd: Path = ROOT, package: str = "viz") -> subprocess.CompletedProcess:
    return cli(*args, module=package, cwd=cwd)


def _viz_here(capfd, *args: str) -> subprocess.CompletedProcess:
    """``python -m viz ARGS`` through its ``main`` in this process."""
    from viz.__main__ import main

    return in_process(capfd, *args, main=main)


def test_help_exits_0_and_names_every_command(capfd):
    done = _viz_here(capfd, "--help")
    assert done.returncode == 0, done.stderr
    for command in ("figures", "scenes", "record", "report", "history"):
        assert command in done.stdout
    figures = _viz_here(capfd, "figures", "--help")
    assert figures.returncode == 0
    # a time depends on the machine: the help names none (README gives it with its machine)
    assert re.findall(r"\d+\s*(?:s|min|minutes?)\b|\bunder (?:a|one|1) min", figures.stdout) == []


@pytest.mark.parametrize("args", [(), ("bogus",)])
def test_missing_or_unknown_command_is_a_usage_error(args, capfd):
    done = _viz_here(capfd, *args)
    assert done.returncode == 2
    assert done.stderr.startswith("usage: python -m viz") and "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines()[-1].startswith("python -m viz: error: ")


def test_ctrl_c_in_figures_prints_one_line_and_exits_130(tmp_path):
    """SIGINT to a real process in the middle of a sweep: one line, status 130, the sweep file kept."""
    out = tmp_path / "figures"
    # Fig. 7 at the paper's settings takes minutes; the interrupt lands in the first points.
    proc = launch("figures", "--only", "fig7", "--out", str(out), "--quiet", module="viz", cwd=ROOT)
    argv = proc.args
    try:
        deadline = time.monotonic() + 900
        sweep = out / "sweeps" / "fig7.h5"
        # Readiness: the sweep file holds its first point, so the sweep's loop is running.
        while not (sweep.exists() and read_sweep(sweep)):
            assert proc.poll() is None, (argv, proc.communicate(timeout=900))
            assert time.monotonic() < deadline, f"{argv}: no sweep point within 900 s"
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=900)
    finally:
        proc.kill()
    assert proc.returncode == 130, stderr
    assert stderr.strip().splitlines() == [
        "python -m viz figures: interrupted; finished sweep points are kept in the sweep files and reused "
        "by the next run"
    ]
    assert len(read_sweep(out / "sweeps" / "fig7.h5")) < 33  # readable, and interrupted early
    assert not list(out.glob("fig7.*"))


def test_installed_under_its_own_name(tmp_path):
    """The installed package is warpratchet_viz; outside the checkout there is no top-level viz."""
    done = _viz("--help", cwd=tmp_path, package="warpratchet_viz")
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("usage: python -m warpratchet_viz")
    absent = subprocess.run(
        [sys.executable, "-c", "import viz"], cwd=tmp_path, capture_output=True, text=True, timeout=900
    )
    assert absent.returncode != 0 and "No module named 'viz'" in absent.stderr


def test_package_list_maps_every_package_folder():
    """pyproject.toml lists packages by hand (setuptools cannot rename found ones): none may be missing."""
    try:
        import tomllib
    except ImportError:  # Python 3.10: pytest itself depends on tomli there
        import tomli as tomllib

    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]
    folders = {"warpratchet_viz": "viz"}
    assert config["package-dir"] == folders
    listed = set(config["packages"])
    found = set()
    for top, folder in (("warpratchet", "warpratchet"), ("warpratchet_viz", "viz")):
        for init in (ROOT / folder).rglob("__init__.py"):
            parts = init.parent.relative_to(ROOT / folder).parts
            found.add(".".join((top, *parts)))
    assert listed == found
    assert not any(name == "viz" or name.startswith("viz.") for name in listed)


def test_viz_imports_itself_relatively():
    """Absolute ``viz`` imports would break under the installed name warpratchet_viz."""
    for path in (ROOT / "viz").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module or ""]
            assert not [n for n in names if n == "viz" or n.startswith("viz.")], f"{path}: {names}"


def test_history_plots_an_archives_history(tmp_path, capfd):
    """``python -m viz history run.h5 -o history.png``; an archive without a history is one line, status 2.

    Through ``main`` in this process."""
    from viz.__main__ import main
    from warpratchet import Ensemble, MapParams

    def refused(*args: str) -> str:
        code, err = main(list(args)), capfd.readouterr().err
        assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
        return err

    path = tmp_path / "run.h5"
    Ensemble.sample(MapParams(3.0, 0.1, 0.01), 500, "strip", 1).run(4000, archive=path)
    done = _viz_here(capfd, "history", str(path), "-o", str(tmp_path / "history.png"))
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "history.png").read_bytes().startswith(b"\x89PNG")
    old = refused("history", str(ROOT / "tests" / "data" / "archive_v2.h5"), "-o", str(tmp_path / "old.png"))
    assert "has no history" in old
    assert not (tmp_path / "old.png").exists()
    # an existing figure is the user's: kept without --overwrite, replaced with it
    (tmp_path / "history.png").write_bytes(b"mine")
    again = refused("history", str(path), "-o", str(tmp_path / "history.png"))
    assert "already exists" in again and "--overwrite" in again
    assert (tmp_path / "history.png").read_bytes() == b"mine"
    replaced = _viz_here(capfd, "history", str(path), "-o", str(tmp_path / "history.png"), "--overwrite")
    assert replaced.returncode == 0, replaced.stderr
    assert (tmp_path / "history.png").read_bytes().startswith(b"\x89PNG")
