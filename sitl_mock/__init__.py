"""sitl_mock: a mock PX4/ArduPilot autopilot speaking real MAVLink over UDP. Never imports companion."""
