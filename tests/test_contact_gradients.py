"""The capsule's and sphere's profile derivatives written by hand (``obstacles.*_back``,
``stacked_contact``) against JAX's autodiff and against finite differences of the penalty's
energy, and the law under jit, vmap and grad with respect to the obstacles."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gvsjax.core import contact, obstacles, stacked_contact


def pieces(n_c=40, seed=0):
    """Random pieces (p, unit t) near the origin, 10 cm long, rod radius 3 cm, the first and last at
    a link's ends."""
    rng = np.random.default_rng(seed)
    p = jnp.asarray(rng.uniform(-0.2, 0.2, (n_c, 3)))
    t = rng.normal(size=(n_c, 3))
    t = jnp.asarray(t / np.linalg.norm(t, axis=-1, keepdims=True))
    lo = jnp.full(n_c, -0.05).at[0].set(0.0)
    hi = jnp.full(n_c, 0.05).at[-1].set(0.0)
    return p, t, jnp.full(n_c, 0.03), lo, hi


def stack(kind, m=6, seed=1):
    rng = np.random.default_rng(seed)
    if kind is gv.Capsule:
        obs = [gv.Capsule(tuple(rng.uniform(-0.25, 0.25, 3)), tuple(rng.uniform(-0.25, 0.25, 3)),
                          float(rng.uniform(0.01, 0.1))) for _ in range(m)]
    else:
        obs = [gv.Sphere(tuple(rng.uniform(-0.2, 0.2, 3)), float(rng.uniform(0.02, 0.1))) for _ in range(m)]
    return contact._groups(tuple(obs))[0][0], m


