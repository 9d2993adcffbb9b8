"""One description of the format: the validator and the committed JSON Schema come from it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from companion.errors import MissionError
from companion.geometry.profile import ProfileLimits
from companion.guidance.types import GuidanceParams
from companion.mission import parse_mission
from companion.mission.schema import MISSION, Object, Tagged, json_schema, json_schema_text

SCHEMA_FILE = Path(__file__).resolve().parents[2] / "companion" / "mission" / "mission.schema.json"


def test_committed_json_schema_is_generated_from_the_python_description():
    assert SCHEMA_FILE.read_text() == json_schema_text(), (
        "regenerate: companion mission schema > companion/mission/mission.schema.json")


def test_every_json_object_refuses_unknown_keys():
    def walk(node, where="$"):
        if isinstance(node, dict):
            if node.get("type") == "object" and "properties" in node:
                assert node.get("additionalProperties") is False, where
            for key, value in node.items():
                walk(value, f"{where}.{key}")
        elif isinstance(node, list):
            for i, value in enumerate(node):
                walk(value, f"{where}[{i}]")

    walk(json_schema())
    assert json.loads(json_schema_text())["title"] == "companion mission"


def test_guidance_defaults_agree_with_guidance_params():
    g = MISSION.fields["guidance"].spec.fields
    m = MISSION.fields["midcourse"].spec.fields
    defaults = GuidanceParams()
    # One documented exception: a mission that names no method flies predictive, while
    # GuidanceParams() keeps the paper's corrector for code that builds the guidance itself.
    assert g["method"].default == "predictive" and defaults.method == "corrector"
    assert g["l1_m"].default == defaults.l1_m
    assert g["rate_hz"].default == defaults.rate_hz
    assert g["k1_max"].default == defaults.k1_max
    assert g["k2_max"].default == defaults.k2_max
    assert g["d_limit_factor"].default == defaults.d_limit_factor
    assert g["rollout_tau_s"].default == defaults.rollout_tau_s
    # lambda_s4 has no schema default: absent, the loader fills GuidanceParams' and notes that the
    # mission stated none (a flight that compensates the slow tail then flies another).
    assert "default" not in json_schema()["properties"]["guidance"]["properties"]["lambda_s4"]
    m_line = parse_mission("{name: l, speed_m_s: 5, path: {type: waypoints, points_m: [[0, 0], [50, 0]]}}")
    assert m_line.guidance.lambda_s4 == defaults.lambda_s4 and not m_line.lambda_stated
    stated = parse_mission("{name: l, speed_m_s: 5, path: {type: waypoints, points_m: [[0, 0], [50, 0]]}, "
                           "guidance: {lambda_s4: 0.5}}")  # not the default: the value read is the one stated
    assert stated.guidance.lambda_s4 == 0.5 and stated.lambda_stated
    assert m["circle_radius_m"].default == defaults.circle_radius_m
    assert m["trigger"].default == defaults.midcourse_trigger


def test_profile_limit_defaults_agree_with_profile_limits():
    v = MISSION.fields["vertical"].spec.fields
    a = MISSION.fields["along_track"].spec.fields
    limits = ProfileLimits()
    assert (v["climb_max_m_s"].default, v["sink_max_m_s"].default, v["accel_max_m_s2"].default,
            v["alt_gain_1_s"].default) == (limits.climb_max_m_s, limits.sink_max_m_s,
                                          limits.vert_accel_max_m_s2, limits.alt_gain_1_s)
    assert (a["accel_max_m_s2"].default, a["turn_accel_share"].default) == (limits.along_accel_max_m_s2,
                                                                           limits.turn_accel_share)


def test_every_key_name_carries_its_unit_or_is_unitless_by_nature():
    unitless = {"version", "name", "frame", "origin", "path", "guidance", "vehicle", "midcourse", "on_finish",
                "start", "type", "y_of_x", "x_of_s", "y_of_s", "s_range", "closed", "method",
                "k1_max", "k2_max", "d_limit_factor", "trigger", "segments", "vertical",
                "along_track", "tail_share", "turn_accel_share", "accel_feedforward", "accel_ff_gain",
                "tail_compensation"}
    suffixes = ("_m", "_m_s", "_m_s2", "_m_s3", "_deg", "_hz", "_s", "_s2", "_s4")

    def walk(spec, where=""):
        if isinstance(spec, Tagged):
            for variant in spec.variants.values():
                walk(variant, where)
        elif isinstance(spec, Object):
            for key, fld in spec.fields.items():
                assert key in unitless or key.endswith(suffixes), f"{where}{key}"
                walk(fld.spec, f"{where}{key}.")
        elif hasattr(spec, "items"):
            walk(spec.items, where)

    walk(MISSION)


@pytest.mark.parametrize(
    "extra, key",
    [
        ("origin: {lat_deg: 47, lon_deg: 8, altitude: 3}\nframe: geodetic\n", "origin.altitude"),
        ("midcourse: {radius_m: 10}\n", "midcourse.radius_m"),
        ("start: {x_m: 0, y_m: 0, heading_deg: 0, speed: 3}\n", "start.speed"),
        ("guidance: {method: corrector, L1_m: 10}\n", "guidance.L1_m"),
    ],
)
def test_typos_are_errors_at_every_level(extra, key):
    text = "name: t\nspeed_m_s: 4\npath: {type: waypoints, points_m: [[0, 0], [50, 0]]}\n" + extra
    with pytest.raises(MissionError) as info:
        parse_mission(text, "t.yaml")
    assert f"t.yaml: {key}: unknown key; expected one of" in str(info.value)


def test_typo_inside_a_segment_names_its_index():
    text = ("name: t\nspeed_m_s: 4\npath:\n  type: segments\n  segments:\n"
            "    - {type: line, length_m: 50}\n    - {type: arc, radius_m: 20, angle_deg: 90}\n")
    with pytest.raises(MissionError) as info:
        parse_mission(text, "t.yaml")
    lines = str(info.value).splitlines()
    assert "t.yaml: path.segments[1].angle_deg: unknown key; expected one of type, radius_m, turn_deg" in lines
    assert "t.yaml: path.segments[1].turn_deg: missing; expected a finite number >= -360 and <= 360 and != 0" in lines


def test_defaults_fill_in_an_issue_two_mission():
    m = parse_mission("name: d\nspeed_m_s: 3\npath: {type: waypoints, points_m: [[0, 0], [40, 0]]}\n")
    assert (m.altitude_m, m.on_finish, m.frame, m.start, m.origin) == (10.0, "hold", "local_enu", None, None)
    assert m.guidance == GuidanceParams(speed_m_s=3.0, method="predictive")
