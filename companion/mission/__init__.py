"""Mission files: the YAML format, its validation, and imports from QGroundControl.

Public API::

    from companion.mission import load_mission, parse_mission, Mission, StartState

    mission = load_mission("missions/paper_sine.yaml")
    mission.path.length_m, mission.guidance.l1_m, mission.start

The format is described in ``docs/missions.md`` and, as data, in
:mod:`companion.mission.schema` (the one source of truth for the validator and
``mission.schema.json``).
"""

from companion.mission.loader import (
    MAX_FILE_BYTES,
    check_mission_text,
    load_mission,
    parse_mission,
    read_mission_text,
)
from companion.mission.model import GeodeticOrigin, Mission, StartState

__all__ = [
    "MAX_FILE_BYTES",
    "GeodeticOrigin",
    "Mission",
    "StartState",
    "check_mission_text",
    "load_mission",
    "parse_mission",
    "read_mission_text",
]
