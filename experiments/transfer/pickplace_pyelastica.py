"""PyElastica's side of the pick-and-place transfer (``transfer_pickplace_pyelastica.py``).

The paper's arm as a shearable, extensible ``CosseratRod``, its base frame turned by the task's
cycloidal angle law, and the tendon: a cable at ``OFFSET`` from the midline (gvsjax's local +y,
PyElastica's -d2), anchored at the tip and sliding without friction through a guide at every node
(``TendonForce``). Episodes are cached one by one (atomic writes; a rerun resumes). The tendon's
checks (``validate_tendon``): a straight rod without gravity under a constant tension against the
closed-form arc (curvature T offset / (E I), shortened by T / (E A)), and the horizontal arm under
gravity against gvsjax's statics (``gv.equilibrium``).
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.append(str(Path(__file__).resolve().parents[1] / "benchmarks"))  # bench_pyelastica, in the benchmarks folder
from bench_pyelastica import P, _elastica, is_stable, swinging_rod
from transfer_pyelastica import bending_arm, cosserat_arm

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation
from gvsjax.core.kinematics import backbone
from gvsjax.tasks import pickplace as pp

OFFSET = 0.025  # m, the task's tendon (paper_arm(tendon_offset=0.025))


# ----------------------------------------------------------------------------- PyElastica

def _tendon():
    """The ``TendonForce`` forcing class (PyElastica's forcing API) and its numba kernel."""
    from numba import njit

    ea = _elastica()[0]

    @njit(cache=True)
    def tendon_loads(x, Q, offset, T, forces, torques):
        """Adds the cable's loads to forces (3, n + 1) (world) and torques (3, n) (material frames)."""
        n = Q.shape[2]
        e = np.empty((3, n + 1))
        for i in range(n + 1):
            a, b = max(i - 1, 0), min(i, n - 1)
            v = -(Q[1, :, a] + Q[1, :, b])  # -d2: gvsjax's local +y
            e[:, i] = v / math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
        p = x + offset * e
        F = np.zeros((3, n + 1))
        for i in range(n):
            s = p[:, i + 1] - p[:, i]
            u = T * s / math.sqrt(s[0] ** 2 + s[1] ** 2 + s[2] ** 2)
            F[:, i] += u
            F[:, i + 1] -= u
        F[:, 0] = 0.0  # node 0 is held: the cable goes on into the base (the actuator)
        C = np.empty((3, n + 1))  # couple of F about the node: offset e x F
        for i in range(n + 1):
            C[0, i] = offset * (e[1, i] * F[2, i] - e[2, i] * F[1, i])
            C[1, i] = offset * (e[2, i] * F[0, i] - e[0, i] * F[2, i])
            C[2, i] = offset * (e[0, i] * F[1, i] - e[1, i] * F[0, i])
        for k in range(n):
            c = 0.5 * (C[:, k] + C[:, k + 1])
            if k == 0:
                c += 0.5 * C[:, 0]
            if k == n - 1:
                c += 0.5 * C[:, n]
            for r in range(3):
                torques[r, k] += Q[r, 0, k] * c[0] + Q[r, 1, k] * c[1] + Q[r, 2, k] * c[2]
        forces += F

    class TendonForce(ea.NoForces):
        """A cable at ``offset`` (m, gvsjax's local +y) anchored at the tip, sliding through a
        frictionless guide at every node, its tension ``law(t)`` (N)."""

        def __init__(self, offset, law):
            super().__init__()
            self.offset = float(offset)
            self.law = law

        def apply_forces(self, system, time=0.0):
            tendon_loads(system.position_collection, system.director_collection, self.offset,
                         float(self.law(float(time))), system.external_forces, system.external_torques)

    return TendonForce


def _s(u):
    """The task's cycloid s(u) and ds/du, u clipped to [0, 1] (``motion.cycloid`` in numpy)."""
    u = min(max(u, 0.0), 1.0)
    return u - math.sin(2.0 * math.pi * u) / (2.0 * math.pi), 1.0 - math.cos(2.0 * math.pi * u)


def episode_laws(theta, tension, step_time, ramp_time=None):
    """Both steps' laws: ``angle(t) -> (theta, theta')`` (rad, rad/s), ``pull(t) -> tension`` (N).

    Step k (k = 0, 1) moves from step k-1's commands (0 before step 1) to (theta[k], tension[k])
    on the cycloid over ``ramp_time`` (default: the whole step, the task's ``motion.controls``),
    then holds them."""
    ramp = step_time if ramp_time is None else ramp_time
    th = (0.0, float(theta[0]), float(theta[1]))
    te = (0.0, float(tension[0]), float(tension[1]))

    def stage(t):
        k = 0 if t < step_time else 1
        return k, (t - k * step_time) / ramp

    def angle(t):
        k, u = stage(t)
        s, ds = _s(u)
        rate = ds / ramp if 0.0 <= u <= 1.0 else 0.0
        return th[k] + (th[k + 1] - th[k]) * s, (th[k + 1] - th[k]) * rate

    def pull(t):
        k, u = stage(t)
        return te[k] + (te[k + 1] - te[k]) * _s(u)[0]

    return angle, pull


def check_laws(params, theta, tension) -> float:
    """Largest difference (rad, rad/s, N) between ``episode_laws`` and the task's ``motion.controls``."""
    T = params.step_time
    t = np.linspace(0.0, T, 41)
    angle, pull = episode_laws(theta, tension, T)
    err = 0.0
    for k, (th0, te0) in enumerate(((0.0, 0.0), (theta[0], tension[0]))):
        a, p = pp.controls(th0, theta[k], te0, tension[k], T)
        th_task = np.asarray(jax.vmap(a)(jnp.asarray(t)))
        rate_task = np.asarray(jax.vmap(jax.grad(a))(jnp.asarray(t)))
        te_task = np.asarray(jax.vmap(p)(jnp.asarray(t)))
        mine = np.array([(*angle(k * T + x), pull(k * T + x)) for x in t])
        err = max(err, float(np.max(np.abs(mine - np.stack([th_task, rate_task, te_task], 1)))))
    return err


def pyelastica_run(angle, pull, t_end, record_at, dt=1e-4, n_elements=100, gravity=None, average_last=0.1):
    """One PyElastica run of the tendon arm to ``t_end``; the tip at each time in ``record_at``.

    Returns dict(tips (k, 3) and tip_velocities (k, 3) at those times, tips_mean (k, 3): the tip's
    mean over the preceding ``average_last`` seconds (the undamped stretch and shear oscillate),
    base_angle_error (rad, at the end), stretch (max |1 - |dx| / l0| at the recorded times), wall_s,
    n_steps, dt)."""
    ea, KelvinVoigtDamper, _, _ = _elastica()
    TendonForce = _tendon()
    t0 = time.perf_counter()

    class Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
        pass

    sim = Sim()
    rod = swinging_rod(sim, n_elements, None, tip_force=0.0, gravity=gravity, law=angle)
    sim.add_forcing_to(rod).using(TendonForce, offset=OFFSET, law=pull)
    n_steps = int(round(t_end / dt))
    h = t_end / n_steps
    sim.dampen(rod).using(KelvinVoigtDamper, time_step=h, eta=P["damping"], radius=P["radius"])
    sim.finalize()
    stepper = ea.PositionVerlet()
    marks = [int(round(r / h)) for r in record_at]
    n_avg = max(1, int(round(average_last / h)))
    tips, means, vels, stretch = [], [], [], 0.0
    acc, acc_n = np.zeros(3), 0
    t = np.float64(0.0)
    for i in range(1, n_steps + 1):
        t = stepper.step(sim, t, np.float64(h))
        if any(m - n_avg < i <= m for m in marks):
            acc += rod.position_collection[:, -1]
            acc_n += 1
        if i in marks:
            tips.append(rod.position_collection[:, -1].copy())
            means.append(acc / acc_n)
            vels.append(rod.velocity_collection[:, -1].copy())
            acc, acc_n = np.zeros(3), 0
            seg = np.linalg.norm(np.diff(rod.position_collection, axis=1), axis=0)
            stretch = max(stretch, float(np.max(np.abs(seg / rod.rest_lengths - 1.0))))
            if not np.all(np.isfinite(rod.position_collection)):
                break
    d3 = rod.director_collection[2, :, 0]
    base_err = abs((math.atan2(d3[0], -d3[1]) - angle(float(t))[0] + math.pi) % (2 * math.pi) - math.pi)
    return dict(tips=np.array(tips), tips_mean=np.array(means), tip_velocities=np.array(vels),
                base_angle_error=base_err, stretch=stretch, wall_s=time.perf_counter() - t0, n_steps=n_steps, dt=h)


def pyelastica_episode(theta, tension, dt, n_elements, step_time=5.0):
    """Both steps of an episode (theta_F and tension per step) from rest: the tip at each step's end."""
    angle, pull = episode_laws(theta, tension, step_time)
    r = pyelastica_run(angle, pull, 2 * step_time, (step_time, 2 * step_time), dt, n_elements)
    ok = len(r["tips"]) == 2 and all(is_stable(dict(tip=p, tip_velocity=v))
                                     for p, v in zip(r["tips"], r["tip_velocities"]))
    return dict(theta=[float(x) for x in theta], tension=[float(x) for x in tension], dt=dt, n_elements=n_elements,
                tips=r["tips"].tolist(), tips_mean=r["tips_mean"].tolist(),
                tip_velocities=r["tip_velocities"].tolist(), stable=bool(ok),
                stretch=r["stretch"], base_angle_error=r["base_angle_error"], wall_s=r["wall_s"],
                n_steps=r["n_steps"])


def _key(i: int, dt: float, n_elements: int) -> str:
    return f"{i}|{dt:.6g}|{n_elements}"


def wait_for(pause_file) -> None:
    if pause_file and os.path.exists(pause_file):
        print(f"  paused while {pause_file} exists", flush=True)
        while os.path.exists(pause_file):
            time.sleep(20.0)


def pyelastica_episodes(theta, tension, idx, dt, n_elements, cache_path, pause_file=None) -> dict:
    """Cached PyElastica episodes of pairs ``idx`` (theta, tension: (n, 2)); resumes from the cache."""
    cache = {}
    if os.path.exists(cache_path):
        with open(cache_path) as fh:
            cache = json.load(fh)

    def current(i):
        c = cache.get(_key(i, dt, n_elements))
        return c is not None and np.allclose(c["theta"], theta[i], rtol=1e-12, atol=0) and np.allclose(
            c["tension"], tension[i], rtol=1e-12, atol=0)

    jobs = [int(i) for i in idx if not current(int(i))]
    print(f"PyElastica dt={dt:.3g}, {n_elements} elements: {len(idx) - len(jobs)} episodes cached, "
          f"{len(jobs)} to run", flush=True)
    t0 = time.perf_counter()
    for k, i in enumerate(jobs, 1):
        wait_for(pause_file)
        cache[_key(i, dt, n_elements)] = pyelastica_episode(theta[i], tension[i], dt, n_elements)
        tmp = cache_path + ".tmp"
        with open(tmp, "w") as fh:
            json.dump(cache, fh)
        os.replace(tmp, cache_path)
        if k % 5 == 0 or k == len(jobs):
            print(f"  {k}/{len(jobs)} ({time.perf_counter() - t0:.0f} s)", flush=True)
    return {int(i): cache[_key(int(i), dt, n_elements)] for i in idx}


def pyelastica_tips(eps: dict, idx) -> tuple[np.ndarray, np.ndarray]:
    """(tips (n, 2, 2), stable (n,)) of cached episodes."""
    tips = np.array([np.array(eps[i]["tips"])[:, :2] if eps[i]["stable"] else np.full((2, 2), np.nan) for i in idx])
    return tips, np.array([eps[i]["stable"] for i in idx])


# ----------------------------------------------------------------------------- tendon validation

def validate_elements(args) -> dict:
    """The closed-form case (no gravity, 30 N) with ``--check-elements`` elements at dt/2: PyElastica's
    discretisation error, and its Richardson extrapolation (error O(1/n): the base holds element 0's
    frame, so the clamp acts half an element out along the rod)."""
    I = math.pi * P["radius"] ** 4 / 4.0
    EI, EA = P["youngs_modulus"] * I, P["youngs_modulus"] * math.pi * P["radius"] ** 2
    T, n1, n2 = 30.0, args.elements, args.check_elements
    angle, pull = episode_laws((0.0, 0.0), (T, T), 5.0, ramp_time=1.0)
    tip = {n: pyelastica_run(angle, pull, 6.0, (6.0,), args.dt / 2, n, gravity=0.0, average_last=0.5)["tips_mean"][0]
           for n in (n1, n2)}
    kap, L = T * OFFSET / EI, P["length"] * (1.0 - T / EA)
    closed = np.array([(1.0 - math.cos(kap * P["length"])) / kap, -math.sin(kap * P["length"]) / kap, 0.0]) * L
    extra = (n2 * tip[n2] - n1 * tip[n1]) / (n2 - n1)
    out = dict(tension=T, dt=args.dt / 2, closed_form=closed.tolist(), extrapolated=extra.tolist(),
               **{f"pyelastica_{n}": tip[n].tolist() for n in (n1, n2)},
               **{f"deflection_error_{n}_mm": 1e3 * float(tip[n][0] - closed[0]) for n in (n1, n2)},
               deflection_error_extrapolated_mm=1e3 * float(extra[0] - closed[0]),
               extrapolated_vs_closed_mm=1e3 * float(np.linalg.norm(extra - closed)))
    print(out, flush=True)
    return out


def validate_tendon(args) -> dict:
    """PyElastica's tendon against the closed form and against gvsjax's statics."""
    out: dict = dict(offset=OFFSET, dt=args.dt, cases=[])
    I = math.pi * P["radius"] ** 4 / 4.0
    A = math.pi * P["radius"] ** 2
    EI, EA = P["youngs_modulus"] * I, P["youngs_modulus"] * A
    K, ss = args.modes, args.ss_order
    rich = dict(tendon_offset=OFFSET, tip_force=0.0)

    def gv_tip(robot, tension, theta):
        n = robot.n_dofs
        res = gv.equilibrium(robot, jnp.zeros(n).at[0].set(theta), tendon_force=tension, prescribed=[theta],
                             load_scale_steps=8)
        return np.asarray(backbone(robot, res.q)[-1]), bool(res.converged)

    # (a) no gravity, base at 0, tension held: an arc of curvature T d / (E I), shortened by T / (E A)
    for T in (30.0, 300.0):
        angle, pull = episode_laws((0.0, 0.0), (T, T), 5.0, ramp_time=1.0)
        r = pyelastica_run(angle, pull, 6.0, (6.0,), args.dt, args.elements, gravity=0.0, average_last=0.5)
        pe = r["tips_mean"][0]  # the mean over the last 0.5 s: the undamped stretch oscillates
        kap, L = T * OFFSET / EI, P["length"] * (1.0 - T / EA)
        closed = np.array([(1.0 - math.cos(kap * P["length"])) / kap * L / P["length"],
                           -math.sin(kap * P["length"]) / kap * L / P["length"], 0.0])
        g2, c2 = gv_tip(gv.paper_arm(gravity=0.0, tendon_offset=OFFSET), T, 0.0)
        gss, css = gv_tip(cosserat_arm(K, ss, max(8, K + 2), gravity=0.0, **rich), T, 0.0)
        case = dict(case=f"no gravity, hanging frame, T = {T:g} N", tension=T, closed_form=closed.tolist(),
                    pyelastica=pe.tolist(), gvsjax_2_modes=g2.tolist(), gvsjax_ss=gss.tolist(),
                    converged=[c2, css], wall_s=r["wall_s"])
        case["pyelastica_vs_closed_mm"] = 1e3 * float(np.linalg.norm(pe - closed))
        case["gvsjax_ss_vs_closed_mm"] = 1e3 * float(np.linalg.norm(gss - closed))
        case["gvsjax_2_modes_vs_closed_inextensible_mm"] = 1e3 * float(np.linalg.norm(g2 - closed * P["length"] / L))
        case["tendon_deflection_mm"] = 1e3 * float(closed[0])
        out["cases"].append(case)
        print(case, flush=True)
    # (b) gravity, base horizontal (theta = pi/2, reached on the cycloid in 2 s), tension 0 and 30 N
    th = math.pi / 2
    tips = {}
    for T in (0.0, 30.0):
        angle, pull = episode_laws((th, th), (T, T), 10.0, ramp_time=2.0)
        r = pyelastica_run(angle, pull, 10.0, (10.0,), args.dt, args.elements, average_last=0.5)
        pe = r["tips_mean"][0]
        gb, cb = gv_tip(bending_arm(K, max(8, K + 2), **rich), T, th)
        gss, css = gv_tip(cosserat_arm(K, ss, max(8, K + 2), **rich), T, th)
        gfine, cfine = gv_tip(cosserat_arm(args.fine_modes, ss + 1, max(8, args.fine_modes + 2), **rich), T, th)
        tips[T] = dict(pyelastica=pe, bend=gb, ss=gss, ss_fine=gfine)
        case = dict(case=f"gravity, horizontal base, T = {T:g} N", tension=T, pyelastica=pe.tolist(),
                    gvsjax_bend=gb.tolist(), gvsjax_ss=gss.tolist(), gvsjax_ss_fine=gfine.tolist(),
                    converged=[cb, css, cfine], wall_s=r["wall_s"],
                    pyelastica_vs_gvsjax_ss_mm=1e3 * float(np.linalg.norm(pe - gss)),
                    pyelastica_vs_gvsjax_bend_mm=1e3 * float(np.linalg.norm(pe - gb)),
                    gvsjax_ss_vs_finer_mm=1e3 * float(np.linalg.norm(gss - gfine)))
        out["cases"].append(case)
        print(case, flush=True)
    eff = {k: tips[30.0][k] - tips[0.0][k] for k in tips[0.0]}
    out["tendon_effect_horizontal"] = dict(
        **{f"{k}_mm": (1e3 * v).tolist() for k, v in eff.items()},
        pyelastica_vs_gvsjax_ss_mm=1e3 * float(np.linalg.norm(eff["pyelastica"] - eff["ss"])),
        relative=float(np.linalg.norm(eff["pyelastica"] - eff["ss"]) / np.linalg.norm(eff["ss"])))
    print(out["tendon_effect_horizontal"], flush=True)
    return out
