"""Argument errors of the Python API a script writer meets: one ``InputError`` naming the argument, not a
``TypeError`` or ``AttributeError`` from deep inside."""

from __future__ import annotations

import numpy
import pytest

import gearctl
from gearctl import InputError


@pytest.fixture(scope="module")
def servo():  # noqa: ANN201
    model = gearctl.load_model("shing1993_servo")
    plant = gearctl.build_plant(model)
    return model, plant, gearctl.load_controller("pid", plant)


def test_reference_unknown_setting_is_named() -> None:
    with pytest.raises(InputError, match=r"amplitud .*did you mean 'amplitude'") as err:
        gearctl.reference("sine", amplitud=0.1)
    assert err.value.field == "amplitud"
    assert gearctl.reference("move", amplitude=0.3, profile="trapezoid").amplitude == 0.3


@pytest.mark.parametrize("ref", ["sine", lambda t: 0.1, None])
def test_closed_loop_refuses_a_non_reference(servo, ref) -> None:  # noqa: ANN001
    _, plant, ctrl = servo
    with pytest.raises(InputError, match=r"^ref = .* is not a reference") as err:
        gearctl.simulate_closed_loop(plant, ctrl, ref, 0.05)
    assert err.value.field == "ref"


def test_closed_loop_refuses_a_non_controller_and_bad_sensors(servo) -> None:  # noqa: ANN001
    _, plant, _ = servo
    with pytest.raises(InputError, match=r"^controller = None is not a controller"):
        gearctl.simulate_closed_loop(plant, None, gearctl.reference("sine"), 0.05)
    _, plant, ctrl = servo
    with pytest.raises(InputError, match=r"^sensors = 'ideal' is not a Sensors"):
        gearctl.simulate_closed_loop(plant, ctrl, gearctl.reference("sine"), 0.05, sensors="ideal")


def test_loop_margins_refuses_a_mimo_model(servo) -> None:  # noqa: ANN001
    _, plant, _ = servo
    contact = gearctl.linearize_modes(plant).contact
    with pytest.raises(InputError, match=r"loop has 2 inputs and 4 outputs: expected a SISO open loop") as err:
        gearctl.loop_margins(contact)
    assert err.value.field == "loop"
    with pytest.raises(InputError, match=r"not a python-control LTI system"):
        gearctl.loop_margins([1.0, 2.0])


def test_mode_model_needs_one_entry_per_stage(servo) -> None:  # noqa: ANN001
    from gearctl.modes import mode_model

    _, plant, _ = servo
    with pytest.raises(InputError, match=r"loaded = \[True, False\] has 2 entries: expected one per stage \(1\)"):
        mode_model(plant, [True, False])
    assert mode_model(plant, [False]).nstates == 4


@pytest.mark.parametrize("torque", [1.0, (1.0, 2.0, 3.0), ("a", 0.0), (float("nan"), 0.0)])
def test_simulate_refuses_a_torque_that_is_no_pair(servo, torque) -> None:  # noqa: ANN001
    from gearctl.simulate import simulate

    _, plant, _ = servo
    with pytest.raises(InputError, match=r"^torque = .* is not a torque: expected \(xi_motor, xi_load\)") as err:
        simulate(plant, [0, 0, 0, 0], 0.01, torque=torque)
    assert err.value.field == "torque"
    assert simulate(plant, [0, 0, 0, 0], 0.01, torque=[0.1, 0]).success


@pytest.mark.parametrize("obj", [None, "pid", object()])
def test_export_refuses_a_non_controller(obj, tmp_path) -> None:  # noqa: ANN001
    from gearctl.export import export_controller

    with pytest.raises(InputError, match=r"cannot be exported: expected one of gearctl's controller kinds") as err:
        export_controller(obj, tmp_path / "out")
    assert err.value.field == "controller"
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"cycles": 2.5}, r"^cycles = 2.5 is not a whole number: expected a whole number in \[1, 50\]"),
    ({"targets": True}, r"^targets = True is not a whole number"),
    ({"targets": 1}, r"^targets = 1 is out of range: expected a whole number in \[2, 50\]"),
    ({"seed": -1}, r"^seed = -1 is out of range"),
    ({"seed": 1.5}, r"^seed = 1.5 is not a whole number"),
])
def test_precision_test_checks_counts_and_seed(servo, kwargs, message) -> None:  # noqa: ANN001
    _, plant, ctrl = servo
    with pytest.raises(InputError, match=message):
        gearctl.precision_test(plant, ctrl, **kwargs)


