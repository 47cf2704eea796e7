"""gvsjax vs PyElastica on the paper's basketball swing (also the paper's Fig. 4 check).

The same arm (``gvsjax.core.robots.PAPER_ARM``: 1 m, r = 5 cm, rho = 1000, E = 5 MPa,
G = E/3, eta = 1e5 Pa s, gravity 9.81 along -y), the same swing
theta(t) = 210 deg (t/T)^2 of the base frame about +z, the ball as a constant
5.886 N force along -y on the tip, simulated to release at delta*T
(T = 2 s, delta = 0.9 unless told otherwise).

PyElastica model: a ``CosseratRod`` with 100 elements (shearable, extensible,
all six strains), position Verlet at the largest stable step (searched), the
base prescribed through PyElastica's constraint API (``SwingingBase``: node 0
held at the origin, element 0's frame set to R_z(theta(t)) and its angular
velocity to theta'(t)), gravity (``GravityForces``), the tip force
(``TipForce``), and damping:

* ``kv`` (default): Kelvin-Voigt bending damping, the same law as gvsjax
  (internal couple 3 eta I dkappa/dt, SoRoSim's convention), as a damper of
  PyElastica's damping API (``KelvinVoigtDamper``): for a planar rod
  dkappa/dt = domega/ds exactly, so the couple at the Voronoi node between
  elements j, j+1 is 3 eta I (omega_{j+1} - omega_j) / l_j. It is applied by
  a backward-Euler step after each Verlet step (a tridiagonal solve), since
  explicitly it would limit dt to ~2e-7 s. Torsion gets eta J the same way.
  Stretch and shear (inactive in gvsjax) are left undamped.
* ``linear``: PyElastica's ``AnalyticalLinearDamper`` (uniform constant gamma,
  v <- v exp(-gamma dt)). It damps absolute velocities, not strain rates, so no
  constant matches Kelvin-Voigt: gamma = 2 zeta_1 omega_1 = 3 eta omega_1^2 / E
  gives the first bending mode the same damping ratio as Kelvin-Voigt but
  also drags the rigid swing. Reported to quantify that mismatch.

gvsjax: ``gv.paper_arm(tip_force=5.886)`` (2 monomial bending modes, 5 Gauss
points), the basketball task's default integration (40 ``ars443`` steps per
throw); 300 RK4 steps per throw (the stable RK4 peer) is timed in the same run.

    python experiments/benchmarks/bench_pyelastica.py                 # all parts, ~10 min on 2 shared cores
    python experiments/benchmarks/bench_pyelastica.py --quick         # fewer stability/extrapolation runs
    python experiments/benchmarks/bench_pyelastica.py --only-convergence &   # the table in a 2nd process, then
    python experiments/benchmarks/bench_pyelastica.py --dt 1.33e-4    # skip the search (its result on this machine)

Writes benchmarks/pyelastica.json, figures/fig4_flight_paths.png and prints
Markdown tables.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import jax
import jax.numpy as jnp
import numpy as np
from bench_sim import configurations, load_average, timed  # this folder is on sys.path when run as a script

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation
from gvsjax.tasks import basketball as bb

THETA_F = math.radians(210.0)
BALL = 5.886  # N
Y_FLOOR = -1.95  # m, the task's floor
P = gv.PAPER_ARM
HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


# ----------------------------------------------------------------------------- PyElastica

def _elastica():
    import elastica as ea
    from numba import njit

    @njit(cache=True)
    def kv_implicit(omega, inv_J, a_bend, a_twist, dt):
        """One backward-Euler step of the Kelvin-Voigt couples on omega (3, n), in place:
        J_i w_i' = a_{i-1} (w_{i-1} - w_i) + a_i (w_{i+1} - w_i), a_j = c / l_j at Voronoi node j;
        element 0 is prescribed (Dirichlet), the tip end is free (Thomas algorithm)."""
        n = omega.shape[1]
        cp = np.empty(n)
        dp = np.empty(n)
        for k in range(3):
            a = a_twist if k == 2 else a_bend
            cp[0] = 0.0
            dp[0] = omega[k, 0]
            for i in range(1, n):
                m = 1.0 / inv_J[k, k, i]
                left = dt * a[i - 1]
                right = dt * a[i] if i < n - 1 else 0.0
                diag = m + left + right - (-left) * cp[i - 1]
                cp[i] = -right / diag
                dp[i] = (m * omega[k, i] + left * dp[i - 1]) / diag
            for i in range(n - 2, 0, -1):
                dp[i] -= cp[i] * dp[i + 1]
            for i in range(1, n):
                omega[k, i] = dp[i]

    class KelvinVoigtDamper(ea.DamperBase):
        """Strain-rate (Kelvin-Voigt) damping of bending and torsion, as in gvsjax, integrated
        implicitly after each step (like AnalyticalLinearDamper, it costs no stability: explicit
        Kelvin-Voigt at 100 elements would need dt < l^2 rho / (6 eta) ~ 2e-7 s)."""

        def __init__(self, time_step, eta, radius, **kwargs):
            super().__init__(**kwargs)
            I = math.pi * radius**4 / 4.0
            lv = np.append(self._system.rest_voronoi_lengths, 1.0)
            self.a_bend = 3.0 * eta * I / lv  # SoRoSim: eta diag(J, 3I, 3I, ...)
            self.a_twist = eta * 2.0 * I / lv
            self.dt = float(time_step)

        def dampen_rates(self, system, time):
            kv_implicit(system.omega_collection, system.inv_mass_second_moment_of_inertia,
                        self.a_bend, self.a_twist, self.dt)

    class TipForce(ea.NoForces):
        """A constant world-frame force on the last node (the ball's weight)."""

        def __init__(self, force):
            super().__init__()
            self.force = np.asarray(force, dtype=np.float64)

        def apply_forces(self, system, time=0.0):
            system.external_forces[:, -1] += self.force

    class SwingingBase(ea.ConstraintBase):
        """Node 0 fixed; element 0's frame follows R_z(theta(t)): theta = theta_F (t/T)^2, or any
        ``law(t) -> (theta, dtheta/dt)`` (rad, rad/s) with theta(0) = 0."""

        def __init__(self, base_position, base_director, T=None, law=None, **kwargs):
            super().__init__(**kwargs)
            self.T = None if T is None else float(T)
            self.law = law
            self.base = np.array(base_position)
            # the rod is built hanging along -y with d1 = +z: R_z(theta(0)) below must be its frame
            assert np.allclose(base_director, self._frame(self._theta(0.0)[0])), base_director

        @staticmethod
        def _frame(th):
            c, s = math.cos(th), math.sin(th)
            # rows d1, d2, d3: d1 = +z (bending axis), d3 = tangent, d2 = d3 x d1
            return np.array([[0.0, 0.0, 1.0], [-c, -s, 0.0], [s, -c, 0.0]])

        def _theta(self, t):
            if self.law is not None:
                return self.law(t)
            s = t / self.T
            return THETA_F * s * s, 2.0 * THETA_F * s / self.T

        def constrain_values(self, system, time):
            th, _ = self._theta(float(time))
            system.position_collection[:, 0] = self.base
            system.director_collection[:, :, 0] = self._frame(th)

        def constrain_rates(self, system, time):
            _, thd = self._theta(float(time))
            system.velocity_collection[:, 0] = 0.0
            system.omega_collection[:, 0] = (thd, 0.0, 0.0)  # R_z rate in the material frame

    return ea, KelvinVoigtDamper, TipForce, SwingingBase


def first_bending_omega() -> float:
    """First clamped-free bending frequency (rad/s) of the arm, Euler-Bernoulli."""
    I = math.pi * P["radius"] ** 4 / 4.0
    rhoA = P["density"] * math.pi * P["radius"] ** 2
    return 1.8751**2 * math.sqrt(P["youngs_modulus"] * I / (rhoA * P["length"] ** 4))


def swinging_rod(sim, n_elements: int, T: float | None, youngs_modulus: float | None = None, tip_force: float = BALL,
                 gravity: float | None = None, law=None):
    """The arm as a PyElastica rod in ``sim`` (a system collection with constraints and forcing):
    hanging along -y, its base swung by ``SwingingBase`` (the swing of duration ``T``, or the
    angle ``law``), gravity and the ball's weight on the tip.
    ``youngs_modulus``: E (Pa; default the paper's), G = E / (2 (1 + poisson)) as in gvsjax;
    ``tip_force``: the ball's weight (N, along -y; 0: none); ``gravity``: m/s^2 (default the paper's)."""
    ea, _, TipForce, SwingingBase = _elastica()
    E = P["youngs_modulus"] if youngs_modulus is None else float(youngs_modulus)
    rod = ea.CosseratRod.straight_rod(
        n_elements, start=np.zeros(3), direction=np.array([0.0, -1.0, 0.0]), normal=np.array([0.0, 0.0, 1.0]),
        base_length=P["length"], base_radius=P["radius"], density=P["density"],
        youngs_modulus=E, shear_modulus=E / (2.0 * (1.0 + P["poisson"])))
    sim.append(rod)
    sim.constrain(rod).using(SwingingBase, constrained_position_idx=(0,), constrained_director_idx=(0,), T=T,
                             law=law)
    g = P["gravity"] if gravity is None else float(gravity)
    if g:
        sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=np.array([0.0, -g, 0.0]))
    if tip_force:
        sim.add_forcing_to(rod).using(TipForce, force=(0.0, -float(tip_force), 0.0))
    return rod


