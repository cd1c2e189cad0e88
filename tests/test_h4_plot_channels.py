"""plot_bode / plot_step on a train's mode models with the default channel, and a bad signal name by name."""

from __future__ import annotations

import pytest

import gearctl
from gearctl import InputError
from gearctl.plots import plot_bode, plot_step


def test_default_channel_is_the_motor_on_a_train_too() -> None:
    modes = gearctl.linearize_modes(gearctl.build_plant(gearctl.load_model("servo_2stage_phm09")))
    fig = plot_bode({"contact": modes.contact, "separation": modes.separation, "rigid": modes.rigid})
    assert fig.axes[0].get_title() == "xi0 -> theta0"
    fig = plot_step({"contact": modes.contact}, output="s2", T=[0.0, 1e-3, 2e-3])
    assert fig.axes[0].get_title() == "Step of xi0 -> s2"


@pytest.mark.parametrize("kw,field", [({"output": "theta1"}, "output"), ({"input": "xi1"}, "input")])
def test_a_signal_the_model_lacks_is_named(kw: dict[str, str], field: str) -> None:
    modes = gearctl.linearize_modes(gearctl.build_plant(gearctl.load_model("servo_2stage_phm09")))
    for plot in (plot_bode, plot_step):
        with pytest.raises(InputError, match=rf"^{field} = '\w+' is not a signal of system 'contact': expected one of"):
            plot({"contact": modes.contact}, **kw)