def test_sweep_takes_one_vary_string_as_one_key() -> None:
    from gearctl.sweep import sweep

    one = sweep("shing1993_servo", "pid", vary="backlash=0.5x:2x", runs=2, engine="serial", duration=0.2)
    listed = sweep("shing1993_servo", "pid", vary=["backlash=0.5x:2x"], runs=2, engine="serial", duration=0.2)
    assert [r["params"] for r in one.runs] == [r["params"] for r in listed.runs]
    assert [r["rms_error"] for r in one.runs] == [r["rms_error"] for r in listed.runs]


def test_build_plant_and_load_controller_name_what_they_need(servo) -> None:  # noqa: ANN001
    with pytest.raises(InputError, match=r"model = 'shing1993_servo' is not a gear model: load it first, "
                                         r"gearctl.load_model\('shing1993_servo'\)"):
        gearctl.build_plant("shing1993_servo")
    with pytest.raises(InputError, match=r"^plant = None is not a Plant"):
        gearctl.load_controller("pid", None)
    model, _, _ = servo
    with pytest.raises(InputError, match=r"^plant = .* is not a Plant"):
        gearctl.load_controller("pid", model)


@pytest.mark.parametrize("settle", [-1.0, 5.0, float("nan"), "0.1"])
def test_tracking_metrics_refuses_a_settle_time_outside_the_run(servo, settle) -> None:  # noqa: ANN001
    _, plant, ctrl = servo
    run = gearctl.simulate_closed_loop(plant, ctrl, gearctl.reference("sine"), 0.7)
    with pytest.raises(InputError, match=r"^settle = .* is out of range: expected 0 <= value <= 0.7 \[s\]") as err:
        gearctl.tracking_metrics(run, settle=settle)
    assert err.value.field == "settle"
    whole = gearctl.tracking_metrics(run, settle=0.0).rms_error
    assert gearctl.tracking_metrics(run, settle=0.6).rms_error != whole


def _plant_takers() -> list:  # noqa: ANN202 - (label, call taking the plant) of every documented plant-taking function
    from gearctl.modes import mesh_mode, mode_model
    from gearctl.simulate import report_case, simulate

    return [
        ("linearize_modes", gearctl.linearize_modes), ("contact_mode_model", gearctl.contact_mode_model),
        ("separation_model", gearctl.separation_model), ("rigid_model", gearctl.rigid_model),
        ("mode_model", lambda p: mode_model(p, [True])), ("mesh_mode", mesh_mode),
        ("plant_nlsys", gearctl.plant_nlsys), ("simulate", lambda p: simulate(p, [0.0] * 4, 0.01)),
        ("report_case", lambda p: report_case(p, "free", 0.01)),
        ("simulate_closed_loop", lambda p: gearctl.simulate_closed_loop(p, None, None, 0.05)),
        ("precision_test", lambda p: gearctl.precision_test(p, None)),
    ]


@pytest.mark.parametrize("label, call", _plant_takers(), ids=[label for label, _ in _plant_takers()])
def test_plant_functions_refuse_a_gear_model_by_name(servo, label, call) -> None:  # noqa: ANN001
    model, plant, _ = servo
    with pytest.raises(InputError, match=r"^plant = <GearModel 'shing1993_servo'> is not a Plant: build it first, "
                                         r"gearctl.build_plant\(model\)$") as err:
        call(model)
    assert err.value.field == "plant"
    with pytest.raises(InputError, match=r"^plant = 'shing1993_servo' is not a Plant: build it first, "
                                         r"gearctl.build_plant\(gearctl.load_model\('shing1993_servo'\)\)$"):
        call("shing1993_servo")
    with pytest.raises(InputError, match=r"^plant = None is not a Plant"):
        call(None)