def pyelastica_throw(T=2.0, delta=0.9, dt=1e-4, n_elements=100, damping="kv", record_every=0,
                     youngs_modulus=None, eta=None):
    """One PyElastica throw to release. Returns dict(tip, tip_velocity, wall_s, setup_s, n_steps,
    path (k, 3) tip positions after steps 1, 1 + record_every, ... if record_every, stretch max
    |1 - |dx|/l0| at release). ``youngs_modulus``, ``eta``: E (Pa) and the Kelvin-Voigt damping
    (Pa s) of ``damping="kv"``; default the paper's."""
    ea, KelvinVoigtDamper, _, _ = _elastica()
    t_setup = time.perf_counter()

    class Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
        pass

    sim = Sim()
    rod = swinging_rod(sim, n_elements, T, youngs_modulus)
    t_rel = delta * T
    n_steps = int(math.ceil(t_rel / dt - 1e-9))
    h = t_rel / n_steps
    if damping == "kv":
        sim.dampen(rod).using(KelvinVoigtDamper, time_step=h, eta=P["damping"] if eta is None else float(eta),
                              radius=P["radius"])
    elif damping == "linear":
        w1 = first_bending_omega()
        gamma = 3.0 * P["damping"] * w1**2 / P["youngs_modulus"]
        sim.dampen(rod).using(ea.AnalyticalLinearDamper, uniform_damping_constant=gamma, time_step=h)
    elif damping != "none":
        raise ValueError(f"damping={damping!r}; allowed: 'kv', 'linear', 'none'")
    sim.finalize()
    stepper = ea.PositionVerlet()
    setup_s = time.perf_counter() - t_setup

    path = []
    t = np.float64(0.0)
    t0 = time.perf_counter()
    for i in range(n_steps):
        t = stepper.step(sim, t, np.float64(h))
        if record_every and i % record_every == 0:
            path.append(rod.position_collection[:, -1].copy())
    wall = time.perf_counter() - t0
    seg = np.linalg.norm(np.diff(rod.position_collection, axis=1), axis=0)
    return dict(tip=rod.position_collection[:, -1].copy(), tip_velocity=rod.velocity_collection[:, -1].copy(),
                wall_s=wall, setup_s=setup_s, n_steps=n_steps, dt=h,
                stretch=float(np.max(np.abs(seg / rod.rest_lengths - 1.0))),
                path=np.array(path) if path else None)


