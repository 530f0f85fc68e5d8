"""The house's rules for text, checked where a reader meets it.

* No issue numbers in user-facing text: every string and comment of ``warpratchet/`` and
  ``viz/`` (help, messages, printed output, docstrings), every page of ``docs/``, the README, and
  the rendered ``--help`` of every ``warpratchet`` subcommand.
* Docstrings and comments of ``warpratchet/`` and ``viz/`` say what and why in the present tense:
  no dates, no measured timings (those go to ``benchmarks/README.md`` with their command), no
  "before: ... / was X, now Y" narration.

Each rule is a regular expression; the self-test below shows that each one fires on the kind of
line it is meant to refuse and passes the kinds of line the code legitimately holds.
"""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CODE = sorted(p for top in ("warpratchet", "viz") for p in (ROOT / top).rglob("*.py"))
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

#: An issue or pull-request number: "issue 16", "issues 12 and 14", "(#25)".
ISSUE = re.compile(r"\bissues?\s+#?\d+|\(#\d+\)|\bissue\s+#\d+", re.IGNORECASE)
#: What a docstring or comment must not hold, by name.
NARRATION = {
    "a date": re.compile(r"\b(19|20)\d\d-[01]\d-[0-3]\d\b"),
    "a measured timing": re.compile(
        r"\d\s?(ms|µs|us|ns)\s+(per|a|an|each)\s+(launch|row|step|point|chunk|block|frame|run)\b"
        r"|\bbest (launch|of \d+)\b[^.]*\d\s?(ms|s)\b"
        r"|\d[\d.,]*\s?[MG]\s?point-steps",
        re.IGNORECASE,
    ),
    "a former state": re.compile(
        r"(?:^|[(|#])\s*before:|\b(was|were)\b[^;\n]{0,80}?[,;]\s*now\b|\bnow ~?\d|\bmeasured again later\b",
        re.IGNORECASE | re.MULTILINE,
    ),
}


def _strings_and_comments(path: Path) -> tuple[list[tuple[int, str]], list[tuple[int, str]]]:
    """(every string constant, docstrings and comments only) of a module, with line numbers."""
    source = path.read_text(encoding="utf-8")
    strings, prose = [], []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            strings.append((node.lineno, node.value))
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                if isinstance(body[0].value.value, str):
                    prose.append((body[0].lineno, body[0].value.value))
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT:
            strings.append((token.start[0], token.string))
            prose.append((token.start[0], token.string))
    return strings, prose


def _found(pattern: re.Pattern, texts: list[tuple[int, str]], where: str) -> list[str]:
    return [f"{where}:{line}: {m.group(0)!r}" for line, text in texts for m in pattern.finditer(text)]


def test_no_issue_numbers_in_code_text_docs_or_help():
    found = []
    for path in CODE:
        strings, _ = _strings_and_comments(path)
        found += _found(ISSUE, strings, str(path.relative_to(ROOT)))
    for page in PAGES:
        lines = list(enumerate(page.read_text(encoding="utf-8").splitlines(), 1))
        found += _found(ISSUE, lines, str(page.relative_to(ROOT)))
    from warpratchet.cli import build_parser

    parser = build_parser()
    (sub,) = [a for a in parser._actions if hasattr(a, "choices") and isinstance(a.choices, dict)]
    helps = [(0, parser.format_help())] + [(0, p.format_help()) for p in sub.choices.values()]
    found += _found(ISSUE, helps, "warpratchet --help")
    assert found == []


@pytest.mark.parametrize("rule", sorted(NARRATION))
def test_docstrings_and_comments_narrate_no_history(rule):
    found = []
    for path in CODE:
        _, prose = _strings_and_comments(path)
        found += _found(NARRATION[rule], prose, str(path.relative_to(ROOT)))
    assert found == [], f"{rule}: move it to benchmarks/README.md or the commit body"


#: Per rule, lines it must refuse and ordinary prose it must let pass.
EXAMPLES = {
    "issue": {
        "the run's history (issue 15)": "no warning is issued here",
        "see issues 12 and 14": "Issue an UnreliableWarning",
    },
    "a date": {"measured 2026-11-26 on the EPYC": "seconds since 1970 (a count)"},
    "a measured timing": {
        "cost ~12 ms per launch of 10^6 points": "retries ~2 ms apart",
        "best launch 177 ms (16) vs 171 ms (8)": "backing off to 36 s a try",
        "reaches 775 M point-steps/s": "speed in point-steps per second",
    },
    "a former state": {
        "before: scalar Warp step per lane": "before the first run",
        "8 lanes (before: 171 instructions)": "printed on the line before: a usage line",
        "it was params.check_real, now errors": "the state now moves on",
        "~12 ms per launch; now ~2 ms": "what the flag is called now",
    },
}


@pytest.mark.parametrize(
    ("rule", "refused", "allowed"),
    [(rule, refused, allowed) for rule, pairs in EXAMPLES.items() for refused, allowed in pairs.items()],
)
def test_each_rule_refuses_what_it_names_and_passes_ordinary_prose(rule, refused, allowed):
    pattern = ISSUE if rule == "issue" else NARRATION[rule]
    assert pattern.search(refused) and not pattern.search(allowed)