@pytest.mark.parametrize("loaded", [["separation"], ["front"], [None], [0.5], [2], "contact", True])
def test_mode_model_refuses_what_is_no_contact_mode(servo, loaded) -> None:  # noqa: ANN001
    from gearctl.modes import mode_model

    _, plant, _ = servo
    with pytest.raises(InputError, match=r"^loaded(\[0\])? = .* is not a (contact mode|sequence)") as err:
        mode_model(plant, loaded)
    assert err.value.field == "loaded"


def test_mode_model_reads_modes_as_contact_or_separation() -> None:
    import numpy as np

    from gearctl.modes import mode_model

    train = gearctl.build_plant(gearctl.load_model("servo_3stage_quanser_srv02"))
    sep = gearctl.Mode.SEPARATION
    for modes, flags in (([gearctl.Mode.FRONT, sep, gearctl.Mode.BACK], [True, False, True]),
                         (np.array([0, -1, 0]), [False, True, False]), (np.array([True, False, False]), None)):
        flags = flags if flags is not None else [bool(v) for v in modes]
        np.testing.assert_array_equal(mode_model(train, modes).A, mode_model(train, flags).A)
    # the separated stage's force is zero, a loaded one's is not
    sys = mode_model(train, [gearctl.Mode.FRONT, sep, gearctl.Mode.BACK])
    force = [sys.C[sys.output_labels.index(f"force{i}")] for i in (1, 2, 3)]
    assert np.any(force[0]) and not np.any(force[1]) and np.any(force[2])


def test_mode_model_refuses_to_separate_a_stage_without_backlash() -> None:
    import numpy as np

    from gearctl.modes import mode_model

    model = gearctl.load_model("servo_2stage_phm09")
    train = gearctl.build_plant(model, backlash=[0.0, model.stages[1].pair.backlash])
    with pytest.raises(InputError, match=r"^loaded\[0\] = False: stage 1 has no backlash .* cannot separate") as err:
        mode_model(train, [False, True])
    assert err.value.field == "loaded"
    # stage 2 has a gap: separating it alone is the linearize_modes model
    np.testing.assert_array_equal(mode_model(train, [True, False]).A,
                                  gearctl.linearize_modes(train).stage_separated[1].A)
    pair = gearctl.build_plant(gearctl.load_model("shing1993_servo"), backlash=0.0)
    with pytest.raises(InputError, match=r"the pair has no backlash"):
        mode_model(pair, [gearctl.Mode.SEPARATION])
    assert gearctl.separation_model(pair).nstates == 4


def test_per_stage_backlash_takes_a_numpy_array_and_refuses_other_shapes() -> None:
    import numpy as np

    model = gearctl.load_model("servo_3stage_quanser_srv02")
    b = np.array([1e-5, 2e-5, 3e-5])
    plant = gearctl.build_plant(model, backlash=b)
    assert plant.backlashes == (1e-5, 2e-5, 3e-5)
    assert plant.with_backlash(2 * b).backlashes == (2e-5, 4e-5, 6e-5)
    assert model.with_backlash(b).stages[2].pair.backlash == 3e-5
    assert gearctl.build_plant(model, backlash=np.float64(1e-5)).backlashes == (1e-5,) * 3
    assert gearctl.build_plant(model, backlash=np.array(1e-5)).backlashes == (1e-5,) * 3
    with pytest.raises(InputError, match=r"has 2 values: expected 1 or one per stage \(3\)"):
        plant.with_backlash(b[:2])
    with pytest.raises(InputError, match=r"is not a backlash: expected one number, or a list or 1-D array"):
        gearctl.build_plant(model, backlash=np.ones((3, 1)) * 1e-5)
    with pytest.raises(InputError, match=r"is not a backlash"):
        gearctl.build_plant(model, backlash=[[1e-5], [1e-5, 2e-5], 1e-5])
    with pytest.raises(InputError, match=r"^backlash = '5e-5' is not a number \(a string"):
        model.with_backlash("5e-5")
    with pytest.raises(InputError, match=r"^backlash = -1.0 is out of range"):
        plant.with_backlash(np.array([1e-5, -1.0, 1e-5]))