def test_the_closest_points_and_the_bend_reverse_passes_are_autodiffs():
    rng = np.random.default_rng(2)
    n = 2000
    te, b1, b2 = (jnp.asarray(rng.uniform(-0.3, 0.3, n)) for _ in range(3))
    ee = jnp.asarray(rng.uniform(0.05, 0.4, n))
    lo, hi = jnp.full(n, -0.05), jnp.full(n, 0.05)
    g = tuple(jnp.asarray(rng.normal(size=n)) for _ in range(4))
    _, pull = jax.vjp(lambda a, b, c: obstacles.segment_closest(a, b, c, ee, lo, hi), te, b1, b2)
    for x, y in zip(pull(g), obstacles.segment_closest_back(te, b1, b2, ee, lo, hi, *g)):
        np.testing.assert_allclose(y, x, rtol=1e-10, atol=1e-10 * float(jnp.max(jnp.abs(x))))
    sin2 = jnp.maximum(1.0 - te * te / ee, 0.0)
    _, pull = jax.vjp(lambda a, b, s: obstacles.capsule_bend(a, b, ee, s, lo, hi, 0.08), te, b2, sin2)
    for x, y in zip(pull(g[0]), obstacles.capsule_bend_back(te, b2, ee, sin2, lo, hi, 0.08, g[0])):
        np.testing.assert_allclose(y, x, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("kind", [gv.Capsule, gv.Sphere])
def test_the_profiles_reverse_pass_is_the_autodiff_of_the_profile(kind):
    p, t, r, lo, hi = pieces()
    obs, m = stack(kind)
    col = lambda x: tuple(jnp.broadcast_to(x[:, i, None], (len(x), m)) for i in range(3))  # noqa: E731
    P, T = col(p), col(t)
    profile = stacked_contact._capsule if kind is gv.Capsule else stacked_contact._sphere
    ends = (lo[:, None], hi[:, None], r[:, None])
    g = tuple(jnp.asarray(np.random.default_rng(3).normal(size=(len(p), m))) for _ in range(3))
    _, pull = jax.vjp(lambda P, T: tuple(profile(obs, P, T, *ends)[0][3:]), P, T)  # (floor, curvature, centre)
    by_hand = profile(obs, P, T, *ends)[1](g)
    for a, b in zip(pull(g), by_hand):
        for x, y in zip(a, b):
            np.testing.assert_allclose(y, x, rtol=1e-10, atol=1e-10 * float(jnp.max(jnp.abs(x))))


@pytest.mark.parametrize("kind", [gv.Capsule, gv.Sphere])
def test_the_force_and_moment_are_minus_the_energys_central_differences(kind):
    """Each piece's elastic force -dE/dp and moment -t x dE/dt (damping off, at rest) against
    central differences of its energy, E from the same law: independent of any derivative."""
    p, t, r, lo, hi = pieces(n_c=60)
    obs, _ = stack(kind, m=8)
    pen = contact.Penalty(stiffness=1e6, damping=0.0, smoothing=1e-3)

    def law(p, t):
        f3, m3, g, e = stacked_contact.stacked_law(obs, p, t, jnp.zeros_like(p), jnp.zeros_like(p), r, lo, hi, pen)
        return jnp.stack(f3, -1), jnp.stack(m3, -1), g, e

    f, mom, g, _ = law(p, t)
    assert float(jnp.min(g)) < -1e-3 and float(jnp.max(jnp.abs(f))) > 10.0  # pressing
    h = 1e-7
    energy = lambda p, t: law(p, t)[3]  # noqa: E731
    fd = jnp.stack([(energy(p + h * e, t) - energy(p - h * e, t)) / (2 * h) for e in jnp.eye(3)], -1)
    np.testing.assert_allclose(f, -fd, rtol=1e-5, atol=1e-5 * float(jnp.max(jnp.abs(f))))
    # turning the piece about axis a by a small angle moves t by a x t: dE = (a x t) . dE/dt = a . (t x dE/dt)
    turn = lambda a: t + h * jnp.cross(a, t)  # noqa: E731
    fd_m = jnp.stack([(energy(p, turn(a)) - energy(p, turn(-a))) / (2 * h) for a in jnp.eye(3)], -1)
    np.testing.assert_allclose(mom, -fd_m, rtol=1e-5, atol=1e-5 * float(jnp.max(jnp.abs(mom))))


# extended: the default run checks the capsules' reverse passes (above) and a gradient through a run
# against a plane (test_contact); this is their one long compile together
@pytest.mark.extended
def test_jit_vmap_and_grad_through_a_run_against_capsules():
    """The clamped arm swung into a bar: a batch of bar positions under jit(vmap), and the gradient
    of the tip's final x with respect to the bar's position against central differences."""
    arm = gv.soft_arm(bending_order=1, stretch_order=-1, torsion_order=-1, n_gauss=2)

    def tip_x(x_bar):
        bar = gv.Capsule(start=jnp.stack([x_bar, -0.3, 0.6]), end=jnp.stack([x_bar, 0.3, 0.6]), radius=0.03)
        robot = arm.replace(contact=gv.Contact(obstacles=(bar, gv.Sphere((0.5, 0.0, 2.0), 0.1)),
                                               rod=gv.Penalty(stiffness=3e5, damping=1e3), n_points=11))
        tr = gv.simulate(robot, 0.3, n_steps=60, tendon_force=jnp.array([0.0, 0.0, 200.0, 0.0] + [0.0] * 4),
                         integrator="ars443", check_stability=False)
        return tr.tip[-1, 0], jnp.min(tr.contact_gap)

    batched = jax.jit(jax.vmap(tip_x))
    tips, gaps = batched(jnp.array([-0.1, -0.12, 2.0]))
    assert float(gaps[0]) < 0.0 and float(gaps[2]) > 0.1  # the first bar is hit, the last far away
    assert float(tips[2]) < float(tips[0])  # unhindered, the arm swings further to -x
    slope = jax.jit(jax.grad(lambda x: tip_x(x)[0]))(-0.1)
    h = 1e-6  # the tip is curved in the bar's place: 1e-5 is 3% off
    plus, minus, _ = batched(jnp.array([-0.1 + h, -0.1 - h, 2.0]))[0]  # the same program: no new compile
    fd = (plus - minus) / (2 * h)
    assert np.isfinite(float(slope))
    np.testing.assert_allclose(float(slope), float(fd), rtol=1e-5)


def test_the_broad_phase_is_exact_while_few_obstacles_are_in_reach_and_drops_the_farthest_beyond():
    """``Contact.nearest``: the law against each piece's k nearest capsules of a stack equals the
    law against all of them when no piece is within reach of more than k, gaps included; with
    fewer picks than touch a piece, the farthest's force is what is lost."""
    p, t, r, lo, hi = pieces(n_c=60)
    R = jnp.asarray(np.linalg.qr(np.random.default_rng(4).normal(size=(60, 3, 3)))[0])
    R = R.at[:, :, 0].set(t)  # only the tangent matters to the elastic part; the rest moves the damping's arm
    eta = jnp.asarray(np.random.default_rng(5).normal(size=(60, 6)))
    bars = tuple(gv.Capsule((x, -0.3, z), (x, 0.3, z), 0.03) for x in (-0.15, 0.0, 0.15) for z in (-0.15, 0.0, 0.15))
    pen = contact.Penalty(stiffness=1e6, damping=1e3, smoothing=1e-3, friction=0.3)
    full = contact.law(p, R, eta, r, lo, hi, bars, pen, 0.0)
    touching = np.asarray(jnp.sum(jnp.stack([contact.law(p, R, eta, r, lo, hi, (b,), pen, 0.0)[2] for b in bars])
                                  < pen.smoothing, axis=0))
    assert touching.max() == 2  # some pieces touch two bars at once
    for k in (2, 3):
        near = contact.law(p, R, eta, r, lo, hi, bars, pen, 0.0, nearest=k)
        for a, b in zip(near, full):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-9)
    one = contact.law(p, R, eta, r, lo, hi, bars, pen, 0.0, nearest=1)
    np.testing.assert_array_equal(one[2], full[2])  # the gaps are still over every bar
    lost = np.abs(np.asarray(one[1] - full[1])).max(axis=-1)
    assert lost[touching <= 1].max() <= 1e-9 and lost[touching == 2].min() > 0.0


