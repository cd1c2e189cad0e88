"""The controller-building API a user reaches from Python (gearctl.design: PIDGains, PIDDesign, design_pid, PID,
the inverse, the reversal offset, loop_info, the reading checks) documents every parameter, with the check of
tests/test_docstring_parameters.py (which covers gearctl.__all__, not gearctl.design)."""

from __future__ import annotations

import inspect
import re

from test_docstring_parameters import class_problems, function_problems

from gearctl.controller import check_reading
from gearctl.describe import MeshBacklash
from gearctl.design.base import LoopInfo, check_loop_info, loop_info
from gearctl.design.deadzone import DeadzoneInverse
from gearctl.design.pid import PID, PIDDesign, PIDGains, check_readings, design_pid
from gearctl.modes import ContactModes

#: The constructors and functions a user calls to build and analyse a controller in Python. (Methods that only a
#: wrapper calls, e.g. DeadzoneInverse.flank, are left to the module's own docs.)
USER_API = [PIDGains, PIDDesign, design_pid, PID, check_readings, loop_info, check_loop_info, LoopInfo,
            check_reading, ContactModes, MeshBacklash]


def test_every_parameter_of_the_design_api_is_documented() -> None:
    problems = []
    for obj in USER_API:
        check = class_problems if inspect.isclass(obj) else function_problems
        problems += check(obj.__qualname__, obj)
    # the constructor of the inverse: jump_floor was undocumented
    problems += [p for p in class_problems("DeadzoneInverse", DeadzoneInverse) if p.startswith("DeadzoneInverse:")]
    assert problems == []


def test_pid_docstring_names_methods_that_exist() -> None:
    # PID's Notes and PID.torque named a method reference_acceleration, which does not exist (reference_update)
    for doc in (PID.__doc__, PID.torque.__doc__):
        for name in re.findall(r":meth:`(\w+)`", doc or ""):
            assert hasattr(PID, name), name
