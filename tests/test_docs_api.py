"""docs/api.md runs: every ```python block, in order, in one namespace, in a fresh folder.

The tutorial is the API's documentation (issue 14, item 9); this keeps every line of it true.
"""

from __future__ import annotations

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
