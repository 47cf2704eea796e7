"""Contact with obstacles: a body resting on a plane, a block on an incline (sliding and
sticking), a soft cantilever propped on a frictionless plane, a thin bar between two
contact samples, moving obstacles, and jit / vmap / grad over obstacle layouts. Every
reference is a closed form computed here with numpy or scipy, not with gvsjax."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import brentq

from gvsjax.core import contact, penetration
from helpers import raises_naming

G = 9.81


def smooth_depth(g, l):
    """The documented smoothed penetration: -g when deep, (l - g)^2 / (4 l) for |g| < l, 0 past l."""
    return np.where(g <= -l, -g, np.where(g < l, (l - g) ** 2 / (4 * l), 0.0))


def smooth_gap(load, k, l):
    """The gap at which the smoothed penalty k delta(g) carries ``load``."""
    return brentq(lambda g: k * smooth_depth(g, l) - load, -1.0, l, xtol=1e-15)


# ----------------------------------------------------------------------------
# a rigid body on planes


MASS, BALL = 2.0, 0.05


def ball(plane=None, **penalty) -> gv.Robot:
    """A body on a vertical prismatic joint (q = height of its centre) with a contact ball."""
    body = gv.RigidLink(mass=MASS, inertia=(1e-3,) * 3, joint=gv.Joint("prismatic", (0.0, 1.0, 0.0)))
    c = gv.Contact(obstacles=(plane or gv.Plane(),), sites=(gv.ContactSite(radius=BALL, link=0),),
                   site=gv.Penalty(**{"stiffness": 1e5, "damping": 200.0, "smoothing": 1e-4, **penalty}))
    return gv.Robot(links=(body,), contact=c)


def test_body_resting_on_a_plane_carries_its_weight_at_the_penetration_of_the_penalty_law():
    k, l = 1e5, 1e-4
    tr = gv.simulate(ball(), 1.0, 1e-3, q0=jnp.array([0.08]))
    assert not bool(tr.in_contact[0]) and bool(tr.in_contact[-1])
    np.testing.assert_allclose(np.asarray(tr.contact_force[-1, 0]), [0.0, MASS * G, 0.0], atol=1e-9)
    gap = smooth_gap(MASS * G, k, l)
    np.testing.assert_allclose(float(tr.q[-1, 0]), BALL + gap, atol=1e-10)
    np.testing.assert_allclose(float(tr.contact_gap[-1, 0]), gap, atol=1e-10)
    assert -gap < 2e-4  # mg / k = 0.2 mm


def test_a_rising_plane_lifts_the_body_at_its_speed():
    speed = 0.3
    plane = gv.Plane(motion=lambda t: jnp.stack([0.0 * t, speed * t, 0.0 * t]))
    tr = gv.simulate(ball(plane), 1.0, 1e-3, q0=jnp.array([BALL]))
    np.testing.assert_allclose(float(tr.qd[-1, 0]), speed, rtol=1e-6)
    np.testing.assert_allclose(float(tr.q[-1, 0]), BALL + speed + smooth_gap(MASS * G, 1e5, 1e-4), atol=1e-6)


def test_body_rests_on_a_box_and_on_a_sphere_at_their_surfaces():
    box = gv.Box(centre=(0.0, -0.2, 0.0), half_extents=(0.3, 0.2, 0.3),
                 rotation=gv.axis_rotation((0.0, 1.0, 0.0), 0.4))
    sphere = gv.Sphere(centre=(0.0, -0.5, 0.0), radius=0.5)
    gap = smooth_gap(MASS * G, 1e5, 1e-4)
    for obstacle in (box, sphere):
        tr = gv.simulate(ball(obstacle), 1.0, 1e-3, q0=jnp.array([0.1]))
        np.testing.assert_allclose(float(tr.q[-1, 0]), BALL + gap, atol=1e-10)


# ----------------------------------------------------------------------------
# a block on an incline: two contact corners, planar joint

HALF, THICK = 0.05, 0.02


def incline(angle, mu, slip_speed=1e-2, static=None, speed=0.0, duration=1.0):
    """A block on a plane at ``angle`` (rad), kinetic friction ``mu`` (static: ``static``),
    launched down the slope at ``speed`` (m/s): (trajectory, the downhill direction)."""
    body = gv.RigidLink(mass=1.0, inertia=(1e-4, 1e-4, (HALF**2 + THICK**2) / 3), joint=gv.Joint("planar"))
    corners = tuple(gv.ContactSite(offset=(x, -THICK, 0.0), link=0) for x in (-HALF, HALF))
    plane = gv.Plane(normal=(-np.sin(angle), np.cos(angle), 0.0))
    c = gv.Contact(obstacles=(plane,), sites=corners, site=gv.Penalty(stiffness=1e5, damping=200.0, friction=mu,
                                                                      static_friction=static, slip_speed=slip_speed))
    robot = gv.Robot(links=(body,), contact=c)
    normal, down = np.array([-np.sin(angle), np.cos(angle)]), -np.array([np.cos(angle), np.sin(angle)])
    q0 = jnp.array([*(THICK * normal), angle])
    qd0 = jnp.array([*(speed * down), 0.0])
    return gv.simulate(robot, duration, 5e-4, q0=q0, qd0=qd0), down


def test_block_slides_down_an_incline_at_g_sin_minus_mu_cos():
    angle, mu = np.deg2rad(30.0), 0.3
    tr, down = incline(angle, mu)
    t, v = np.asarray(tr.t), np.asarray(tr.qd[:, :2]) @ down
    i, j = np.searchsorted(t, 0.5), len(t) - 1
    a = (v[j] - v[i]) / (t[j] - t[i])
    np.testing.assert_allclose(a, G * (np.sin(angle) - mu * np.cos(angle)), rtol=1e-2)
    normal = np.array([-np.sin(angle), np.cos(angle), 0.0])
    np.testing.assert_allclose(float(jnp.sum(tr.contact_force[-1] @ normal)), G * np.cos(angle), rtol=1e-6)


def test_block_sticks_on_an_incline_below_the_friction_angle_up_to_the_regularised_creep():
    """tan(angle) < mu: Coulomb holds the block. The regularised law lets it creep at the speed
    where mu N v / sqrt(v^2 + v_s^2) = m g sin(angle), v = v_s tan / sqrt(mu^2 - tan^2)."""
    angle, mu, v_s = np.deg2rad(20.0), 0.6, 1e-2
    tr, down = incline(angle, mu, v_s)
    v = np.asarray(tr.qd[:, :2]) @ down
    tan = np.tan(angle)
    creep = v_s * tan / np.sqrt(mu**2 - tan**2)
    np.testing.assert_allclose(v[-1], creep, rtol=1e-2)
    assert np.max(np.abs(v)) < 2 * creep  # never slides: sliding would reach g (sin - mu cos) t


def friction_per_load(v, mu_s, mu_k, v_s):
    """The documented regularised law: |friction| / normal force at slip speed v."""
    mu = mu_k + (mu_s - mu_k) / (1.0 + (v / (10.0 * v_s)) ** 4)
    return mu * v / np.sqrt(v * v + v_s * v_s)


MU_S, MU_K = 0.4, 0.3


def test_the_friction_law_holds_and_creeps_as_documented():
    """The largest friction per load max_v mu(v) v / sqrt(v^2 + v_s^2) (the steepest slope held)
    and the creep speeds in docs/contact.md, from the law as gvsjax evaluates it."""
    v_s = 1e-2
    v = np.linspace(1e-6, 0.5, 200001)
    for mu_k, hold in ((0.0, 0.948), (0.75, 0.967), (1.0, 1.0)):
        law = np.asarray(penetration.friction_coefficient(jnp.asarray(v * v), 1.0, mu_k, v_s)) * v
        assert abs(law.max() - hold) < 1.5e-3, (mu_k, law.max())
        for tan, creep in ((0.5, 0.58), (0.8, 1.34), (0.9, 2.09)):
            assert v[np.argmax(law >= tan)] <= creep * v_s * (1 + 1e-3)


def test_two_coefficients_hold_a_block_below_the_static_angle_up_to_the_creep():
    """20 deg: tan = 0.364 < mu_s = 0.4 (but > mu_k = 0.3): the block creeps at the speed where
    the regularised law balances the slope, v_s tan / sqrt(mu_s^2 - tan^2) within 1% (the fall
    towards mu_k raises it by 0.3%)."""
    angle, v_s = np.deg2rad(20.0), 1e-3
    tr, down = incline(angle, MU_K, v_s, static=MU_S)
    v = np.asarray(tr.qd[:, :2]) @ down
    tan = np.tan(angle)
    creep = brentq(lambda x: friction_per_load(x, MU_S, MU_K, v_s) - tan, 0.0, 5 * v_s, xtol=1e-15)
    np.testing.assert_allclose(creep, v_s * tan / np.sqrt(MU_S**2 - tan**2), rtol=1e-2)
    np.testing.assert_allclose(v[-1], creep, rtol=1e-2)
    assert np.max(np.abs(v)) < 2 * creep  # with mu_k alone it would slide at g (sin - mu_k cos)


def test_two_coefficients_slide_above_the_static_angle_at_the_kinetic_rate():
    """25 deg: tan = 0.466 > mu_s: the block slides, at g (sin - mu_k cos) once past the slow slip."""
    angle = np.deg2rad(25.0)
    tr, down = incline(angle, MU_K, 1e-3, static=MU_S)
    t, v = np.asarray(tr.t), np.asarray(tr.qd[:, :2]) @ down
    i, j = np.searchsorted(t, 0.5), len(t) - 1
    np.testing.assert_allclose((v[j] - v[i]) / (t[j] - t[i]), G * (np.sin(angle) - MU_K * np.cos(angle)), rtol=1e-2)


def test_a_launched_block_stops_in_the_kinetic_distance():
    """Flat ground, launched at 1 m/s: it stops after v0^2 / (2 mu_k g); the static coefficient
    only acts in the last centimetre per second."""
    tr, down = incline(0.0, MU_K, 1e-3, static=MU_S, speed=1.0, duration=0.6)
    travel = (np.asarray(tr.q[-1, :2]) - np.asarray(tr.q[0, :2])) @ down
    assert abs(float(np.asarray(tr.qd[-1, :2]) @ down)) < 1e-3
    np.testing.assert_allclose(travel, 1.0 / (2 * MU_K * G), rtol=5e-3)


# ----------------------------------------------------------------------------
# a soft cantilever propped on a frictionless plane

E, R0, RHO = 1e9, 0.02, 1000.0
EI, W = E * np.pi * R0**4 / 4, RHO * np.pi * R0**2 * G


def propped(plane_y, stiffness=1e7) -> gv.Robot:
    """A horizontal cantilever (clamped at the origin along +x, weight W per metre) over a
    plane at height plane_y. Quadratic curvature: the propped cantilever's exact shape."""
    link = gv.SoftLink(length=1.0, radius=R0, material=gv.Material(E, RHO, 0.0, 0.5), joint=gv.Joint("fixed"),
                       basis=gv.StrainBasis(orders=(-1, -1, 2, -1, -1, -1), kind="legendre"), n_gauss=4)
    c = gv.Contact(obstacles=(gv.Plane(point=(0.0, plane_y, 0.0)),), rod=gv.Penalty(stiffness=stiffness),
                   n_points=11)
    return gv.Robot(links=(link,), gravity=G, contact=c)


