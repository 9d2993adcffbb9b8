"""The maths layers stay pure, and the mock autopilot and the companion meet only on the wire."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

PURE_ALLOWED = {
    "companion.geometry": {"numpy", "scipy", "companion.geometry"},
    "companion.guidance": {"numpy", "scipy", "companion.geometry", "companion.guidance"},
    "companion.sim": {"numpy", "scipy", "companion.geometry", "companion.guidance", "companion.sim"},
}
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


def top_allowed(name: str, allowed: set[str]) -> bool:
    return any(name == a or name.startswith(a + ".") for a in allowed)


@pytest.mark.parametrize("package", sorted(PURE_ALLOWED))
def test_maths_layers_import_only_maths(package):
    folder = ROOT / package.replace(".", "/")
    allowed = PURE_ALLOWED[package]
    offenders = []
    for path in sorted(folder.rglob("*.py")):
        for name in imported_modules(path):
            root = name.split(".")[0]
            if name.startswith("companion") and not top_allowed(name, allowed):
                offenders.append(f"{path.relative_to(ROOT)}: {name}")
            elif root in FORBIDDEN_STDLIB or root in {"pymavlink", "yaml", "matplotlib"}:
                offenders.append(f"{path.relative_to(ROOT)}: {name}")
    assert not offenders, "impure imports:\n" + "\n".join(offenders)


def test_mock_and_companion_share_nothing_but_the_wire():
    offenders = []
    for path in sorted((ROOT / "sitl_mock").rglob("*.py")):
        offenders += [f"{path.relative_to(ROOT)}: {n}" for n in imported_modules(path) if n.split(".")[0] == "companion"]
    for path in sorted((ROOT / "companion").rglob("*.py")):
        offenders += [f"{path.relative_to(ROOT)}: {n}" for n in imported_modules(path) if n.split(".")[0] == "sitl_mock"]
    assert not offenders, "\n".join(offenders)


def test_pymavlink_only_in_io_and_mock():
    offenders = []
    for path in sorted((ROOT / "companion").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        if rel.startswith("companion/io/"):
            continue
        offenders += [f"{rel}: {n}" for n in imported_modules(path) if n.split(".")[0] == "pymavlink"]
    assert not offenders, "pymavlink outside companion.io:\n" + "\n".join(offenders)


def test_vehicle_identification_is_maths_and_its_tlog_reading_an_adapter():
    # The fit (companion.sim.identify) sees arrays only; reading the tlog is companion.io.idlog's
    # job, and the command wires the two.
    fit = imported_modules(ROOT / "companion" / "sim" / "identify.py")
    assert {n for n in fit if n.startswith("companion")} <= {"companion.guidance.types"}
    assert not {n.split(".")[0] for n in fit} & (FORBIDDEN_STDLIB | {"pymavlink", "yaml"})
    adapter = imported_modules(ROOT / "companion" / "io" / "idlog.py")
    assert "companion.sim.identify" in adapter and "companion.io.logread" in adapter
    command = imported_modules(ROOT / "companion" / "cli" / "identify.py")
    assert not {n for n in command if n.startswith("companion.io.logread") or n.split(".")[0] == "pymavlink"}
