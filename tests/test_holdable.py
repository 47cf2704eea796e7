"""What the 3D arm holds still (``gvsjax.tasks.holdable``) and the reachability experiment's measures:
nearest distances and pose matches against brute force, the action sample, bad input, the table."""

import importlib.util
from pathlib import Path

import jax
import numpy as np
import pytest

from gvsjax.tasks import arm3d, holdable


def _experiment():
    path = Path(__file__).parents[1] / "experiments" / "studies" / "tendon_reachability.py"
    spec = importlib.util.spec_from_file_location("tendon_reachability", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_nearest_equals_brute_force():
    """Chunked nearest neighbours (m not a multiple of the chunk) against an explicit loop."""
    rng = np.random.default_rng(3)
    points, table = rng.normal(size=(37, 3)), rng.normal(size=(53, 3))
    d, i = holdable.nearest(points, table, chunk=8)
    for k, p in enumerate(points):
        dist = [np.sqrt(np.sum((p - t) ** 2)) for t in table]
        assert i[k] == int(np.argmin(dist))
        np.testing.assert_allclose(d[k], min(dist), rtol=1e-12)
    # one point per call, as inside jit: the same distances
    each = jax.jit(jax.vmap(holdable.distance_to, in_axes=(0, None)))(points, table)
    np.testing.assert_allclose(np.asarray(each), d, rtol=1e-12)


def test_pose_match_equals_brute_force():
    rng = np.random.default_rng(4)
    unit = lambda x: x / np.linalg.norm(x, axis=-1, keepdims=True)  # noqa: E731
    points, table = rng.uniform(0, 0.3, (41, 3)), rng.uniform(0, 0.3, (60, 3))
    axes, table_axes = unit(rng.normal(size=(41, 3))), unit(rng.normal(size=(60, 3)))
    got = holdable.pose_reachable(points, axes, table, table_axes, 0.08, 40.0, chunk=16)
    angle = np.degrees(np.arccos(np.clip(axes @ table_axes.T, -1, 1)))
    dist = np.linalg.norm(points[:, None] - table[None], axis=-1)
    want = np.any((dist < 0.08) & (angle < 40.0), axis=1)
    assert 0 < want.sum() < len(want)  # the case has both answers
    np.testing.assert_array_equal(got, want)


def test_action_sample_holds_the_corners_faces_and_inside():
    a = holdable.sample_actions(jax.random.PRNGKey(0), 1024, 4)
    assert a.shape == (1024, 4) and np.all(np.abs(a) <= 1)
    corners = {tuple(x) for x in a[:16]}
    assert len(corners) == 16 and all(set(c) <= {-1.0, 1.0} for c in corners)
    pinned = np.abs(a[16:]) == 1
    assert 0.2 < pinned.mean() < 0.3  # a third each of 0, 1/4 and 1/2 of the entries pinned
    assert (~pinned).all(1).mean() > 1 / 3  # the third never pinned, and some of the others
    # twelve dimensions: corners drawn, not listed
    b = holdable.sample_actions(jax.random.PRNGKey(0), 256, 12)
    assert b.shape == (256, 12) and np.all(np.abs(b[:32]) == 1)
    for bad in (0, 2.5, True):
        with pytest.raises(ValueError, match="n="):
            holdable.sample_actions(jax.random.PRNGKey(0), bad, 4)


def test_equilibrium_poses_refuses_a_wrong_action_size():
    with pytest.raises(ValueError, match=r"expected \(n, 12\) for ArmParams.actuation='muscle'"):
        holdable.equilibrium_poses(arm3d.ArmParams(actuation="muscle"), np.zeros((3, 4)))


def test_the_reachability_table_is_made_from_its_json():
    """The docs' table (docs/gen_results.py): each row at the largest sample, the change over the last
    doubling, the policy's result beside it; the experiment's shares."""
    import sys

    sys.path.insert(0, str(Path(__file__).parents[1] / "docs"))
    import gen_results

    by = {"8": {"median_m": 0.1, "within_5cm": 0.2, "within_10cm": 0.5},
          "16": {"median_m": 0.08, "within_5cm": 0.25, "within_10cm": 0.52}}
    data = {"rows": [{"task": "track3d", "targets": "box", "by_samples": by}]}
    line = gen_results.reachability_table(data, lambda task: f"{task} 13%").splitlines()[-1]
    assert line == ("| track3d | the published box (the policy's) | 8.0 cm | 5 cm: 25.0%, 10 cm: 52.0% | "
                    "5.0 points (8 -> 16 actions) | track3d 13% |")
    d = np.array([0.01, 0.04, 0.06, 0.2])
    assert _experiment().shares(d) == {"median_m": 0.05, "within_5cm": 0.5, "within_10cm": 0.75}