def reaction(plane_y):
    robot = propped(plane_y)
    q = gv.equilibrium(robot).q
    force, _ = contact.report(robot, q, jnp.zeros_like(q), 0.0)
    return jnp.sum(force[:, 1])


def test_propped_cantilever_on_a_frictionless_plane_carries_the_beam_theory_reaction():
    """Free sag W L^4 / 8 EI, held at the plane (tip deflection d): R = 3 EI / L^3 (sag - d);
    and dR / d(plane height) = 3 EI / L^3."""
    sag = W / (8 * EI)
    d = 0.5 * sag
    plane_y = -d - R0  # the rod's underside touches at tip deflection d
    value, slope = jax.value_and_grad(reaction)(plane_y)
    np.testing.assert_allclose(float(value), 3 * EI * (sag - d), rtol=2e-2)
    np.testing.assert_allclose(float(slope), 3 * EI, rtol=3e-2)


# ----------------------------------------------------------------------------
# a thin bar between two contact samples


def test_a_bar_thinner_than_the_sample_spacing_pushes_the_rod_wherever_it_lies():
    """The paper's arm hanging straight (21 samples, 5 cm apart) against a 1 cm bar across it,
    1 mm deep: every sample's own ball misses the bar, yet the force is the penalty integral
    k int (a + r - sqrt(rho^2 + u^2))_+ du, the same wherever the bar lies between samples."""
    k, a, depth = 1e6, 0.005, 1e-3
    arm = gv.paper_arm()
    r = gv.PAPER_ARM["radius"]
    rho = a + r - depth
    u = np.linspace(-0.02, 0.02, 400001)
    exact = k * np.trapezoid(np.clip(a + r - np.sqrt(rho**2 + u**2), 0.0, None), u)
    q = jnp.zeros(arm.n_dofs)

    @jax.jit
    def push(y):
        bar = gv.Capsule(start=(rho, y, -0.2), end=(rho, y, 0.2), radius=a)
        robot = arm.replace(contact=gv.Contact(obstacles=(bar,), rod=gv.Penalty(stiffness=k)))
        force, gap = contact.report(robot, q, q, 0.0)
        return jnp.sum(force, axis=0), gap

    for y in (-0.4, -0.4125, -0.425, -0.44):  # on a sample, a quarter and a half spacing off, ...
        force, gap = push(y)
        np.testing.assert_allclose(float(force[0]), -exact, rtol=1e-2)
        centre_gap = np.hypot(rho, np.asarray(y) + np.linspace(0.0, 1.0, 21)) - a - r
        if y in (-0.4125, -0.425):
            assert np.all(centre_gap > 0)  # a ball at each sample would not touch it