def is_stable(res) -> bool:
    return bool(np.all(np.isfinite(res["tip"])) and np.linalg.norm(res["tip"]) < 2.0 * P["length"]
                and np.linalg.norm(res["tip_velocity"]) < 100.0)


def largest_stable_dt(T, delta, lo=1e-5, hi=1e-3, iters=6):
    """Bisect (geometrically) the largest dt whose throw stays finite and bounded."""
    assert is_stable(pyelastica_throw(T, delta, lo)), f"dt={lo} unstable"
    if is_stable(pyelastica_throw(T, delta, hi)):
        return hi
    for _ in range(iters):
        mid = math.sqrt(lo * hi)
        if is_stable(pyelastica_throw(T, delta, mid)):
            lo = mid
        else:
            hi = mid
    return lo


# ----------------------------------------------------------------------------- gvsjax

def gvsjax_release_fn(n_steps=300, integrator="rk4", **arm):
    robot = gv.paper_arm(tip_force=BALL, **arm)

    def rel(T, delta):
        traj = gv.simulate(robot, delta * T, n_steps=n_steps, save_every=n_steps, check_stability=False,
                           integrator=integrator, base_angle=lambda t: THETA_F * (t / T) ** 2)
        return traj.tip[-1], traj.tip_velocity[-1]

    return rel


