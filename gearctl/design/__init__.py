"""Controllers for the sampled position loop: PID baseline, dead-zone inverse, reversal offset, adaptive
inverse, MPC.

Every controller implements :class:`gearctl.controller.Controller`: it sees only the sensor signals
(motor and, optionally, load encoder) and the reference, never the plant state; what it needs beyond that
it estimates itself. One controller per module; :mod:`gearctl.design.registry` builds them from
controller files. Importing this package is light: python-control and CasADi load when a design needs
them.
"""

from .base import Controller, LoopInfo, loop_info

__all__ = ["Controller", "LoopInfo", "loop_info"]
