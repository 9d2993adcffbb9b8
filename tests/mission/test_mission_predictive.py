"""Mission keys of ``method: predictive`` and YAML's unquoted ``off``."""

from __future__ import annotations

import math

import pytest

from companion.errors import MissionError
from companion.mission import parse_mission

BASE = """\
name: m
speed_m_s: 5.0
path: {{type: function, y_of_x: "0*x", x_range_m: [0, 100]}}
{extra}
"""


def load(extra: str):
    return parse_mission(BASE.format(extra=extra), "m.yaml")


def test_predictive_keys_reach_the_guidance_params():
    m = load("guidance: {method: predictive, lambda_s4: 0.1, rollout_tau_s: 0.3, a_max_m_s2: 5}")
    g = m.guidance
    assert (g.method, g.lambda_s4, g.rollout_tau_s, g.a_max_m_s2) == ("predictive", 0.1, 0.3, 5.0)


def test_absent_predictive_keys_take_their_documented_defaults():
    g = load("guidance: {method: predictive}").guidance
    assert g.lambda_s4 == 0.03 and g.rollout_tau_s == 0.0 and g.a_max_m_s2 == math.inf


def test_rollout_tau_is_read_for_the_corrector_too():
    assert load("guidance: {method: corrector, rollout_tau_s: 0.25}").guidance.rollout_tau_s == 0.25


@pytest.mark.parametrize("text", ["midcourse: {trigger: off}", "midcourse:\n  trigger: off",
                                  "midcourse: {trigger: 'off'}", "midcourse: {trigger: Off}",
                                  "midcourse: {trigger: false}", "midcourse: {trigger: no}"])
def test_unquoted_off_is_the_trigger_off_not_a_boolean(text):
    # YAML 1.1 reads off, no and false alike as boolean false: all mean "off" here.
    assert load(text).guidance.midcourse_trigger == "off"


@pytest.mark.parametrize("text", ["midcourse: {trigger: on}", "midcourse: {trigger: true}",
                                  "guidance: {method: off}"])
def test_other_booleans_stay_errors(text):
    # true is no choice, and false is "off" only where "off" is a choice (not for method).
    with pytest.raises(MissionError, match=r"expected one of"):
        load(text)


def test_a_bend_beyond_the_vehicle_limit_warns_for_predictive():
    # A 4 m radius arc at 5 m/s needs 6.25 m/s^2, more than a 5 m/s^2 limit.
    text = ("name: m\nspeed_m_s: 5.0\npath: {type: segments, segments: [{type: line, length_m: 20}, "
            "{type: arc, radius_m: 4, turn_deg: 90}, {type: line, length_m: 20}], blend_m: 1}\n")
    tight = parse_mission(text + "guidance: {method: predictive, a_max_m_s2: 5}\n", "m.yaml")
    assert any("a_max_m_s2 = 5" in w for w in tight.warnings)
    loose = parse_mission(text + "guidance: {method: predictive, a_max_m_s2: 8}\n", "m.yaml")
    assert not any("a_max_m_s2" in w for w in loose.warnings)


def test_a_mission_naming_no_method_flies_predictive():
    assert load("").guidance.method == "predictive"
    assert load("guidance: {l1_m: 12}").guidance.method == "predictive"


@pytest.mark.parametrize("name", ["paper_sine.yaml", "paper_far_start.yaml"])
def test_the_papers_scenario_missions_name_the_corrector_explicitly(name):
    from pathlib import Path

    import yaml

    from companion.mission import load_mission

    path = Path(__file__).resolve().parents[2] / "missions" / name
    assert yaml.safe_load(path.read_text())["guidance"]["method"] == "corrector"
    assert load_mission(path).guidance.method == "corrector"
