"""sitl_mock: a mock PX4/ArduPilot autopilot speaking real MAVLink over UDP. Never imports companion.

Run it with ``sitl-mock`` or ``python -m sitl_mock`` (see ``docs/sitl_mock.md``). Modules:
``vehicle`` (point-mass model), ``personality`` (PX4 / ArduPilot identity, modes, parameters),
``flight`` (modes, setpoints, failsafes), ``links`` (UDP, frame checks, signing, tlog),
``autopilot`` (message handling, streams, run loop), ``cli`` (options, ``main``).
"""
