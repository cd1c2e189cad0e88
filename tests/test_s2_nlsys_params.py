"""plant_nlsys declares a pair's parameters (python-control's ``sys.params``) and refuses them by name on a train;
the linear models and the nlsys name a system name that is no string."""

from __future__ import annotations

import dataclasses

import control as ct
import numpy as np
import pytest

import gearctl
from gearctl import InputError
from gearctl.modes import mode_model, rigid_model, separation_model


@pytest.fixture(scope="module")
def pair() -> gearctl.Plant:
    return gearctl.build_plant(gearctl.load_model("shing1993"))


def _free(sys: ct.NonlinearIOSystem, **kw: object) -> np.ndarray:
    """A short free vibration (50 rad/s on the pinion: impacts within the window), outputs ``s`` and ``force``."""
    T = np.linspace(0.0, 1e-3, 101)
    r = ct.input_output_response(sys, T, 0.0, [0.0, 0.0, 50.0, 0.0],
                                 solve_ivp_kwargs={"rtol": 1e-9, "atol": 1e-13}, **kw)
    return r.outputs[4:]


def test_a_pair_declares_backlash_k_and_c(pair) -> None:  # noqa: ANN001
    sys = gearctl.plant_nlsys(pair)
    # python-control's convention: a system's parameters and their defaults are in sys.params (it was {})
    assert sys.params == {"backlash": pair.backlash, "k": pair.k, "c": pair.c}
    # the declared values are the plant's: passing them changes nothing
    np.testing.assert_array_equal(_free(sys, params=dict(sys.params)), _free(sys))
    # an override is the plant with that value (oracle: the nlsys of the replaced plant)
    wide = dataclasses.replace(pair, backlash=2 * pair.backlash)
    np.testing.assert_allclose(_free(sys, params={"backlash": 2 * pair.backlash}), _free(gearctl.plant_nlsys(wide)),
                               rtol=0, atol=1e-12 * np.abs(_free(gearctl.plant_nlsys(wide))).max())


def test_a_train_declares_none_and_names_params() -> None:
    train = gearctl.build_plant(gearctl.load_model("servo_2stage_phm09"))
    sys = gearctl.plant_nlsys(train)
    assert sys.params == {}
    T = np.linspace(0.0, 1e-4, 11)
    # was: "backlash: the report's pair names apply to a one-stage plant ..." naming backlash, not params
    with pytest.raises(InputError, match=r"^params = \{'backlash': 0\.0001\}: .* on a pair only") as err:
        ct.input_output_response(sys, T, 0.0, np.zeros(6), params={"backlash": 1e-4})
    assert err.value.field == "params"


@pytest.mark.parametrize("make", [
    lambda p: gearctl.plant_nlsys(p, name=3),
    lambda p: gearctl.contact_mode_model(p, name=3),
    lambda p: separation_model(p, name=1.5),
    lambda p: rigid_model(p, name=["rigid"]),
    lambda p: mode_model(p, [True], name=b"x"),
])
def test_a_system_name_that_is_no_string_is_named(pair, make) -> None:  # noqa: ANN001
    # python-control raised TypeError: expected string or bytes-like object (from a regex deep inside)
    with pytest.raises(InputError, match=r"^name = .* is not a system name") as err:
        make(pair)
    assert err.value.field == "name"


def test_a_name_of_none_is_python_controls_generated_one(pair) -> None:  # noqa: ANN001
    assert separation_model(pair, name=None).name.startswith("sys[")
    assert gearctl.plant_nlsys(pair, name=None).name == "gear_improved"
