"""Every malformed mission in ``tests/mission/bad/`` fails ``companion mission check`` the same way:
exit code 2, exactly one line on stderr naming the file, the key and what was expected, no traceback.

Each file's first line is ``# expect: <text the error line must contain>``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from companion.cli.main import main
from companion.errors import MissionError
from companion.mission import MAX_FILE_BYTES, load_mission

BAD = Path(__file__).parent / "bad"
FILES = sorted(BAD.glob("*.yaml"))


def expected_text(path: Path) -> str:
    first = path.read_text().splitlines()[0]
    assert first.startswith("# expect: "), f"{path.name}: first line must be '# expect: ...'"
    return first[len("# expect: "):]


def test_the_corpus_has_at_least_25_files():
    assert len(FILES) >= 25


@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_malformed_mission_gives_its_one_line_error_and_exit_2(path, capsys):
    code = main(["mission", "check", str(path)])
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert code == 2
    assert "Traceback" not in err and out == ""
    assert len(lines) == 1, err
    assert lines[0].startswith(f"{path}: ")
    assert expected_text(path) in lines[0]


@pytest.mark.parametrize("path", FILES[:5], ids=[p.stem for p in FILES[:5]])
def test_loading_a_malformed_mission_raises_mission_error_and_other_commands_exit_2(path, capsys):
    with pytest.raises(MissionError) as info:
        load_mission(path)
    assert expected_text(path) in str(info.value)
    code = main(["mission", "show", str(path)])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert err.startswith("companion: error: ") and expected_text(path) in err


def _check(path: Path, capsys) -> tuple[int, str]:
    code = main(["mission", "check", str(path)])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    return code, captured.err


def test_huge_file_is_refused_before_reading(tmp_path, capsys):
    path = tmp_path / "huge.yaml"
    with path.open("w") as f:
        f.write("name: huge\nspeed_m_s: 5\n# " + "x" * (MAX_FILE_BYTES + 10) + "\n")
    code, err = _check(path, capsys)
    assert code == 2
    assert err.strip() == (f"{path}: expected a mission file of at most {MAX_FILE_BYTES} bytes, "
                           f"got {path.stat().st_size} bytes")


def test_binary_file_is_refused(tmp_path, capsys):
    path = tmp_path / "image.yaml"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(range(256)))
    code, err = _check(path, capsys)
    assert code == 2 and err.strip() == f"{path}: expected a YAML text file, got binary data"


def test_latin1_text_is_refused_as_not_utf8(tmp_path, capsys):
    path = tmp_path / "latin1.yaml"
    path.write_bytes("name: caf\xe9\nspeed_m_s: 5\n".encode("latin-1"))
    code, err = _check(path, capsys)
    assert code == 2 and "expected a UTF-8 YAML text file, got an invalid byte at offset 9" in err


def test_json_or_prose_is_refused_as_not_a_mission(tmp_path, capsys):
    path = tmp_path / "notes.yaml"
    path.write_text("This is a note about the flight, not a mission.\n")
    code, err = _check(path, capsys)
    assert code == 2
    assert "expected a YAML mapping of mission keys (name, speed_m_s, path, ...), got 'This is" in err


def test_missing_file_and_directory_are_refused(tmp_path, capsys):
    code, err = _check(tmp_path / "nope.yaml", capsys)
    assert code == 2 and err.strip() == f"{tmp_path / 'nope.yaml'}: file not found"
    code, err = _check(tmp_path, capsys)
    assert code == 2 and "expected a mission file, got a directory" in err


def test_a_file_with_many_problems_lists_every_one(tmp_path, capsys):
    path = tmp_path / "many.yaml"
    path.write_text("name: many\nspeed_m_s: 0\npath: {type: waypoints, points_m: [[0, 0], [.nan, 1]]}\n"
                    "guidance: {method: magic, l1_m: -1}\nonfinish: hold\n")
    code, err = _check(path, capsys)
    lines = err.splitlines()
    assert code == 2
    keys = [line.split(": ")[1] for line in lines]
    assert keys == ["onfinish", "speed_m_s", "path.points_m[1][0]", "guidance.method", "guidance.l1_m"]
