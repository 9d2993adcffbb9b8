"""The real-firmware tier: flights against the real ArduCopter / PX4 SITL binaries.

Run with ``pytest -m sitl`` (the default run deselects it, see pyproject.toml). Each test needs
its binary, named by an environment variable (README.md, "Testing against the real firmware"),
and skips with the reason when it is absent:

- ``COMPANION_SITL_ARDUCOPTER`` (``.../build/sitl/bin/arducopter``) and
  ``COMPANION_SITL_ARDUCOPTER_DEFAULTS`` (``.../Tools/autotest/default_params/copter.parm``);
- ``COMPANION_SITL_PX4`` (``.../build/px4_sitl_default/bin/px4``) and ``COMPANION_SITL_PX4_ROMFS``
  (``.../build/px4_sitl_default/etc``).

ArduCopter runs as instance ``COMPANION_SITL_INSTANCE`` (default 4) sending to UDP
``COMPANION_SITL_PORT`` (default 14640). PX4 SIH uses fixed ports, so only one can run: the test
skips when another holds them.
"""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path

import pytest

from companion.cli.main import main

pytestmark = pytest.mark.sitl

ROOT = Path(__file__).resolve().parents[2]
FLIGHT_S = 40.0


def _env_file(name: str) -> str:
    value = os.environ.get(name)
    if not value:
        pytest.skip(f"{name} is not set (path of the real SITL binary or its file)")
    if not Path(value).exists():
        pytest.skip(f"{name}={value}: no such file")
    return value


def _px4_ports_free() -> bool:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        s.bind(("127.0.0.1", 14580))  # where a running PX4 SITL listens for its offboard link
        return True
    except OSError:
        return False
    finally:
        s.close()


def _bench(args: list[str], tmp_path: Path, capsys) -> dict:
    code = main(["bench", "sitl", str(ROOT / "missions" / "paper_sine.yaml"), "--method", "corrector",
                 "--max-duration-s", f"{FLIGHT_S:g}", "--workdir", str(tmp_path), "--json", *args])
    out = json.loads(capsys.readouterr().out)
    assert code == 0, out
    return out


def _check_mock_predicts_real(side: dict) -> None:
    mock, real = side["mock"], side["real"]
    assert real["exit"] == "max duration" and mock["exit"] == "max duration"
    assert real["duration_s"] > 0.9 * FLIGHT_S
    # The stability bar: d_rms at most 1.5 times the mock's (capture from take-off included).
    assert real["d_rms_m"] <= 1.5 * mock["d_rms_m"]
    assert real["a_max_m_s2"] < 6.0


def test_arducopter_flies_the_paper_sine_as_the_mock_predicts(tmp_path, capsys):
    binary = _env_file("COMPANION_SITL_ARDUCOPTER")
    defaults = _env_file("COMPANION_SITL_ARDUCOPTER_DEFAULTS")
    out = _bench(["--arducopter", binary, "--arducopter-defaults", defaults,
                  "--instance", os.environ.get("COMPANION_SITL_INSTANCE", "4"),
                  "--port", os.environ.get("COMPANION_SITL_PORT", "14640")], tmp_path, capsys)
    _check_mock_predicts_real(out["autopilots"]["ardupilot"])


def test_px4_sih_flies_the_paper_sine_as_the_mock_predicts(tmp_path, capsys):
    binary = _env_file("COMPANION_SITL_PX4")
    romfs = _env_file("COMPANION_SITL_PX4_ROMFS")
    if not _px4_ports_free():
        pytest.skip("another PX4 SITL holds UDP 14580 (only one can run on this machine)")
    out = _bench(["--px4", binary, "--px4-romfs", romfs], tmp_path, capsys)
    _check_mock_predicts_real(out["autopilots"]["px4"])
