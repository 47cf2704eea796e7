"""reach_obstacles' contact-rich episode against a stored reference: the held reference action
applied at once swings the arm into the cage's bars; a change to the contact's implementation
must reproduce the episode's states, gaps and penetrations to float64 rounding.

Rewrite the reference (only for an intended change of physics): ``python tests/test_contact_episode.py``.
"""

import dataclasses
from pathlib import Path

import jax
import numpy as np
import pytest

import gvsjax as gv  # noqa: F401  (XLA flags first)
from gvsjax.tasks import make
from gvsjax.tasks.reach_obstacles.env import held_policy

REFERENCE = Path(__file__).parent / "data" / "reach_obstacles_episode.npz"


def episode() -> dict[str, np.ndarray]:
    """30 control steps of the held reference action (absolute tendon actions, the reward without a
    final weight) from reset key 0, float64, the scene turned by 0.3 rad (traced obstacles, as in
    training)."""
    env = make("reach_obstacles")
    params = dataclasses.replace(env.default_params(), yaw_range=0.3, residual_scale=0.0, residual_rise=0.0,
                                 final_weight=0.0)
    policy = held_policy(env)

    @jax.jit
    def run(key):
        obs, state = env.reset(key, params)

        def body(carry, _):
            obs, state = carry
            obs, state, reward, _, info = env.step(key, state, policy(obs), params)
            return (obs, state), (state.q, state.qd, state.gap, info["depth"], reward)

        return jax.lax.scan(body, (obs, state), None, length=30)[1]

    q, qd, gap, depth, reward = (np.asarray(x) for x in run(jax.random.PRNGKey(0)))
    return {"q": q, "qd": qd, "gap": gap, "depth": depth, "reward": reward}


@pytest.mark.extended
def test_the_contact_rich_episode_matches_its_reference():
    ref = np.load(REFERENCE)
    out = episode()
    assert ref["depth"].max() > 0.03  # the swing does reach deep into a bar
    for k in ref.files:
        scale = max(np.abs(ref[k]).max(), 1e-3)
        assert np.abs(out[k] - ref[k]).max() <= 1e-9 * scale, k


if __name__ == "__main__":
    np.savez(REFERENCE, **episode())
    print({k: float(np.abs(v).max()) for k, v in np.load(REFERENCE).items()})
