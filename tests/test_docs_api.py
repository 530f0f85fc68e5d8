"""docs/api.md runs: every ```python block, in order, in one namespace, in a fresh folder.

The tutorial is the API's documentation (issue 14, item 9); this keeps every line of it true.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "api.md"
BLOCK = re.compile(r"^```python\n(.*?)^```$", re.DOTALL | re.MULTILINE)


def test_the_tutorial_runs(tmp_path, monkeypatch, capsys):
    pytest.importorskip("pandas", reason="the tutorial's tables use pandas (an optional dependency)")
    blocks = BLOCK.findall(DOC.read_text())
    assert len(blocks) >= 6
    monkeypatch.chdir(tmp_path)  # the tutorial writes tutorial.h5 and tutorial_sweep.h5 here
    namespace: dict = {"__name__": "tutorial"}
    for i, code in enumerate(blocks):
        exec(compile(code, f"{DOC.name} block {i + 1}", "exec"), namespace)  # noqa: S102
    out = capsys.readouterr().out
    assert "A = 0.14" in out  # the first block's A, next to Eq. (Aa)'s 0.1450


PACKAGE = DOC.parents[1] / "warpratchet"
LISTED = re.compile(r"^- \*\*`(warpratchet(?:\.\w+)?)`\*\*: (.*)\.$", re.MULTILINE)


def _public_modules() -> dict[str, list[str]]:
    """Each public module (``warpratchet`` and its top-level modules and packages whose names do
    not start with ``_``) and its ``__all__``, read from the source: no import, so no optional
    dependency is needed."""
    found = {}
    for path in sorted(PACKAGE.iterdir()):
        if path.name.startswith("_") and path.name != "__init__.py":
            continue
        source = path / "__init__.py" if path.is_dir() else path
        if not source.is_file() or source.suffix != ".py":
            continue
        name = (
            "warpratchet"
            if path.name == "__init__.py"
            else f"warpratchet.{source.stem if path.is_file() else path.name}"
        )
        tree = ast.parse(source.read_text())
        values = [
            node.value
            for node in tree.body
            if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "__all__" for t in node.targets)
        ]
        assert len(values) == 1, f"{source}: one literal __all__"
        found[name] = list(ast.literal_eval(values[0]))
    return found


def test_the_public_api_listed_in_the_docs_is_what_all_holds():
    listed = {
        module: [n.strip().strip("`") for n in names.split(",")]
        for module, names in LISTED.findall(DOC.read_text())
    }
    public = _public_modules()
    assert len(public) > 20 and "warpratchet.theory" in public
    assert sorted(listed) == sorted(public), "docs/api.md lists other modules than the public ones"
    for module, names in public.items():
        assert listed[module] == names, module