# ----------------------------------------------------------------------------
# jit, vmap over obstacle layouts, grad with respect to obstacle positions


def test_vmap_over_plane_heights_and_grad_of_the_rest_height_with_respect_to_the_plane():
    def rest(height):
        tr = gv.simulate(ball(gv.Plane(point=jnp.stack([0.0, height, 0.0]))), 0.5, n_steps=500,
                         q0=jnp.array([0.07]) + height, check_stability=False)
        return tr.q[-1, 0]

    heights = jnp.array([0.0, 0.01, -0.02])
    batched = jax.jit(jax.vmap(rest))(heights)
    gap = smooth_gap(MASS * G, 1e5, 1e-4)
    np.testing.assert_allclose(np.asarray(batched), np.asarray(heights) + BALL + gap, atol=1e-8)
    slope = jax.jit(jax.grad(rest))(0.01)
    assert np.isfinite(float(slope))
    np.testing.assert_allclose(float(slope), 1.0, atol=1e-6)


# ----------------------------------------------------------------------------
# bad input


@pytest.mark.parametrize("make, name", [
    (lambda: gv.Contact(rod=gv.Penalty(stiffness=-1.0)), "contact.rod.stiffness"),
    (lambda: gv.Contact(site=gv.Penalty(smoothing=0.0)), "contact.site.smoothing"),
    (lambda: gv.Contact(rod=gv.Penalty(friction=-0.1)), "contact.rod.friction"),
    (lambda: gv.Contact(rod=gv.Penalty(friction=0.5, static_friction=0.4)), "contact.rod.static_friction"),
    (lambda: gv.Contact(n_points=1), "contact.n_points"),
    (lambda: gv.Contact(nearest=0), "contact.nearest"),
    (lambda: gv.Contact(pairs=0), "contact.pairs"),
    (lambda: gv.Contact(nearest=4, pairs=8), "contact.pairs"),
    (lambda: gv.Contact(obstacles=(gv.Sphere(radius=0.0),)), "contact.obstacles[0].radius"),
    (lambda: gv.Contact(obstacles=(gv.Plane(normal=(0.0, 0.0, 0.0)),)), "contact.obstacles[0].normal"),
    (lambda: gv.Contact(obstacles=(gv.Capsule(start=(0.0, 0.0, 0.0), end=(0.0, 0.0, 0.0)),)), "obstacles[0].end"),
    (lambda: gv.Contact(obstacles=(gv.Box(rotation=((1.0, 0.0, 0.0),) * 3),)), "obstacles[0].rotation"),
    (lambda: gv.Contact(obstacles=(gv.Box(half_extents=(0.1, 0.1)),)), "obstacles[0].half_extents"),
    (lambda: gv.Contact(obstacles=((0.0, 1.0, 0.0),)), "contact.obstacles[0]"),
    (lambda: gv.Contact(sites=(gv.ContactSite(link=0),)), "contact.sites[0].link"),
])
def test_bad_contact_input_names_the_parameter_before_compiling(make, name):
    robot = gv.paper_arm().replace(contact=make())
    raises_naming(name, gv.simulate, robot, 0.1, 1e-3)


