"""The README's way to a static value of the contact model (``G[out, in](1e-3j)``) against a power balance."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import gearctl

DATA = Path(__file__).parent / "data"


def test_static_force_and_gap_under_a_constant_motor_torque() -> None:
    """Under 1 N m on the motor every shaft ends at a constant speed: omega_0 = 1 / d_eq (the torque's power goes
    into viscous friction), each shaft's speed omega_0 / N_j, and each stage carries what the shafts after it lose:
    r_b2,i F_i = sum_(j > i) d_j omega_j N_(i+1) / N_j (moments about shaft i + 1, reflected); s_i = F_i / k_i."""
    for name in ("shing1993_servo", "servo_2stage_phm09", DATA / "h4_train4_review.toml"):
        plant = gearctl.build_plant(gearctl.load_model(name))
        G = gearctl.linearize_modes(plant).contact
        N = np.cumprod([1.0] + [st.ratio for st in plant.stages])
        d = np.array([sh.d for sh in plant.shafts])
        w = (1.0 / np.sum(d / N**2)) / N  # shaft speeds [rad/s]
        n = plant.n_stages
        for i, st in enumerate(plant.stages):
            # torque the downstream shafts take, moved to shaft i + 1 (a torque on shaft j is N_(i+1)/N_j there)
            tq = sum(d[j] * w[j] * N[i + 1] / N[j] for j in range(i + 1, n + 1))
            F = tq / st.rb2
            suffix = "" if n == 1 else str(i + 1)
            np.testing.assert_allclose(G[f"force{suffix}", G.input_labels[0]](1e-3j).real, F, rtol=1e-4)
            np.testing.assert_allclose(G[f"s{suffix}", G.input_labels[0]](1e-3j).real, F / st.k, rtol=1e-4)
