"""dead_zone_factor's gap ``b``: any real number type is read (numpy's integers were refused as "out of range"), and
what is no number, a bool among them, is refused as no number (``True`` was read as a 1 m gap)."""

from __future__ import annotations

import numpy as np
import pytest

from gearctl import InputError
from gearctl.describe import dead_zone_factor

A = np.array([1e-4, 2e-4])


@pytest.mark.parametrize("b", [np.int64(0), np.float32(0.0), 0])
def test_a_gap_of_any_real_type_is_read(b: object) -> None:
    np.testing.assert_array_equal(dead_zone_factor(A, b), dead_zone_factor(A, 0.0))


@pytest.mark.parametrize("b", [True, "5e-5", None, np.array([5e-5])])
def test_a_gap_that_is_no_number_is_refused_as_such(b: object) -> None:
    with pytest.raises(InputError, match=r"^b = .* is not a number: expected a finite number >= 0 \[m\]") as err:
        dead_zone_factor(A, b)
    assert err.value.field == "b"
