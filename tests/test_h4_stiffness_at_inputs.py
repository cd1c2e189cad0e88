"""``mesh_stiffness_at`` refuses angles that are not finite numbers, by name."""

from __future__ import annotations

import math

import numpy as np
import pytest

import gearctl
from gearctl import InputError


@pytest.mark.parametrize("theta1", [float("nan"), [0.1, float("inf")], -math.inf, "x", [[0.1, None]]])
def test_mesh_stiffness_at_refuses_non_finite_angles(theta1) -> None:  # noqa: ANN001
    pair = gearctl.load_model("shing1993").pair
    with pytest.raises(InputError, match=r"^theta1 = .* is not finite: expected angles of gear 1 from C \[rad\]") as e:
        gearctl.mesh_stiffness_at(pair, theta1)
    assert e.value.field == "theta1"


def test_mesh_stiffness_at_is_periodic_and_its_mean_is_the_reported_one() -> None:
    """Finite angles still work: periodic with 2 pi / N1, and its average over one cycle is mesh_stiffness's mean."""
    pair = gearctl.load_model("pinion17_shifted_shing1993").pair
    period = 2 * math.pi / pair.teeth1
    th = np.linspace(0.0, period, 200001)[:-1] + 0.37 * period
    K = gearctl.mesh_stiffness_at(pair, th)
    np.testing.assert_allclose(gearctl.mesh_stiffness_at(pair, th + 7 * period), K, rtol=1e-9)
    np.testing.assert_allclose(K.mean(), gearctl.mesh_stiffness(pair).mean, rtol=1e-4)