@pytest.mark.parametrize("value", [(1.0, 2.0, 3.0), 0.1, (float("nan"), 0.0), None])
def test_simulate_refuses_a_torque_function_value_that_is_no_pair(servo, value) -> None:  # noqa: ANN001
    import numpy as np

    from gearctl.simulate import simulate

    _, plant, _ = servo
    with pytest.raises(InputError, match=r"^torque\(t, x\) = .* at t = 0.002 s is not a torque") as err:
        simulate(plant, [0, 0, 0, 0], 0.01, dt=1e-3, torque=lambda t, x: value if t > 1.5e-3 else (0.1, 0.0))
    assert err.value.field == "torque"
    run = simulate(plant, [0, 0, 0, 0], 0.01, dt=1e-3, torque=lambda t, x: np.array([0.1, 0.0]))
    assert run.success and run.x[2, -1] > 0


@pytest.mark.parametrize("kwargs, field, rule", [
    ({"x0": "zero"}, "x0", "is not an initial state"), ({"x0": ["a", 0, 0, 0]}, "x0", "is not an initial state"),
    ({"x0": [[0, 0], [0, 0]]}, "x0", "is not an initial state"),
    # a string or a bool is named as such, as every other number's check does (it was 'is out of range', and
    # True ran as 1 s)
    ({"dt": "1e-3"}, "dt", r"is not a number \(a string"), ({"dt": True}, "dt", r"is not a number \(true/false\)"),
    ({"dt": -1e-3}, "dt", r"is out of range: expected 0 < value \[s\]")])
def test_simulate_names_an_initial_state_or_interval_that_is_no_number(servo, kwargs, field, rule) -> None:  # noqa: ANN001
    from gearctl.simulate import simulate

    _, plant, _ = servo
    args = {"x0": [0.0] * 4, **kwargs}
    with pytest.raises(InputError, match=rf"^{field} = .* {rule}") as err:
        simulate(plant, args.pop("x0"), 0.01, **args)
    assert err.value.field == field


@pytest.mark.parametrize("omega", [-1.0, [10.0], [[1.0, 2.0], [3.0, 4.0]], [0.0, 1.0, 2.0], [3.0, 2.0, 1.0],
                                   [1.0, float("nan")], "1,2,3", numpy.ones((3, 3))])
def test_loop_margins_refuses_what_is_no_frequency_grid(omega) -> None:  # noqa: ANN001
    import control as ct
    import numpy as np

    loop = ct.tf([4.0], [1.0, 2.0, 1.0, 0.0])
    with pytest.raises(InputError, match=r"^omega = [^\n]* is not a frequency grid") as err:
        gearctl.loop_margins(loop, omega=omega)
    assert err.value.field == "omega"
    # a grid given as a list reads as the default grid does (K/(s (s+1)^2): crossover where 4 = w (1 + w^2))
    got = gearctl.loop_margins(loop, omega=list(np.logspace(-2, 2, 20000)))
    wc = np.roots([1.0, 0.0, 1.0, -4.0])
    wc = float(wc[np.abs(wc.imag) < 1e-12].real[0])
    np.testing.assert_allclose(got["gain_crossover_hz"], wc / (2 * np.pi), rtol=1e-3)


def test_mesh_stiffness_and_geometry_name_a_model_given_for_its_pair() -> None:
    pair_model = gearctl.load_model("shing1993")
    train_model = gearctl.load_model("servo_2stage_phm09")
    with pytest.raises(InputError, match=r"^pair = <GearModel 'shing1993'> is not a GearPair: pass its gear pair, "
                                         r"model.pair$") as err:
        gearctl.mesh_stiffness(pair_model)
    assert err.value.field == "pair"
    with pytest.raises(InputError, match=r"a train of 2 stages, pass one stage's gear pair, model.stages\[i\].pair"):
        gearctl.pair_geometry(train_model)
    with pytest.raises(InputError, match=r"^pair = 'shing1993' is not a GearPair"):
        gearctl.mesh_stiffness("shing1993")
    assert gearctl.mesh_stiffness(train_model.stages[1].pair).mean > 0


