"""Size limits of the companion's code: functions up to 80 lines, classes up to 300.

A longer function or class must say why, in the comment block right above it (above its
decorators), on a line containing ``size:``, for example::

    # size: one pass over an hour's log; a helper call per record costs a measurable share.
    def read_flight(...):

The older form ``# Over 300 lines on purpose: ...`` counts too. Exemptions are meant to be rare:
their number is capped below, and raising the cap is a decision for review, not a way to pass.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "companion"
MAX_FUNCTION_LINES = 80
MAX_CLASS_LINES = 300
# Path (the path contract), MavLink (the one pymavlink adapter), read_flight (the replay hot path).
MAX_EXEMPTIONS = 3
# A reason must follow the marker: at least a few words, not just the marker.
REASON = re.compile(r"#.*\b(?:size:|lines on purpose:)\s*\S.{10,}", re.IGNORECASE)


def _span(node: ast.AST) -> tuple[int, int]:
    """First line (its first decorator, if any) and last line of a def or class."""
    decorators = getattr(node, "decorator_list", [])
    first = min([node.lineno] + [d.lineno for d in decorators])
    return first, node.end_lineno


def _comment_above(lines: list[str], first: int) -> list[str]:
    """The block of comment lines directly above line ``first`` (1-based)."""
    block = []
    i = first - 2
    while i >= 0 and lines[i].lstrip().startswith("#"):
        block.append(lines[i])
        i -= 1
    return block


def _sized_nodes(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node, MAX_FUNCTION_LINES
        elif isinstance(node, ast.ClassDef):
            yield node, MAX_CLASS_LINES


def measure(package: Path = PACKAGE) -> tuple[list[str], list[str]]:
    """``(offenders, exempted)``: each ``file:line name (N lines > limit)``."""
    offenders, exempted = [], []
    for file in sorted(package.rglob("*.py")):
        text = file.read_text(encoding="utf-8")
        lines = text.splitlines()
        for node, limit in _sized_nodes(ast.parse(text, str(file))):
            first, last = _span(node)
            size = last - first + 1
            if size <= limit:
                continue
            entry = f"{file.relative_to(package.parent)}:{node.lineno} {node.name} ({size} lines > {limit})"
            if any(REASON.search(line) for line in _comment_above(lines, first)):
                exempted.append(entry)
            else:
                offenders.append(entry)
    return offenders, exempted


def test_no_function_or_class_over_the_limits_without_a_reason():
    offenders, _ = measure()
    assert not offenders, ("over the size limits without a '# size: <why>' comment above:\n  "
                           + "\n  ".join(offenders))


def test_exemptions_stay_rare():
    _, exempted = measure()
    assert len(exempted) <= MAX_EXEMPTIONS, "more exemptions than allowed:\n  " + "\n  ".join(exempted)


def test_the_check_finds_a_long_function_and_honours_a_reason(tmp_path):
    pkg = tmp_path / "companion"
    pkg.mkdir()
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES))
    (pkg / "long.py").write_text(f"def too_long():\n{body}\n\n\n# size:\ndef bare_marker():\n{body}\n\n\n"
                                 f"# size: one table of the dialect, kept whole for review.\n"
                                 f"def explained():\n{body}\n\n\ndef short():\n    return 1\n")
    offenders, exempted = measure(pkg)
    assert [e.split()[1] for e in offenders] == ["too_long", "bare_marker"]
    assert [e.split()[1] for e in exempted] == ["explained"]
    assert offenders[0].endswith(f"({MAX_FUNCTION_LINES + 1} lines > {MAX_FUNCTION_LINES})")