def flight(p0, v0, n=200):
    """Ballistic path (n, 2) from release to the floor y = Y_FLOOR; the landing x.

    The basketball task's own flight (``floor_time``, ``flight_point``)."""
    g = P["gravity"]
    p0, v0 = jnp.asarray(p0, float)[:2], jnp.asarray(v0, float)[:2]
    tau = np.linspace(0.0, float(bb.floor_time(p0, v0, g, Y_FLOOR)), n)
    path = np.asarray(bb.flight_point(p0, v0, tau, g))
    return path, float(path[-1, 0])


def convergence_table(T, delta):
    """Release tip state vs n_modes (monomial up to 3, Legendre beyond) and n_gauss. Each row
    runs RK4 at half its linearised stability limit (many modes are stiff: 8 modes need
    dt < 7 us) and at least 4000 steps; differences are against the last (most refined) row."""
    rows = []
    t_rel = T * delta
    for n_modes, n_gauss, basis in [(1, 5, "monomial"), (2, 3, "monomial"), (2, 5, "monomial"),
                                    (2, 8, "monomial"), (3, 5, "monomial"), (4, 5, "legendre"),
                                    (4, 8, "legendre"), (6, 8, "legendre"), (6, 12, "legendre"),
                                    (8, 10, "legendre")]:
        arm = dict(n_modes=n_modes, n_gauss=n_gauss, basis=basis)
        dt_max = gv.stable_step_estimate(gv.paper_arm(tip_force=BALL, **arm), "rk4", np.zeros(n_modes + 1))
        n_steps = max(4000, int(math.ceil(t_rel / (0.5 * dt_max))))
        t0 = time.perf_counter()
        p, v = jax.jit(gvsjax_release_fn(n_steps=n_steps, **arm))(T, delta)
        p, v = np.asarray(p), np.asarray(v)
        rows.append(dict(**arm, n_steps=n_steps, tip=p.tolist(), tip_velocity=v.tolist(),
                         landing_x=flight(p, v)[1], wall_s=time.perf_counter() - t0))
    best = rows[-1]
    for r in rows:
        r["d_tip_mm"] = 1e3 * float(np.linalg.norm(np.subtract(r["tip"], best["tip"])))
        r["d_vel_mm_s"] = 1e3 * float(np.linalg.norm(np.subtract(r["tip_velocity"], best["tip_velocity"])))
        r["d_landing_cm"] = 1e2 * (r["landing_x"] - best["landing_x"])
    return rows


