"""The backlash element's describing function refuses amplitudes and frequencies that are no numbers."""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest

from gearctl import InputError
from gearctl.describe import MeshBacklash, dead_zone_factor


@pytest.mark.parametrize("A", [float("nan"), -1e-4, [1e-4, float("nan")], [2e-4, -1e-4]])
def test_dead_zone_factor_refuses_nan_and_negative_amplitudes(A) -> None:  # noqa: ANN001
    # before, NaN and negative amplitudes read as inside the gap: eta = 0, a describing function of 0
    with pytest.raises(InputError, match=r"^A = .* expected amplitudes >= 0 \[m\]") as err:
        dead_zone_factor(A, 5e-5)
    assert err.value.field == "A"
    with pytest.raises(ValueError, match="A"):
        MeshBacklash(k=1e8, b=5e-5, c=300.0).describing_function_at(A, 1e3)


@pytest.mark.parametrize("b", [float("nan"), -1e-5, float("inf")])
def test_dead_zone_factor_refuses_a_bad_gap(b: float) -> None:
    with pytest.raises(InputError, match=r"^b = .* expected a finite number >= 0 \[m\]"):
        dead_zone_factor(1e-4, b)


@pytest.mark.parametrize("omega", [float("nan"), float("inf"), [1.0, float("-inf")]])
def test_describing_function_at_refuses_non_finite_frequencies(omega) -> None:  # noqa: ANN001
    with pytest.raises(InputError, match=r"^omega = .* is not finite") as err:
        MeshBacklash(k=1e8, b=5e-5, c=300.0).describing_function_at(1e-4, omega)
    assert err.value.field == "omega"


def test_valid_amplitudes_still_match_the_quadrature() -> None:
    """eta against python-control's own numerical describing function of the static dead-zone spring."""
    el = MeshBacklash(k=1e8, b=5e-5)
    A = np.array([5.1e-5, 6e-5, 1e-4, 1e-3])
    numeric = ct.describing_function(lambda x: el(x), A, num_points=4000)
    np.testing.assert_allclose(el.k * dead_zone_factor(A, el.b), numeric.real, rtol=1e-5)
    assert dead_zone_factor(0.0, 5e-5) == 0.0 and dead_zone_factor(math.inf, 5e-5) == 1.0
