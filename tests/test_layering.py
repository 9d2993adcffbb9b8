"""The layers import only what docs/architecture.md allows, and the doc states what is enforced.

The table of docs/architecture.md ("Packages") is the one statement of the rules: this test reads
it, checks that it names every package of the tree, and checks every file's imports against it.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "architecture.md"
MATHS_LAYERS = ("companion.geometry", "companion.guidance", "companion.sim")
# Standard-library modules the pure layers must not touch: clocks, sockets, logging, files.
FORBIDDEN_STDLIB = {"time", "socket", "logging", "os", "subprocess", "threading", "asyncio", "io"}


def imported_modules(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


def _names(cell: str, prefix: str) -> set[str]:
    cell = cell.strip()
    if cell in ("–", "-", ""):
        return set()
    return {prefix + n.strip() for n in cell.split(",")}


def doc_rules() -> dict[str, tuple[set[str], set[str]]]:
    """package -> (companion packages it may import, libraries it may import), from the doc."""
    text = DOC.read_text(encoding="utf-8")
    section = text[text.index("## Packages"):text.index("## Frames and names")]
    rules = {}
    for line in section.splitlines():
        if not line.startswith("| `"):
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        package = cells[0].strip("`")
        # the 'what lives there' cell may contain escaped pipes: the last two cells are the rules
        rules[package] = (_names(cells[-2], "companion."), _names(cells[-1], ""))
    return rules


RULES = doc_rules()


def package_of(path: Path) -> str | None:
    rel = path.relative_to(ROOT).with_suffix("").parts
    if rel[0] == "sitl_mock":
        return "sitl_mock"
    if len(rel) == 2:  # a module directly in companion/
        return None if rel[1] == "__init__" else ".".join(rel)
    return ".".join(rel[:2])


def source_files() -> list[Path]:
    return sorted((ROOT / "companion").rglob("*.py")) + sorted((ROOT / "sitl_mock").rglob("*.py"))


def allowed(name: str, packages: set[str]) -> bool:
    return any(name == a or name.startswith(a + ".") for a in packages)


def test_the_doc_names_every_package_of_the_tree():
    found = {package_of(p) for p in source_files()} - {None}
    assert found == set(RULES), f"in the tree, not in the doc: {sorted(found - set(RULES))}; " \
                                f"in the doc, not in the tree: {sorted(set(RULES) - found)}"


@pytest.mark.parametrize("package", sorted(RULES))
def test_every_package_imports_only_what_the_doc_allows(package):
    may_companion, may_libraries = RULES[package]
    offenders = []
    for path in source_files():
        if package_of(path) != package:
            continue
        for name in imported_modules(path):
            root = name.split(".")[0]
            if root == "companion":
                if name == "companion" or allowed(name, {package}):
                    continue
                if not allowed(name, may_companion):
                    offenders.append(f"{path.relative_to(ROOT)}: {name}")
            elif root == "sitl_mock":
                if package != "sitl_mock":
                    offenders.append(f"{path.relative_to(ROOT)}: {name}")
            elif root not in sys.stdlib_module_names and root not in may_libraries:
                offenders.append(f"{path.relative_to(ROOT)}: {name}")
    assert not offenders, f"imports {package} may not make (docs/architecture.md):\n" + "\n".join(offenders)


@pytest.mark.parametrize("package", MATHS_LAYERS)
def test_maths_layers_touch_no_clock_socket_log_or_file(package):
    offenders = []
    for path in source_files():
        if package_of(path) != package:
            continue
        offenders += [f"{path.relative_to(ROOT)}: {n}" for n in imported_modules(path)
                      if n.split(".")[0] in FORBIDDEN_STDLIB]
    assert not offenders, "impure imports:\n" + "\n".join(offenders)


def test_mock_and_companion_share_nothing_but_the_wire():
    offenders = []
    for path in sorted((ROOT / "sitl_mock").rglob("*.py")):
        offenders += [f"{path.relative_to(ROOT)}: {n}" for n in imported_modules(path) if n.split(".")[0] == "companion"]
    for path in sorted((ROOT / "companion").rglob("*.py")):
        offenders += [f"{path.relative_to(ROOT)}: {n}" for n in imported_modules(path) if n.split(".")[0] == "sitl_mock"]
    assert not offenders, "\n".join(offenders)


def test_pymavlink_only_in_io_and_mock():
    users = {p for p, (_, libraries) in RULES.items() if "pymavlink" in libraries}
    assert users == {"companion.io", "sitl_mock"}


def test_vehicle_identification_is_maths_and_its_tlog_reading_an_adapter():
    # The fit (companion.sim.identify) sees arrays only; reading the tlog is companion.io.idlog's
    # job, and the command wires the two.
    fit = imported_modules(ROOT / "companion" / "sim" / "identify.py")
    assert {n for n in fit if n.startswith("companion")} <= {"companion.guidance.types", "companion.sim.wander"}
    assert not {n.split(".")[0] for n in fit} & (FORBIDDEN_STDLIB | {"pymavlink", "yaml"})
    wander = imported_modules(ROOT / "companion" / "sim" / "wander.py")
    assert not {n for n in wander if n.startswith("companion")}
    assert not {n.split(".")[0] for n in wander} & (FORBIDDEN_STDLIB | {"pymavlink", "yaml"})
    adapter = imported_modules(ROOT / "companion" / "io" / "idlog.py")
    assert "companion.sim.identify" in adapter and "companion.io.logread" in adapter
    command = imported_modules(ROOT / "companion" / "cli" / "identify.py")
    assert not {n for n in command if n.startswith("companion.io.logread") or n.split(".")[0] == "pymavlink"}