def test_float32_run_with_contact_stays_float32_and_matches_float64():
    link = gv.SoftLink(length=1.0, radius=0.02, material=gv.Material(1e9, 1000.0, 0.0, 0.5), joint=gv.Joint("fixed"),
                       basis=gv.StrainBasis(orders=(-1, -1, 1, -1, -1, -1)), n_gauss=2)
    robot = gv.Robot(links=(link,), gravity=G, contact=gv.Contact(obstacles=(gv.Plane(point=(0.0, -0.03, 0.0)),),
                                                                  n_points=5))
    runs = [gv.simulate(robot, 0.05, n_steps=1000, dtype=d, check_stability=False) for d in (jnp.float32, jnp.float64)]
    assert runs[0].contact_gap.dtype == jnp.float32 and runs[0].q.dtype == jnp.float32
    assert float(runs[1].contact_gap[-1, -1]) < 0  # the tip has reached the plane
    np.testing.assert_allclose(np.asarray(runs[0].contact_gap), np.asarray(runs[1].contact_gap), atol=2e-6)


# ----------------------------------------------------------------------------
# a soft link visited by lax.scan touches as the unrolled one


@pytest.mark.extended
def test_a_scanned_link_touches_as_the_unrolled_one():
    """The same bent arm against a bar and a ball, its kinematics scanned or unrolled: the same
    contact forces, gaps and motion (the samples are read from the scan's stacked points)."""
    obstacles = (gv.Capsule(start=(0.12, -0.3, 0.6), end=(0.12, 0.3, 0.6), radius=0.03),
                 gv.Sphere(centre=(-0.1, 0.0, 0.9), radius=0.1))
    q0 = jnp.asarray(np.random.default_rng(0).normal(size=5)) * 0.3
    qd0 = jnp.asarray(np.random.default_rng(1).normal(size=5))
    out = {}
    for recursion in ("scan", "unrolled"):
        arm = gv.soft_arm(bending_order=1, stretch_order=-1, n_gauss=2, recursion=recursion)
        robot = arm.replace(contact=gv.Contact(obstacles=obstacles, n_points=11))
        force, gap = contact.report(robot, q0, qd0, 0.0)
        tr = gv.simulate(robot, 0.02, n_steps=20, q0=q0, qd0=qd0, integrator="rk4", check_stability=False)
        out[recursion] = (np.asarray(force), np.asarray(gap), np.asarray(tr.q[-1]))
    assert out["scan"][1].min() < -1e-3 and np.abs(out["scan"][0]).max() > 10.0  # pressing
    for a, b in zip(out["scan"], out["unrolled"]):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)


