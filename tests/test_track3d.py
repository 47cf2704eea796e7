"""The upright 3D tendon arm (gv.soft_arm) against closed forms, and the track3d task: the
target's motion, the action mapping, the env under jit/vmap, bad input, the figures."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import capture_figures, finite_line

import gvsjax as gv
from gvsjax.tasks import arm3d, make
from gvsjax.tasks import track3d as t3

TRUNCATION_M = 5e-3  # the order-2 basis' tip error on a curvature jump (experiments/studies/track3d_basis.py)


@pytest.fixture(scope="module")
def env():
    return make("track3d")


def test_a_tendon_bends_the_arm_into_the_closed_form_arc():
    """Weightless, one tendon at offset d pulled with T: the Cosserat balance gives a constant
    curvature T d / EI and a uniform compression -T / EA, so the tip lies on a circular arc of
    reference length L shrunk by (1 - T / EA), bent towards the tendon (world +x at rest)."""
    E, r, d, T = 1e7, 0.05, 0.04, 600.0
    robot = gv.soft_arm(gravity=0.0)
    A, I = math.pi * r**2, math.pi * r**4 / 4
    eq = gv.equilibrium(robot, tendon_force=jnp.array([T, 0, 0, 0, 0, 0, 0, 0.0]))
    assert bool(eq.converged)
    kappa, scale = T * d / (E * I), 1 - T / (E * A)
    expected = scale * np.array([(1 - math.cos(kappa)) / kappa, 0.0, math.sin(kappa) / kappa])
    np.testing.assert_allclose(np.asarray(gv.backbone(robot, eq.q)[-1]), expected, atol=1e-9)
    # the tip's tangent is turned by the arc's angle kappa towards the tendon (gv.tip_frame)
    R, p = gv.tip_frame(robot, eq.q)
    np.testing.assert_allclose(np.asarray(R[:, 0]), [math.sin(kappa), 0.0, math.cos(kappa)], atol=1e-9)
    np.testing.assert_allclose(np.asarray(R.T @ R), np.eye(3), atol=1e-12)
    np.testing.assert_allclose(np.asarray(p), expected, atol=1e-9)


def test_the_half_length_tendons_bend_only_the_lower_half():
    """Weightless, a lower-group tendon: an arc of curvature T d / EI up to X = 1/2 (shrunk by
    1 - T / EA), then a straight upper half along the arc's end tangent. The polynomial basis
    smooths the curvature's jump at X = 1/2: the convergence study (experiments/studies/track3d_basis.py)
    puts the order-2 basis within a few millimetres of the reference there."""
    E, r, d, T = 1e7, 0.05, 0.04, 400.0
    robot = gv.soft_arm(gravity=0.0)
    A, I = math.pi * r**2, math.pi * r**4 / 4
    eq = gv.equilibrium(robot, tendon_force=jnp.array([0, 0, 0, 0, 0, T, 0, 0]))  # lower group, +z
    kappa, scale = T * d / (E * I), 1 - T / (E * A)
    phi = kappa * 0.5
    expected = np.array([0.0, scale * (1 - math.cos(phi)) / kappa + 0.5 * math.sin(phi),
                         scale * math.sin(phi) / kappa + 0.5 * math.cos(phi)])
    tip = np.asarray(gv.backbone(robot, eq.q)[-1])
    assert abs(tip[0]) < 1e-12  # the bend stays in the y-z plane
    np.testing.assert_allclose(tip, expected, atol=TRUNCATION_M)


def test_first_bending_frequency_matches_euler_bernoulli():
    """Weightless cantilever: omega_1 = 1.8751^2 sqrt(EI / (rho A L^4)), in both bending planes."""
    robot = gv.soft_arm(gravity=0.0)
    q = jnp.zeros(robot.n_dofs)
    M = np.asarray(gv.mass_and_forces(robot, q, q)[0])  # its lower triangle
    M = M + np.tril(M, -1).T
    K = np.asarray(gv.stiffness_and_damping(robot)[0])
    w = np.sort(np.sqrt(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    E, r, rho = 1e7, 0.05, 1000.0
    w1 = 1.8751**2 * math.sqrt(E * math.pi * r**4 / 4 / (rho * math.pi * r**2))
    np.testing.assert_allclose(w[:2], [w1, w1], rtol=2e-3)  # a Ritz bound from above (three curvature modes)


def test_target_moves_at_its_speed_inside_the_box():
    P = t3.Track3DParams(targets="box")
    low, high = np.array(P.box_low), np.array(P.box_high)

    def walk(key):
        p, v = t3.start(key, P)

        def body(carry, k):
            p, v = t3.move(k, *carry, P)
            return (p, v), (p, v)

        return jax.lax.scan(body, (p, v), jax.random.split(jax.random.fold_in(key, 1), 400))[1]

    p, v = jax.jit(jax.vmap(walk))(jax.random.split(jax.random.PRNGKey(0), 64))
    p, v = np.asarray(p), np.asarray(v)
    assert np.all(p >= low - 1e-12) and np.all(p <= high + 1e-12)
    np.testing.assert_allclose(np.linalg.norm(v, axis=-1), P.speed, rtol=1e-12)
    step = np.linalg.norm(np.diff(p, axis=1), axis=-1)
    assert step.max() <= P.speed * P.arm.control_dt + 1e-12  # a reflection only shortens a step
    turned = np.any(np.abs(np.diff(v, axis=1)) > 1e-9, axis=-1)
    # direction changes: turns (2.5% per step) and wall bounces; the box is crossed in ~2.4 s
    assert 0.05 < turned.mean() < 0.3
    assert p.std(axis=(0, 1)).min() > 0.25 * (high - low).min() / math.sqrt(12)


def _walks(P, n: int, steps: int = 100, seed: int = 0):
    """(n, steps + 1, 3) target positions and (n, steps, 3) velocities of ``n`` walks under jit(vmap)."""
    def walk(key):
        p, v = t3.start(key, P)

        def body(carry, t):
            p, v = t3.move(jax.random.fold_in(key, t), *carry, P)
            return (p, v), (p, v)

        ps, vs = jax.lax.scan(body, (p, v), jnp.arange(steps))[1]
        return jnp.concatenate([p[None], ps]), vs

    p, v = jax.jit(jax.vmap(walk))(jax.random.split(jax.random.PRNGKey(seed), n))
    return np.asarray(p), np.asarray(v)


def test_reachable_targets_stay_near_held_tips_under_jit_and_vmap(env):
    """The default target set: every start and step of 64 walks lies in the box and within
    ``reach_radius`` of a tip of the arm's static table (by brute force), moving at the target's
    speed; a batched draw equals the single one; the same walks on the box leave the set often."""
    P = env.default_params()
    assert P.targets == "reachable" and P.holdable.shape[1] == 3 and env.train_params("box").targets == "box"
    table = np.asarray(P.holdable)
    p, v = _walks(P, 64)
    flat = p.reshape(-1, 3)
    d = np.sqrt(np.min(np.sum((flat[:, None, :] - table[None]) ** 2, -1), axis=1))
    assert d.max() <= P.reach_radius + 1e-12
    assert np.all(flat >= np.array(P.box_low) - 1e-12) and np.all(flat <= np.array(P.box_high) + 1e-12)
    step = np.linalg.norm(np.diff(p, axis=1), axis=-1)
    full = P.speed * P.arm.control_dt
    # a wall shortens a step and a boundary with no direction out of it stops one: both stay rare
    assert step.max() <= full + 1e-12 and step.mean() > 0.8 * full and np.mean(step < 1e-9) < 0.05
    np.testing.assert_allclose(np.linalg.norm(v, axis=-1), P.speed, rtol=1e-12)
    assert flat.std(axis=0).min() > 0.1  # it roams the part, not one corner of it
    key = jax.random.split(jax.random.PRNGKey(0), 64)[5]
    single = t3.start(key, P)[0]
    np.testing.assert_array_equal(np.asarray(single), p[5, 0])
    box = _walks(P.replace(targets="box"), 64)[0].reshape(-1, 3)
    held = np.asarray(jax.vmap(t3.inside, in_axes=(0, None))(jnp.asarray(box), P))
    assert held.mean() < 0.5  # the published box is mostly beyond the arm's static reach
    # the grid's cells (what a step asks) give the same walks, to the bit, as asking every row
    brute = _walks(P.replace(reach_cells=None), 64)
    np.testing.assert_array_equal(brute[0], p)
    np.testing.assert_array_equal(brute[1], v)


def test_the_cells_answer_as_every_row_does_near_the_reach_boundary():
    """``holdable.within_cells`` against the brute-force distance, under jit and vmap: box points,
    and points at the reach radius from a row, a hair inside and outside it."""
    from gvsjax.tasks import holdable

    rng = np.random.default_rng(3)
    table = rng.uniform([-0.5, -0.5, 0.2], [0.5, 0.5, 1.0], (500, 3))
    low, high, r = (-0.6, -0.6, 0.3), (0.6, 0.6, 0.9), 0.03
    cells = holdable.cell_rows(table, low, high, r)
    assert cells.rows.shape[:3] == (15, 15, 8) and cells.rows.shape[3] < 60  # a few rows per cell, not 500
    u = rng.normal(size=(2000, 3))
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    rim = table[rng.integers(0, 500, 2000)] + r * u * rng.choice([1 - 1e-9, 1 + 1e-9], (2000, 1))
    points = np.concatenate([rng.uniform(low, high, (4000, 3)), rim])
    points = points[np.all((points >= low) & (points <= high), axis=1)]
    brute = np.sqrt(np.min(np.sum((points[:, None] - table[None]) ** 2, -1), axis=1)) <= r
    fast = jax.jit(jax.vmap(holdable.within_cells, in_axes=(0, None, None)))(jnp.asarray(points), jnp.asarray(table),
                                                                            cells)
    assert 0.05 < brute.mean() < 0.95
    np.testing.assert_array_equal(np.asarray(fast), brute)


def _shipped_rows_match_the_statics(actuation: str) -> None:
    """Rows of the shipped table of ``actuation`` drawn at random (and the first, a corner of the
    action box), solved again with the statics, give the shipped tips; make_params reads the file."""
    from gvsjax.tasks.holdable import equilibrium_poses
    from gvsjax.tasks.track3d import tables

    with np.load(tables.PATH) as data:
        assert sorted(data.files) == sorted(tables.ACTUATIONS)
        tips = np.array(data[actuation])
    assert tips.shape == (tables.TABLE_SIZE, 3) and tips.dtype == np.float64
    arm = arm3d.ArmParams(actuation=actuation)
    rows = np.concatenate([[0], np.random.default_rng(0).choice(tables.TABLE_SIZE, 5, replace=False)])
    again = equilibrium_poses(arm, tables.table_actions(arm)[rows])
    assert np.all(again["converged"])
    np.testing.assert_allclose(again["position"], tips[rows], rtol=0, atol=1e-9)
    assert tables.default_tips(actuation) is tables.default_tips(actuation)  # read once per process
    np.testing.assert_array_equal(tables.default_tips(actuation), tips)


def test_the_shipped_holdable_table_matches_the_statics():
    """The default arms' tip tables ship with the package (``track3d.tables``), so that making the
    params solves no statics; re-solving some rows keeps the file from drifting from the physics."""
    _shipped_rows_match_the_statics("tendon")


@pytest.mark.extended
def test_the_shipped_muscle_table_matches_the_statics():
    _shipped_rows_match_the_statics("muscle")


def test_bad_target_set_is_refused_before_compiling(env):
    with pytest.raises(ValueError, match=r"Track3DParams.targets='boxes' is invalid: expected one of "
                                         r"\['reachable', 'box'\]"):
        t3.Track3DParams(targets="boxes")
    with pytest.raises(ValueError, match=r"targets='all' is invalid: expected one of \['reachable', 'box'\]"):
        t3.make_params(targets="all")
    with pytest.raises(ValueError, match=r"unknown track3d parameter\(s\) \['holdable'\]"):
        t3.make_params(targets="box", holdable=np.zeros((3, 3)))
    key = jax.random.PRNGKey(0)
    with pytest.raises(ValueError, match="holdable is None but targets='reachable' needs it"):
        env.reset(key, t3.Track3DParams())
    P = env.default_params()
    for name in ("holdable", "starts"):
        for bad in (np.zeros((4, 2)), np.zeros((0, 3))):
            with pytest.raises(ValueError, match=rf"Track3DParams.{name}=.* expected shape \(p, 3\)"):
                env.reset(key, P.replace(**{name: bad}))
    for bad in (0.0, -0.01, float("nan")):
        with pytest.raises(ValueError, match=r"Track3DParams.reach_radius=.* expected a finite number > 0"):
            env.reset(key, P.replace(reach_radius=bad))
    with pytest.raises(ValueError, match=r"Track3DParams.reach_cells=.*built for reach_radius=0.03"):
        env.reset(key, P.replace(reach_radius=0.05))  # the cells of another radius would miss rows
    with pytest.raises(ValueError, match=r"train_targets='boxes' is invalid for task='track3d'; choose one of "
                                         r"\['reachable', 'box'\]"):
        env.train_params("boxes")
    from gvsjax import train

    with pytest.raises(ValueError, match="train_targets='sphere'"):
        train.parse_args(["task=track3d", "train_targets=sphere"])


def test_actions_map_to_opposing_nonnegative_tensions():
    arm = arm3d.ArmParams()
    a = jnp.array([[1.0, -0.5, 0.0, 2.0], [-1.0, 0.25, -3.0, 0.0]])
    T = np.asarray(arm3d.tensions(a, arm)) / arm.tension_max
    np.testing.assert_allclose(T, [[1, 0, 0, 0.5, 0, 1, 0, 0], [0, 0.25, 1, 0, 0, 0, 1, 0]], atol=1e-15)
    assert np.all(T >= 0)


@pytest.mark.slow
def test_env_under_jit_and_vmap(env):
    # the env's mechanics; the default (reachable) target set under jit and vmap: the test above
    P = env.train_params("box")
    keys = jax.random.split(jax.random.PRNGKey(1), 3)
    obs, s = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, P)
    left = -env.action_size - 1  # the fraction of the episode left, then the last action
    assert obs.shape == (3, env.obs_size) and np.all(np.asarray(obs[:, left]) == 1.0)
    assert not np.any(np.asarray(obs[:, left + 1:]))
    step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))
    actions = jnp.array([[1.0, 0, 0, 0], [0, 0, 0, 0], [jnp.nan, 0, 0, 0]])
    tips = []
    for t in range(3):
        obs, s, reward, done, info = step(jax.random.split(jax.random.PRNGKey(t), 3), s, actions, P)
        tips.append(np.asarray(s.tip))
    valid = np.asarray(info["valid"])
    assert valid.tolist() == [True, True, False]  # a NaN action is flagged, the batch runs on
    r = np.asarray(reward)
    d = np.asarray(info["distance"])
    np.testing.assert_allclose(r[:2], np.exp(-P.k * d[:2]), rtol=1e-12)
    assert np.all((r[:2] > 0) & (r[:2] <= 1)) and r[2] == 0
    # pulling the whole-arm +y tendon (section y = world +x) moves the tip towards +x; with no action
    # the arm stands, settling under its weight (rho g L^2 / 2E = 0.5 mm)
    assert tips[-1][0, 0] > tips[0][0, 0] > 0.05
    np.testing.assert_allclose(tips[-1][1], [0, 0, 1], atol=1e-3)
    np.testing.assert_allclose(np.asarray(obs[:2, left]), 1 - 3 / env.episode_length)
    np.testing.assert_allclose(np.asarray(obs[:2, left + 1:]), np.asarray(actions[:2]))
    space = env.observation_space()
    assert space.shape == (env.obs_size,) and space.low[left] == 0 and space.high[-1] == 1
    # the action-rate term (the same program: the weight is a traced param); row 0 changes by (-2, 2, 0, 0.5)
    new = jnp.array([[-1.0, 2.0, 0, 0.5], [0, 0, 0, 0], [0, 0, 0, 0]])
    P2 = P.replace(action_rate_weight=0.5)
    obs, s, reward, done, info = step(jax.random.split(jax.random.PRNGKey(3), 3), s, new, P2)
    change = np.array([(4 + 1 + 0 + 0.25) / 4, 0.0])  # the applied action is clipped to [-1, 1]
    np.testing.assert_allclose(np.asarray(info["action_change"][:2]), change, rtol=1e-12)
    r, d = np.asarray(reward[:2]), np.asarray(info["distance"][:2])
    np.testing.assert_allclose(r, np.exp(-P.k * d) - 0.5 * change, rtol=1e-12)
    np.testing.assert_allclose(np.asarray(obs[0, left + 1:]), [-1, 1, 0, 0.5])
    with pytest.raises(ValueError, match="action_rate_weight=-0.1"):
        env.reset(keys[0], P.replace(action_rate_weight=-0.1))


def test_wrong_arm_or_action_shape_is_refused_before_compiling(env):
    P = env.default_params()
    bad = P.replace(arm=P.arm.replace(robot=gv.soft_arm(tendon_ends=(1.0,))))
    with pytest.raises(ValueError, match="two tendon groups"):
        env.reset(jax.random.PRNGKey(0), bad)
    _, s = env.reset(jax.random.PRNGKey(0), P)
    with pytest.raises(ValueError, match=r"expected \(4,\)"):
        env.step(jax.random.PRNGKey(0), s, jnp.zeros(3), P)
    for ends in ((1.5,), 0.5, (0.0,)):
        with pytest.raises(ValueError, match="tendon_ends"):
            gv.soft_arm(tendon_ends=ends)
    with pytest.raises(ValueError, match="tendon_offset"):
        gv.soft_arm(tendon_offset=0.06)


def test_evaluation_figures_draw_the_curves(tmp_path, monkeypatch):
    from gvsjax.tasks.track3d.figures import evaluation_figures

    rng = np.random.default_rng(0)
    target = rng.uniform(-0.5, 0.5, (4, 100, 3)) + [0, 0, 0.6]
    extra = {"distance": rng.uniform(0, 0.2, (32, 100)), "rest_distance": rng.uniform(0.3, 0.8, (32, 100)),
             "tip": target + 0.02, "target": target, "dt": 0.1}
    figs = capture_figures(monkeypatch)
    paths = evaluation_figures(extra, tmp_path)
    assert [p.name for p in paths] == ["tracking_distance.png", "tracking_paths.png", "error_histogram.png"]
    median = finite_line(figs["tracking_distance.png"], "policy, median", 100)
    np.testing.assert_allclose(median["y"], 100 * np.median(extra["distance"], 0))
    finite_line(figs["tracking_distance.png"], "arm left at rest, median", 100)
    for i in range(4):
        finite_line(figs["tracking_paths.png"], f"episode {i + 1}", 100)
    assert len(figs["tracking_paths.png"]) == 8  # a tip and a target path per episode
    bars = [ln for ln in figs["error_histogram.png"] if ln["label"] == "bars"][0]
    assert abs(bars["y"].sum() - 100) < 1e-9
    # an MPC's evaluation names it in the legend (evaluate controller=mpc sets "who")
    evaluation_figures({**extra, "who": "MPC"}, tmp_path)
    finite_line(figs["tracking_distance.png"], "MPC, median", 100)


def test_the_tendon_arm_simulates_in_float32():
    """Routed tendons and the folded ars443 layout (>= 4 free DoFs) keep float32 throughout."""
    robot = gv.soft_arm(torsion_order=-1, bending_order=1, stretch_order=0)  # 5 DoFs
    arm32 = arm3d.ArmParams(robot=robot, sim_dtype="float32")
    arm64 = arm3d.ArmParams(robot=robot)
    q, qd = arm3d.rest(robot)
    tension = arm3d.tensions(jnp.array([0.5, -0.3, 0.2, 0.4]), arm64)
    simulate32 = lambda q, qd, T: gv.simulate(robot, 0.1, n_steps=8, tendon_force=T, q0=q, qd0=qd,  # noqa: E731
                                              integrator="ars443", dtype=jnp.float32, check_stability=False)
    assert jax.eval_shape(simulate32, q, qd, tension).q.dtype == jnp.float32  # traced, not compiled
    tip32 = arm3d.advance(arm32, q, qd, tension).tip[-1]
    tip64 = arm3d.advance(arm64, q, qd, tension).tip[-1]
    assert tip32.dtype == jnp.float64  # the env's state stays float64
    np.testing.assert_allclose(np.asarray(tip32), np.asarray(tip64), atol=1e-4)
    with pytest.raises(ValueError, match="sim_dtype"):
        arm3d.with_sim_dtype(arm64, "float16")


def test_learning_curve_of_long_episodes_averages_the_recent_ones(tmp_path, monkeypatch):
    """With 100-step episodes most updates end no episode (reward NaN): the 100-episode moving
    average must span the last rows that ended some, not a hundred rows."""
    from gvsjax.utils import plots

    rows = ["update,episodes,episode_reward,episodes_completed"]
    for u in range(60):
        done = u % 5 == 4
        rows.append(f"{u},{102 * (u + 1)},{u if done else 'nan'},{512 if done else 0}")
    (tmp_path / "metrics.csv").write_text("\n".join(rows) + "\n")
    figs = capture_figures(monkeypatch)
    plots.learning_curve(tmp_path / "metrics.csv", tmp_path / "curve.png")
    avg = finite_line(figs["curve.png"], "100-episode moving average", 12)
    np.testing.assert_allclose(avg["y"], np.arange(4, 60, 5))  # each row holds 512 >= 100 episodes
