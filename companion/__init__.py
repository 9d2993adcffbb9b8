"""companion: offboard path-following guidance for PX4 and ArduPilot vehicles.

Layers (each a sub-package; see docs/architecture.md):

- ``geometry``  frames and reference paths (pure maths)
- ``guidance``  the guidance laws and the two-phase guidance object (pure maths)
- ``sim``       offline simulator and the metrics every command reports (pure maths)
- ``mission``   mission files: schema, loading, validation, imports
- ``io``        the MAVLink link, message conversion, tlogs (pymavlink lives here only)
- ``loop``      fixed-rate scheduler and the flight runner
- ``replay``    re-running the guidance on a logged flight
- ``bench``     benchmarks
- ``cli``       the ``companion`` command
"""

__version__ = "0.1.0"
