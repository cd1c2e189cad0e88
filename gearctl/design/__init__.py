"""Controllers for the sampled position loop: PID baseline, dead-zone inverse, MPC.

Every controller implements :class:`~gearctl.design.base.Controller`: it sees only the sensor signals
(motor and, optionally, load encoder) and the reference, never the plant state; what it needs beyond
that it estimates itself.
"""

from .base import Controller, LoopInfo, loop_info
from .deadzone import DeadzoneInverse
from .pid import PID, PIDGains, design_pid

__all__ = ["Controller", "LoopInfo", "loop_info", "PID", "PIDGains", "design_pid", "DeadzoneInverse"]
