"""Each integrator converges at its documented order on the fast throw."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import numpy as np
import pytest

THETA_F, T = np.deg2rad(210.0), 0.5
ARM = gv.paper_arm(tip_force=5.886)


def release_tip(integrator, n_steps):
    traj = gv.simulate(ARM, T, n_steps=n_steps, base_angle=lambda t: THETA_F * (t / T) ** 2,
                       integrator=integrator, save_every=n_steps)
    return np.asarray(traj.tip[-1])


REFERENCE = None


def reference():
    global REFERENCE
    if REFERENCE is None:
        REFERENCE = release_tip("rk4", 4000)
    return REFERENCE


@pytest.mark.parametrize("integrator, order, n", [("rk4", 4, 100), ("midpoint", 2, 400),
                                                  ("euler", 1, 800), ("imex", 1, 800)])
def test_observed_order(integrator, order, n):
    e1 = np.linalg.norm(release_tip(integrator, n) - reference())
    e2 = np.linalg.norm(release_tip(integrator, 2 * n) - reference())
    observed = np.log2(e1 / e2)
    assert observed == pytest.approx(order, abs=0.35), (e1, e2)