def test_stacked_spheres_and_capsules_give_the_law_of_each_obstacle_alone():
    """The law over stacks of static spheres and capsules (one component-wise pass, the profile's
    derivatives by hand) equals the sum of the law over each obstacle alone through autodiff, with
    friction, at pieces near, touching and inside them."""
    rng = np.random.default_rng(0)
    n_c = 9
    p = jnp.asarray(rng.uniform(-0.2, 0.2, (n_c, 3)))
    R = jnp.asarray(np.linalg.qr(rng.normal(size=(n_c, 3, 3)))[0])
    eta = jnp.asarray(rng.normal(size=(n_c, 6)))
    radius, half = jnp.full(n_c, 0.03), 0.02
    lo, hi = jnp.full(n_c, -half).at[0].set(0.0), jnp.full(n_c, half).at[-1].set(0.0)
    obstacles = (gv.Sphere((0.0, 0.05, 0.0), 0.1), gv.Capsule((-0.3, 0.0, 0.1), (0.3, 0.1, 0.0), 0.05),
                 gv.Sphere((0.1, -0.1, 0.1), 0.08), gv.Capsule((0.0, -0.3, -0.1), (0.0, 0.3, -0.1), 0.02),
                 gv.Plane((0.0, -0.15, 0.0)))
    pen = contact.Penalty(stiffness=1e6, damping=1e3, smoothing=1e-3, friction=0.4)
    w, f, g, e = contact.law(p, R, eta, radius, lo, hi, obstacles, pen, 0.0)
    # a still "moving" obstacle takes the law one obstacle at a time, its derivatives by autodiff
    still = lambda o: o.replace(motion=lambda s: jnp.zeros(3))  # noqa: E731
    alone = [contact.law(p, R, eta, radius, lo, hi, (still(o),), pen, 0.0) for o in obstacles]
    assert float(jnp.max(jnp.abs(f))) > 1.0 and float(jnp.min(g)) < 0.0  # some pieces do touch
    np.testing.assert_allclose(w, sum(a[0] for a in alone), rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(f, sum(a[1] for a in alone), rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(g, jnp.min(jnp.stack([a[2] for a in alone]), axis=0))
    np.testing.assert_allclose(e, sum(a[3] for a in alone), rtol=1e-12, atol=1e-12)