@pytest.mark.parametrize("field", ["model", "controller"])
def test_a_name_that_is_no_string_is_named(servo, field) -> None:  # noqa: ANN001
    # load_model(123) ended in pathlib's "expected str, bytes or os.PathLike object, not int"
    _, plant, _ = servo
    load = gearctl.load_model if field == "model" else (lambda name: gearctl.load_controller(name, plant))
    with pytest.raises(InputError, match=rf"^{field} = 123 is not a name or a path \(a int\): expected") as err:
        load(123)
    assert err.value.field == field
    with pytest.raises(InputError, match=rf"^{field} = b'pid' is not a name or a path \(a bytes\)"):
        load(b"pid")


class _PathLike:
    """A path-like that is no pathlib.Path (as py.path.local or os.DirEntry)."""

    def __init__(self, path: str) -> None:
        self.path = path

    def __fspath__(self) -> str:
        return self.path


def test_a_path_like_name_is_read(servo) -> None:  # noqa: ANN001
    # 84b9a3d refused whatever was no str or Path: an os.PathLike, which pathlib reads, too
    from pathlib import Path

    _, plant, _ = servo
    root = Path(__file__).resolve().parents[1]
    assert gearctl.load_model(_PathLike(str(root / "models" / "shing1993.toml"))).name == "shing1993"
    assert gearctl.load_controller(_PathLike(str(root / "controllers" / "pid.toml")), plant).name == "pid"


def test_tracking_metrics_refuses_what_is_no_run(servo) -> None:  # noqa: ANN001
    # tracking_metrics(None) ended in "'NoneType' object has no attribute 't'"
    _, plant, ctrl = servo
    with pytest.raises(InputError, match=r"^res = None is not a closed-loop run \(a NoneType\): expected") as err:
        gearctl.tracking_metrics(None)
    assert err.value.field == "res"
    run = gearctl.simulate_closed_loop(plant, ctrl, gearctl.reference("sine"), 0.05)
    assert gearctl.tracking_metrics(run).duration == pytest.approx(0.05, abs=1e-3)


@pytest.mark.parametrize("call", [gearctl.linearize_modes, gearctl.mesh_stiffness, gearctl.pair_geometry,
                                  lambda v: gearctl.loop_margins(gearctl.linearize_modes(
                                      gearctl.build_plant(gearctl.load_model("shing1993_servo"))).motor_angle, v)],
                         ids=["plant", "mesh_stiffness", "pair_geometry", "omega"])
def test_a_refused_array_is_shown_on_one_line(call) -> None:  # noqa: ANN001
    # a 2-D array's repr breaks over lines: loop_margins showed it on one (12b94d3), check_plant and check_pair
    # printed the rows on three lines; one short_repr (gearctl.errors) for the three
    import numpy as np

    shown = r"array\(\[\[1., 1., 1.\], \[1., 1., 1.\], \[1., 1., 1.\]\]\)"
    with pytest.raises(InputError, match=rf"^\w+ = {shown} is not") as err:
        call(np.ones((3, 3)))
    assert "\n" not in str(err.value)


def test_precision_test_names_a_controller_that_is_none() -> None:
    # precision_test read controller.Ts before any check: AttributeError for None (a docstring review)
    from gearctl import build_plant, load_model
    from gearctl.errors import InputError
    from gearctl.precision import precision_test

    with pytest.raises(InputError, match=r"controller = None is not a controller"):
        precision_test(build_plant(load_model("shing1993_servo")), None, cycles=1)  # type: ignore[arg-type]


def test_ratio_after_refuses_an_index_outside_the_stages() -> None:
    # Plant.ratio_after(-1) read the stages from the end and returned the whole train's ratio
    from gearctl import build_plant, load_model
    from gearctl.errors import InputError

    train = build_plant(load_model("servo_3stage_quanser_srv02"))
    assert train.ratio_after(2) == 1.0 and train.ratio_after(0) == pytest.approx(4.0 * 5.0)
    for bad in (-1, 3, 1.0):
        with pytest.raises(InputError, match=r"i = .* is out of range: expected a stage index from 0 to 2"):
            train.ratio_after(bad)  # type: ignore[arg-type]


def test_plant_names_its_kind_argument() -> None:
    from gearctl import build_plant, load_model
    from gearctl.errors import InputError

    with pytest.raises(InputError, match=r"kind = 'rigid' is not a plant kind: expected one of improved"):
        build_plant(load_model("shing1993_servo"), "rigid")
