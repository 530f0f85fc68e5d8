"""The layers of docs/architecture.md, checked against every import of the code.

Reads every module of ``warpratchet/``, ``viz/`` and ``benchmarks/`` with :mod:`ast` and collects
every import, those inside functions and ``if TYPE_CHECKING:`` blocks included (an import a
function runs later is an arrow all the same). An arrow goes from the importing module to the
module that holds the imported name (``from .archive import open_archive`` is an arrow to the
package ``warpratchet.archive``, ``from .archive._reader import Archive`` one to
``warpratchet.archive._reader``). Then:

* no two modules import each other, however far round (no cycles);
* no arrow points up: the layer table of docs/architecture.md places every module, and a
  module imports only from its own layer or those below;
* front ends (cli, viz, benchmarks) import the public API only: ``warpratchet`` and its public
  top-level modules and packages, never a private module (``_name``) nor a module inside a
  subpackage, which is that package's implementation;
* pure modules import no Warp, HDF5, progress bar, viewer, plotting or cluster library, and
  importing one loads none of them (its package's face included).

The few front-end arrows that the code needs today and the rules refuse are listed in
:data:`EXCEPTIONS`, each with its reason; an exception the code no longer needs fails too.
"""

from __future__ import annotations

import ast
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "architecture.md"
#: The folders read, as the tests import them (``viz`` installs as ``warpratchet_viz``).
TOPS = ("warpratchet", "viz", "benchmarks")
ALIASES = {"warpratchet_viz": "viz"}
#: Libraries a pure module may not import: they need a device, files, a terminal or a cluster.
NOT_PURE = {"warp", "h5py", "tqdm", "rerun", "matplotlib", "dask", "distributed"}

#: (importer, imported) -> why the arrow stays although the front-end rule refuses it.
EXCEPTIONS: dict[tuple[str, str], str] = {}


def _name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES = {_name(p): p for top in TOPS for p in sorted((ROOT / top).rglob("*.py"))}


def _resolve(name: str) -> str | None:
    """The module of ours that holds ``name`` (a module, or a name inside one), or None."""
    head, _, rest = name.partition(".")
    name = ".".join(filter(None, [ALIASES.get(head, head), rest]))
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _imports(module: str) -> tuple[set[str], set[str]]:
    """(arrows to modules of ours, top-level names of other packages) of every import in ``module``."""
    path = MODULES[module]
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    ours, theirs = set(), set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            names = [f"{source}.{alias.name}" for alias in node.names]
        else:
            continue
        for name in names:
            target = _resolve(name)
            if target is None:
                theirs.add(name.partition(".")[0])
            elif target != module:
                ours.add(target)
    return ours, theirs


GRAPH = {module: _imports(module) for module in MODULES}
ARROWS = {module: ours for module, (ours, _) in GRAPH.items()}


def _layers() -> list[tuple[str, list[str]]]:
    """The layer table of docs/architecture.md, top first: (layer, module names)."""
    text = DOC.read_text(encoding="utf-8")
    section = text.split("## Layers", 1)[1].split("\n## ", 1)[0]
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 2 and "`" in cells[1]:
            rows.append((cells[0], re.findall(r"`([\w.]+)`", cells[1])))
    return rows


LAYERS = _layers()


def _layer_of(module: str) -> int | None:
    """Rank of ``module`` (0: the bottom layer), by the most specific name of the table that
    holds it; ``warpratchet`` holds only the package's face, not every module below it."""
    best, rank = "", None
    for i, (_, names) in enumerate(LAYERS):
        for name in names:
            exact = name == "warpratchet"
            if (module == name or (not exact and module.startswith(name + "."))) and len(name) >= len(best):
                best, rank = name, len(LAYERS) - 1 - i
    return rank


def _front_end(module: str) -> bool:
    return _layer_of(module) == len(LAYERS) - 1


def _public(module: str) -> bool:
    """``warpratchet`` or a public top-level module or package of it."""
    parts = module.split(".")
    return parts[0] == "warpratchet" and len(parts) <= 2 and not parts[-1].startswith("_")


def _cycles() -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in ARROWS[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(MODULES):
        if v not in index:
            visit(v)
    return found


def test_the_reader_sees_every_kind_of_import():
    # The parser itself: a function-level import, a relative one, a name inside a package face.
    assert "warpratchet.progress" in ARROWS["warpratchet.ensemble"]  # inside Ensemble.run
    assert "warpratchet.archive._writer" in ARROWS["warpratchet"]  # inside a function of the face
    assert "warpratchet.archive" in ARROWS["warpratchet.cli.verify"]  # from ..archive import ...
    assert "viz.figures" in ARROWS["warpratchet.cli.figures"]  # warpratchet_viz is viz/
    assert len(MODULES) > 100 and sum(map(len, ARROWS.values())) > 400


def test_no_import_cycles():
    assert _cycles() == []


def test_the_table_places_every_module_and_names_no_missing_one():
    assert [layer for layer, _ in LAYERS][0] == "front ends" and len(LAYERS) >= 6
    unplaced = sorted(m for m in MODULES if _layer_of(m) is None)
    assert unplaced == [], "place these modules in the layer table of docs/architecture.md"
    listed = {name for _, names in LAYERS for name in names}
    missing = sorted(n for n in listed if not any(m == n or m.startswith(n + ".") for m in MODULES))
    assert missing == [], "docs/architecture.md names modules that do not exist"


def test_arrows_point_down():
    up = sorted(
        f"{a} ({LAYERS[-1 - _layer_of(a)][0]}) -> {b} ({LAYERS[-1 - _layer_of(b)][0]})"
        for a, targets in ARROWS.items()
        for b in targets
        if _layer_of(b) > _layer_of(a)
    )
    assert up == []


def test_front_ends_use_the_public_api_only():
    reaching = {
        (a, b)
        for a, targets in ARROWS.items()
        if _front_end(a)
        for b in targets
        if not _front_end(b) and not _public(b)
    }
    assert sorted(reaching - EXCEPTIONS.keys()) == []
    assert sorted(EXCEPTIONS.keys() - reaching) == [], "an exception the code no longer needs"


@pytest.mark.parametrize("module", sorted(m for m in MODULES if _layer_of(m) == 0))
def test_pure_modules_import_no_device_files_or_terminal(module):
    _, theirs = GRAPH[module]
    assert sorted(theirs & NOT_PURE) == []


def _loaded_by(names: list[str], then: str = "") -> list[str]:
    """The device and file libraries a fresh interpreter holds after importing ``names`` (and
    running ``then``)."""
    script = (
        "import json, sys\n"
        f"for name in {names!r}:\n"
        "    __import__(name)\n"
        f"{then}\n"
        "print(json.dumps(sorted(k for k in ('warp', 'h5py', 'tqdm', 'rerun') if k in sys.modules)))\n"
    )
    argv = [sys.executable, "-c", script]
    proc = subprocess.run(argv, capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_importing_a_pure_module_loads_no_device_or_file_library():
    # What the import statements alone cannot show: a package's __init__ runs first.
    assert _loaded_by([m for m in sorted(MODULES) if _layer_of(m) == 0]) == []


def test_the_sweep_face_loads_warp_and_hdf5_only_when_asked():
    # Front ends import the paths from the face (``from warpratchet.sweep import maximal_path``).
    assert _loaded_by(["warpratchet.sweep"], "from warpratchet.sweep import maximal_path, ROW_FIELDS") == []
    then = "import warpratchet.sweep as s; assert callable(s.run_sweep) and 'run_sweep' in dir(s)"
    assert set(_loaded_by(["warpratchet.sweep"], then)) >= {"warp", "h5py"}
