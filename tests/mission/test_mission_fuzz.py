"""Whatever a mission or plan file contains, loading either succeeds or raises MissionError:
never another exception (the CLI would show a traceback)."""

from __future__ import annotations

import copy
import json

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from companion.errors import MissionError
from companion.mission import parse_mission
from companion.mission.qgc import convert, read_plan, read_wpl

VALID = [
    {"name": "f", "speed_m_s": 5.0, "path": {"type": "function", "y_of_x": "sin(x)", "x_range_m": [0, 40]},
     "guidance": {"l1_m": 10.0}, "midcourse": {"circle_radius_m": 10.0},
     "start": {"x_m": -15.0, "y_m": 0.0, "heading_deg": 39.0}},
    {"name": "p", "speed_m_s": 4.0, "path": {"type": "parametric", "x_of_s": "20*cos(s)",
                                             "y_of_s": "20*sin(s)", "s_range": [0, "2*pi"], "closed": True}},
    {"name": "w", "frame": "geodetic", "origin": {"lat_deg": 47.0, "lon_deg": 8.0, "alt_m": 400.0},
     "speed_m_s": 4.0, "path": {"type": "waypoints", "points_deg": [[47.0, 8.0], [47.0005, 8.0], [47.0005, 8.0007]]}},
    {"name": "c", "speed_m_s": 4.0, "path": {"type": "waypoints", "corner_radius_m": 5.0,
                                             "points_m": [[0, 0], [40, 0], [40, 40]]}},
    {"name": "s", "frame": "local_ned", "speed_m_s": 4.0,
     "path": {"type": "segments", "blend_m": 2.0, "segments": [{"type": "line", "length_m": 30.0},
                                                               {"type": "arc", "radius_m": 15.0, "turn_deg": 90.0}]}},
]

JUNK = st.one_of(
    st.none(), st.booleans(), st.integers(-10**6, 10**6),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12),
    st.sampled_from(["2*pi", "x", "s", "sin(", "1e308*1e308", "-0", "closed", "geodetic", "arc"]),
    st.lists(st.floats(-1e3, 1e3), max_size=3),
    st.lists(st.lists(st.floats(-100, 100), min_size=2, max_size=2), max_size=4),
    st.dictionaries(st.sampled_from(["type", "x_m", "length_m", "radius_m", "turn_deg"]),
                    st.integers(-5, 5), max_size=3),
)


def key_paths(doc, prefix=()):
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield prefix + (k,)
            yield from key_paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield prefix + (i,)
            yield from key_paths(v, prefix + (i,))


def mutate(doc, path, value, delete):
    target = doc
    for k in path[:-1]:
        target = target[k]
    if delete:
        del target[path[-1]]
    else:
        target[path[-1]] = value


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(base=st.integers(0, len(VALID) - 1), picks=st.lists(st.tuples(st.integers(0, 10**6), JUNK,
                                                                    st.booleans()), min_size=1, max_size=3))
def test_mutated_missions_load_or_raise_mission_error(base, picks):
    doc = copy.deepcopy(VALID[base])
    for index, value, delete in picks:
        paths = list(key_paths(doc))
        if not paths:
            break
        mutate(doc, paths[index % len(paths)], value, delete)
    text = yaml.safe_dump(doc)
    try:
        parse_mission(text, "fuzz.yaml")
    except MissionError as err:
        assert all(line.startswith("fuzz.yaml") for line in str(err).splitlines())


@settings(max_examples=100, deadline=None)
@given(text=st.text(max_size=200))
def test_arbitrary_text_loads_or_raises_mission_error(text):
    try:
        parse_mission(text, "t.yaml")
    except MissionError:
        pass


PLAN_ITEM = {"autoContinue": True, "command": 16, "doJumpId": 1, "frame": 3,
             "params": [0, 0, 0, None, 47.0, 8.0, 30], "type": "SimpleItem"}


@settings(max_examples=120, deadline=None)
@given(items=st.lists(st.fixed_dictionaries({
    "command": st.sampled_from([16, 16, 16, 17, 20, 21, 22, 82, 177, 178, 183, 206, 31, 5000]),
    "frame": st.sampled_from([0, 2, 3, 10, 1]),
    "lat": st.floats(46.99, 47.01), "lon": st.floats(7.99, 8.01),
    "alt": st.sampled_from([30.0, 30.0, 45.0, None, 0.0]),
}), max_size=8), home=st.booleans())
def test_random_plans_import_or_raise_mission_error(items, home):
    raw = []
    for it in items:
        item = dict(PLAN_ITEM, command=it["command"], frame=it["frame"],
                    params=[0, 5, 0, None, it["lat"], it["lon"], it["alt"]])
        raw.append(item)
    text = json.dumps({"fileType": "Plan", "mission": {
        "items": raw, "plannedHomePosition": [47.0, 8.0, 400.0] if home else None, "vehicleType": 2}})
    try:
        convert(read_plan(text, "f.plan"), "f.plan", name="f")
    except MissionError:
        pass


@settings(max_examples=80, deadline=None)
@given(lines=st.lists(st.lists(st.sampled_from(["0", "1", "3", "16", "-35.1", "149.2", "x", "nan", "22", "20"]),
                               min_size=10, max_size=13), max_size=6))
def test_random_wpl_files_import_or_raise_mission_error(lines):
    text = "QGC WPL 110\n" + "\n".join("\t".join(line) for line in lines) + "\n"
    try:
        convert(read_wpl(text, "f.waypoints"), "f.waypoints", name="f")
    except MissionError:
        pass