def cached_convergence(T, delta, path, wait_s=3600.0):
    """The convergence table from ``path`` if a ``--only-convergence`` run wrote it (waiting
    for one still running, marked by ``path + '.lock'``), else computed here."""
    t0 = time.perf_counter()
    while os.path.exists(path + ".lock") and time.perf_counter() - t0 < wait_s:
        time.sleep(5.0)
    if os.path.exists(path):
        with open(path) as fh:
            saved = json.load(fh)
        if saved["T"] == T and saved["delta"] == delta:
            return saved["rows"]
    rows = convergence_table(T, delta)
    with open(path, "w") as fh:
        json.dump(dict(T=T, delta=delta, rows=rows), fh, indent=2)
    return rows


def plot_paths(paths: dict, out: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2))
    styles = ["-", "--", ":", "-."]
    for (label, (swing, fl)), ls in zip(paths.items(), styles):
        line, = ax.plot(fl[:, 0], fl[:, 1], ls, lw=1.6, label=label)
        if swing is not None:
            ax.plot(swing[:, 0], swing[:, 1], ls, lw=0.8, color=line.get_color(), alpha=0.6)
    ax.axhline(Y_FLOOR, color="k", lw=0.8)
    ax.plot([0], [0], "ko", ms=4)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("Ball flight, T = 2 s, delta = 0.9 (thin: tip path during the swing)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--T", type=float, default=2.0)
    ap.add_argument("--delta", type=float, default=0.9)
    ap.add_argument("--n-elements", type=int, default=100)
    ap.add_argument("--dt", type=float, default=None, help="PyElastica step (default: searched)")
    ap.add_argument("--extrapolate-throws", type=int, default=3)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--only-convergence", action="store_true",
                    help="only the gvsjax n_modes/n_gauss table (run it beside the main run)")
    ap.add_argument("--convergence-json", default=os.path.join(ROOT, "benchmarks", "pyelastica_convergence.json"))
    ap.add_argument("--json", default=os.path.join(ROOT, "benchmarks", "pyelastica.json"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "figures", "fig4_flight_paths.png"))
    args = ap.parse_args()
    T, delta = args.T, args.delta
    if args.only_convergence:
        open(args.convergence_json + ".lock", "w").close()
        try:
            rows = convergence_table(T, delta)
            with open(args.convergence_json, "w") as fh:
                json.dump(dict(T=T, delta=delta, rows=rows, load_end=load_average()), fh, indent=2)
        finally:
            os.remove(args.convergence_json + ".lock")
        return
    load_start = load_average()
    print("load at start:", load_start)

    # --- PyElastica: warm numba, then the largest stable step
    pyelastica_throw(0.1, 0.9, 1e-4, args.n_elements)
    dt = args.dt or largest_stable_dt(T, delta, iters=3 if args.quick else 6)
    print(f"PyElastica largest stable dt ~ {dt:.3g} s")
    pe = pyelastica_throw(T, delta, dt, args.n_elements, record_every=max(1, int(0.01 / dt)))
    pe_half = pyelastica_throw(T, delta, dt / 2, args.n_elements)
    pe_lin = pyelastica_throw(T, delta, dt, args.n_elements, damping="linear")
    pe_none = pyelastica_throw(T, delta, dt, args.n_elements, damping="none")

    # --- gvsjax: the task's default integration and the RK4 peer, batch 1 and batch 1024
    # (T ~ U[0.5, 3], delta ~ U[0.85, 1])
    k1, k2 = jax.random.split(jax.random.PRNGKey(0))
    Tb = jax.random.uniform(k1, (1024,), minval=0.5, maxval=3.0)
    db = jax.random.uniform(k2, (1024,), minval=0.85, maxval=1.0)
    sim_seconds = float(jnp.sum(Tb * db))
    gvsjax_runs = []
    for integrator, n_steps in configurations():
        rel = jax.jit(gvsjax_release_fn(n_steps, integrator))
        compile1, run1 = timed(rel, T, delta, repeats=20)
        p, v = (np.asarray(a) for a in rel(T, delta))
        compileb, runb = timed(jax.jit(jax.vmap(gvsjax_release_fn(n_steps, integrator))), Tb, db, repeats=5)
        gvsjax_runs.append(dict(integrator=integrator, n_steps=n_steps, batch1_s=run1, batch1_compile_s=compile1,
                                batch1024_s=runb, batch1024_compile_s=compileb, tip=p.tolist(),
                                tip_velocity=v.tolist()))
    default = gvsjax_runs[0]
    run1, compile1, runb, compileb = (default[k] for k in ("batch1_s", "batch1_compile_s", "batch1024_s",
                                                             "batch1024_compile_s"))
    p_gv, v_gv = np.asarray(default["tip"]), np.asarray(default["tip_velocity"])
    # PyElastica looped: time a few throws of the batch, extrapolate linearly in simulated time
    n_ex = 2 if args.quick else args.extrapolate_throws
    t_ex, s_ex = 0.0, 0.0
    for i in range(n_ex):
        r = pyelastica_throw(float(Tb[i]), float(db[i]), dt, args.n_elements)
        t_ex += r["wall_s"] + r["setup_s"]
        s_ex += float(Tb[i] * db[i])
    pe_batch_s = t_ex / s_ex * sim_seconds

    # --- Fig. 4: flight paths, gvsjax 2 modes and converged, PyElastica
    conv = cached_convergence(T, delta, args.convergence_json)
    best = conv[-1]
    task = bb.BasketballParams(arm=gv.paper_arm(tip_force=BALL))  # the task's swing, drawn at 1800 RK4 steps
    swing2 = jax.jit(lambda: bb.swing(task, T, delta, n_steps=1800, integrator="rk4", save_every=18).tip)()
    paths = {
        f"gvsjax, 2 modes ({default['n_steps']} {default['integrator']} steps)":
            (np.asarray(swing2)[:, :2], flight(p_gv, v_gv)[0]),
        f"gvsjax, {best['n_modes']} Legendre modes (converged)":
            (None, flight(np.array(best["tip"]), np.array(best["tip_velocity"]))[0]),
        f"PyElastica, {args.n_elements} elements, KV damping": (pe["path"][:, :2],
                                                                 flight(pe["tip"], pe["tip_velocity"])[0]),
        "PyElastica, AnalyticalLinearDamper": (None, flight(pe_lin["tip"], pe_lin["tip_velocity"])[0]),
    }
    os.makedirs(os.path.dirname(args.figure), exist_ok=True)
    plot_paths(paths, args.figure)

    land = {k: float(v[1][-1, 0]) for k, v in paths.items()}
    d = lambda a, b: 1e2 * float(np.linalg.norm(np.asarray(a)[:2] - np.asarray(b)[:2]))  # noqa: E731
    res = dict(
        T=T, delta=delta, n_elements=args.n_elements, pyelastica_dt=dt, pyelastica_steps=pe["n_steps"],
        gvsjax_integrator=default["integrator"], gvsjax_steps=default["n_steps"], gvsjax_runs=gvsjax_runs,
        batch1=dict(gvsjax_s=run1, gvsjax_compile_s=compile1, pyelastica_s=pe["wall_s"],
                    pyelastica_setup_s=pe["setup_s"], ratio=pe["wall_s"] / run1),
        batch1024=dict(gvsjax_s=runb, gvsjax_compile_s=compileb, pyelastica_s_extrapolated=pe_batch_s,
                       pyelastica_throws_timed=n_ex, simulated_s=sim_seconds, ratio=pe_batch_s / runb),
        release=dict(
            gvsjax_tip=p_gv.tolist(), gvsjax_tip_velocity=v_gv.tolist(),
            converged_tip=best["tip"], converged_tip_velocity=best["tip_velocity"],
            pyelastica_tip=pe["tip"].tolist(), pyelastica_tip_velocity=pe["tip_velocity"].tolist(),
            pyelastica_max_stretch=pe["stretch"],
            d_tip_cm=dict(gvsjax2_vs_pyelastica=d(p_gv, pe["tip"]), converged_vs_pyelastica=d(best["tip"], pe["tip"]),
                          gvsjax2_vs_converged=d(p_gv, best["tip"]),
                          pyelastica_dt_vs_half_dt=d(pe["tip"], pe_half["tip"]),
                          pyelastica_linear_damper_vs_kv=d(pe_lin["tip"], pe["tip"]),
                          pyelastica_undamped_vs_kv=d(pe_none["tip"], pe["tip"])),
            d_velocity_cm_s=dict(gvsjax2_vs_pyelastica=d(v_gv, pe["tip_velocity"]),
                                 converged_vs_pyelastica=d(best["tip_velocity"], pe["tip_velocity"]))),
        landing_x=land, convergence=conv,
        linear_damper_gamma=3.0 * P["damping"] * first_bending_omega() ** 2 / P["youngs_modulus"],
        load_start=load_start, load_end=load_average(), jax=jax.__version__,
    )
    os.makedirs(os.path.dirname(args.json), exist_ok=True)
    with open(args.json, "w") as fh:
        json.dump(res, fh, indent=2)
    print_tables(res)