def test_the_rod_wide_broad_phase_is_exact_while_few_pairs_are_in_reach_and_drops_the_last_beyond():
    """``Contact.pairs``: the law on at most k (piece, obstacle) pairs in reach equals the law on all
    of them when no more than k pairs are in reach, gaps included, under jit, vmap and grad; with
    fewer picks, what is lost is the force of the last pairs in reach along the rod."""
    p, t, r, lo, hi = pieces(n_c=60)
    R = jnp.asarray(np.linalg.qr(np.random.default_rng(4).normal(size=(60, 3, 3)))[0])
    R = R.at[:, :, 0].set(t)
    eta = jnp.asarray(np.random.default_rng(5).normal(size=(60, 6)))
    bars = tuple(gv.Capsule((x, -0.3, z), (x, 0.3, z), 0.03) for x in (-0.15, 0.0, 0.15) for z in (-0.15, 0.0, 0.15))
    pen = contact.Penalty(stiffness=1e6, damping=1e3, smoothing=1e-3, friction=0.3)
    full = contact.law(p, R, eta, r, lo, hi, bars, pen, 0.0)
    gaps = np.stack([np.asarray(contact.law(p, R, eta, r, lo, hi, (b,), pen, 0.0)[2]) for b in bars])
    in_reach = int(np.sum(gaps < pen.smoothing))
    assert 5 < in_reach < 60  # many pairs, far fewer than the 540 of the pieces and bars
    law = jax.jit(lambda p, k: contact.law(p, R, eta, r, lo, hi, bars, pen, 0.0, pairs=k), static_argnums=1)
    for k in (in_reach, in_reach + 7):
        for a, b in zip(law(p, k), full):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-9)
    few = law(p, in_reach - 2)
    np.testing.assert_allclose(few[2], full[2], rtol=0, atol=1e-15)  # the gaps are still over every pair
    lost = np.abs(np.asarray(few[1] - full[1])).max(axis=-1)
    piece_of_pair = np.nonzero(gaps.T < pen.smoothing)[0]  # in reach, in the rod's order (piece, then obstacle)
    assert set(np.nonzero(lost > 1e-9)[0]) == set(piece_of_pair[-2:])  # the last two pairs' pieces, no other
    # vmap over shifted rods and the energy's gradient against the full law's
    shifts = jnp.asarray([[0.0, 0.0, 0.0], [0.01, 0.0, -0.02]])
    batched = jax.vmap(lambda d: law(p + d, in_reach + 7))(shifts)
    np.testing.assert_allclose(batched[1][1], contact.law(p + shifts[1], R, eta, r, lo, hi, bars, pen, 0.0)[1],
                               rtol=1e-12, atol=1e-9)
    g_pairs = jax.grad(lambda p: jnp.sum(law(p, in_reach + 7)[3]))(p)
    g_full = jax.grad(lambda p: jnp.sum(contact.law(p, R, eta, r, lo, hi, bars, pen, 0.0)[3]))(p)
    np.testing.assert_allclose(g_pairs, g_full, rtol=1e-10, atol=1e-9)