def print_tables(r: dict) -> None:
    b1, bb, rel = r["batch1"], r["batch1024"], r["release"]
    print(f"\nT = {r['T']} s, delta = {r['delta']}; PyElastica {r['n_elements']} elements, "
          f"dt = {r['pyelastica_dt']:.3g} s ({r['pyelastica_steps']} steps); "
          f"gvsjax 2 modes, {r['gvsjax_steps']} {r['gvsjax_integrator']} steps\n")
    print("| batch | gvsjax wall s | PyElastica wall s | ratio | gvsjax compile s |")
    print("|---|---|---|---|---|")
    print(f"| 1 | {b1['gvsjax_s']:.2e} | {b1['pyelastica_s']:.2f} | {b1['ratio']:,.0f}x | "
          f"{b1['gvsjax_compile_s']:.1f} |")
    print(f"| 1024 | {bb['gvsjax_s']:.3f} | {bb['pyelastica_s_extrapolated']:.0f} (extrapolated from "
          f"{bb['pyelastica_throws_timed']} throws) | {bb['ratio']:,.0f}x | {bb['gvsjax_compile_s']:.1f} |")
    print("\n| gvsjax integration | batch 1 s | ratio | batch 1024 s | ratio |")
    print("|---|---|---|---|---|")
    for g in r["gvsjax_runs"]:
        print(f"| {g['n_steps']} {g['integrator']} steps | {g['batch1_s']:.2e} | "
              f"{b1['pyelastica_s'] / g['batch1_s']:,.0f}x | {g['batch1024_s']:.3f} | "
              f"{bb['pyelastica_s_extrapolated'] / g['batch1024_s']:,.0f}x |")
    print("\n| release tip position difference | cm |")
    print("|---|---|")
    for k, v in rel["d_tip_cm"].items():
        print(f"| {k} | {v:.2f} |")
    print(f"\nPyElastica max stretch at release: {rel['pyelastica_max_stretch']:.2e}")
    print("\n| flight path | landing x (m) |")
    print("|---|---|")
    for k, v in r["landing_x"].items():
        print(f"| {k} | {v:.3f} |")
    print("\nRelease state vs n_modes / n_gauss (RK4 at half its stability limit; differences vs the last row)\n")
    print("| n_modes | n_gauss | basis | RK4 steps | tip x, y (m) | d tip (mm) | d tip velocity (mm/s) "
          "| d landing (cm) |")
    print("|---|---|---|---|---|---|---|---|")
    for c in r["convergence"]:
        print(f"| {c['n_modes']} | {c['n_gauss']} | {c['basis']} | {c['n_steps']} | "
              f"{c['tip'][0]:.4f}, {c['tip'][1]:.4f} | {c['d_tip_mm']:.2f} | {c['d_vel_mm_s']:.1f} | "
              f"{c['d_landing_cm']:.1f} |")
    print(f"\nload: {r['load_start']} -> {r['load_end']}")


if __name__ == "__main__":
    main()
