"""Sim-to-sim transfer of the trained pick-and-place policy: gvsjax -> PyElastica.

The policy (trained on the task's model: ``paper_arm(tendon_offset=0.025)``, 2 monomial bending
modes, 5 Gauss points, 60 ``ars443`` steps per 5 s step) chooses both steps' actions for held-out
target pairs (the first ``--n-pairs`` of ``python -m gvsjax.evaluate``'s 1000: ``eval_targets`` of
seed 1_000_003), in its own closed loop on the task's model (``rollout``, the mean actions). The
same four numbers (theta_F, tension per step) are then replayed open-loop by other models of the
arm; the metric is the task's: the tip-to-target distance at the end of each step.

* ``gvsjax 2 modes``: the task's model, the training model;
* ``gvsjax 2 modes, 8 Gauss``: the same basis with finer quadrature;
* ``gvsjax K Legendre``: K Legendre bending modes (basis truncation; K = ``--modes``, checked
  against ``--fine-modes``);
* ``gvsjax K Legendre + stretch/shear``: in-plane stretch and shear active too (Legendre order
  ``--ss-order``), damped with eta (3A, A) (SoRoSim's convention), and a variant with them undamped
  as in PyElastica;
* ``PyElastica``: a shearable, extensible ``CosseratRod`` (``--elements``), position Verlet at
  ``--dt``, the base held and its frame turned by the task's cycloidal angle law
  (``bench_pyelastica.SwingingBase``), gravity, Kelvin-Voigt bending/torsion damping with gvsjax's
  law (``bench_pyelastica``'s ``KelvinVoigtDamper``), and the tendon (``TendonForce`` below).

The gvsjax models run through the task's ``motion.episode_distances`` (``episode``, ``run_step``)
with ``params.arm`` replaced (the transfer helpers of ``transfer_pyelastica.py`` build them), each
checked against itself at 4x the steps.

**The tendon in PyElastica.** A cable at ``offset`` from the midline in the bending plane (on the
side of gvsjax's local +y, i.e. -d2 of PyElastica's frame), anchored at the tip and sliding without
friction through a guide at every node. Its point at node i is p_i = x_i + offset e_i (e_i: -d2 of
the adjacent elements, averaged); with u_i the unit vector from p_i to p_{i+1}, it pulls node i by
T (u_i - u_{i-1}) and the tip by -T u_last, applied at p_i: the force on the node and the couple
(p_i - x_i) x F (split between the adjacent elements, in their material frames). Node 0 and
element 0 are held by the base. ``--validate`` checks it against the closed form (a straight rod
without gravity under a constant tension bends into an arc of curvature T offset / (E I), shortened
by T / (E A)) and against gvsjax's statics (``gv.equilibrium``) of the horizontal arm under gravity.

PyElastica episodes (both steps, 10 s of simulated time each) are cached one by one in ``--cache``
(a rerun resumes); a subset is rerun at ``--dt``/2 (``--check-dt``) and with ``--check-elements``
elements (at dt/2). ``--pause-file F``: while F exists, wait (polling every 20 s) before each model and episode.

    pip install pyelastica          # or pip install -e ".[bench]"
    python -m gvsjax.train task=pickplace out=runs/pp-default
    python experiments/transfer_pickplace_pyelastica.py --checkpoint runs/pp-default --validate
    python experiments/transfer_pickplace_pyelastica.py --replot

(The committed JSON: one run computed the tendon validation and the gvsjax models; the PyElastica
episodes, their checks and ``validate_elements`` ran in two processes side by side through this
script's functions, their caches merged; a last run read everything from the cache.)

Writes benchmarks/transfer_pickplace_pyelastica.json (summary and per-pair distances and tips),
benchmarks/transfer_pickplace_pyelastica_episodes.json (the cache) and
figures/transfer_pickplace_pyelastica.png.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import time

import jax
import jax.numpy as jnp
import numpy as np
from bench_pyelastica import P, _elastica, is_stable, swinging_rod  # experiments/ is on sys.path
from transfer_pyelastica import bending_arm, cosserat_arm, names, variants

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation
from gvsjax.kinematics import backbone
from gvsjax.ppo import load_policy
from gvsjax.ppo.checkpoint import make_policy, resolve
from gvsjax.tasks import pickplace as pp

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
EVAL_N, EVAL_SEED = 1000, 1_000_003  # python -m gvsjax.evaluate's pairs
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


# ----------------------------------------------------------------------------- gvsjax

def replay_fn(params):
    """``(actions (n, 2, 2), targets (n, 2, 2)) -> (tips (n, 2, 2), distances (n, 2))``: the actions
    replayed through the task's ``motion.episode_distances`` (both steps from rest, ``motion.run_step``)."""

    @jax.jit
    def run(actions, targets):
        d, tips = jax.vmap(lambda a, t: pp.episode_distances(params, a, t))(actions, targets)
        return tips, d

    return run


def summary(d: np.ndarray) -> list[dict]:
    return [pp.error_summary(d[:, k]) for k in range(2)]


# ----------------------------------------------------------------------------- the experiment

def save_json(res: dict, path: str) -> None:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(res, fh)
    os.replace(tmp, path)


def run(args) -> dict:
    wait_for(args.pause_file)
    config, env, params, net = load_policy(resolve(args.checkpoint))
    policy = make_policy(config, env.action_size, net)
    targets_all = pp.eval_targets(params, EVAL_N, EVAL_SEED)
    acts, tips_eval, d_eval, _ = (np.asarray(x) for x in jax.jit(lambda t: pp.rollout(params, policy, t))(
        jnp.asarray(targets_all)))
    n = args.n_pairs
    actions, targets = acts[:n], targets_all[:n]
    theta, tension = (np.asarray(x) for x in pp.action_to_physical(jnp.asarray(actions), params))
    idx = np.arange(n)
    out: dict = dict(checkpoint=str(resolve(args.checkpoint)), n_pairs=n, eval_seed=EVAL_SEED,
                     targets=targets.tolist(), actions=actions.tolist(), theta=theta.tolist(),
                     tension=tension.tolist(), eval_all=dict(step1=pp.error_summary(d_eval[:, 0]),
                                                             step2=pp.error_summary(d_eval[:, 1])),
                     laws_vs_task=check_laws(params, theta[0], tension[0]), models={})
    print(f"PyElastica's laws vs the task's controls: {out['laws_vs_task']:.2e}", flush=True)
    previous = {}
    if os.path.exists(args.json):
        with open(args.json) as fh:
            prev = json.load(fh)
        if prev.get("actions") == out["actions"]:
            previous = prev["models"]
            out["tendon_validation"] = prev.get("tendon_validation")
    if args.validate and not out.get("tendon_validation"):
        wait_for(args.pause_file)
        out["tendon_validation"] = validate_tendon(args)
        save_json(out, args.json)
    # --- gvsjax
    arm = dict(tendon_offset=OFFSET, tip_force=0.0)
    for name, robot in variants(args.modes, args.fine_modes, args.ss_order, args.elements, **arm).items():
        if name in previous and (previous[name].get("vs_4x_steps_tip_mm") or args.no_step_check):
            out["models"][name] = previous[name]
            print(f"{name}: from {args.json}", flush=True)
            continue
        wait_for(args.pause_file)
        p = params if robot is None else dataclasses.replace(params, arm=robot)
        t0 = time.perf_counter()
        tips, d = (np.asarray(x) for x in replay_fn(p)(jnp.asarray(actions), jnp.asarray(targets)))
        wall = time.perf_counter() - t0
        d = np.where(np.isfinite(d), d, np.inf)
        step_err = None
        if not args.no_step_check:
            fine = dataclasses.replace(p, n_steps=4 * p.n_steps)
            tips_f, _ = (np.asarray(x) for x in replay_fn(fine)(jnp.asarray(actions), jnp.asarray(targets)))
            step_err = [1e3 * float(np.max(np.linalg.norm(tips[:, k] - tips_f[:, k], axis=1))) for k in range(2)]
        link = p.arm.links[0]
        out["models"][name] = dict(tips=tips.tolist(), distance=d.tolist(), wall_s=wall, n_steps=p.n_steps,
                                   strain_dofs=link.basis.n_dofs, orders=list(link.basis.orders),
                                   n_gauss=link.n_gauss, vs_4x_steps_tip_mm=step_err, metrics=summary(d))
        if robot is None:
            out["task_vs_evaluate_m"] = float(np.max(np.abs(d - d_eval[:n])))
            print(f"  the task's replay vs its closed-loop evaluation: {out['task_vs_evaluate_m']:.1e} m")
        m = summary(d)
        print(f"{name}: median {100 * m[0]['median_m']:.2f} / {100 * m[1]['median_m']:.2f} cm; "
              f"4x steps: {step_err}", flush=True)
        save_json(out, args.json)  # a rerun reuses the models done
    # --- PyElastica
    eps = pyelastica_episodes(theta, tension, idx, args.dt, args.elements, args.cache, args.pause_file)
    tips, stable = pyelastica_tips(eps, idx)
    d = np.where(stable[:, None], np.linalg.norm(tips - targets, axis=2), np.inf)
    name = names(args.modes, args.fine_modes, args.elements)["pyelastica"]
    out["models"][name] = dict(tips=tips.tolist(), distance=d.tolist(), dt=args.dt,
                               wall_s=float(sum(eps[i]["wall_s"] for i in idx)),
                               max_stretch=float(max(eps[i]["stretch"] for i in idx)),
                               max_base_angle_error=float(max(eps[i]["base_angle_error"] for i in idx)),
                               metrics=summary(d))
    m = summary(d)
    print(f"{name}: median {100 * m[0]['median_m']:.2f} / {100 * m[1]['median_m']:.2f} cm", flush=True)
    if args.check_dt:
        change = np.abs(theta[:, 0]) + np.abs(theta[:, 1] - theta[:, 0])  # the fastest motions first
        order = np.argsort(-change)
        chk = np.unique(np.concatenate([order[: args.check_dt // 2], idx[:: max(1, n // (args.check_dt // 2))]]))
        half = pyelastica_episodes(theta, tension, chk, args.dt / 2, args.elements, args.cache, args.pause_file)
        t_half, _ = pyelastica_tips(half, chk)
        dd = np.linalg.norm(t_half - tips[chk], axis=2)
        out["models"][name]["vs_half_dt"] = dict(n_pairs=int(len(chk)), pairs=chk.tolist(), tips=t_half.tolist(),
                                                  tip_mm_max=[1e3 * float(np.max(dd[:, k])) for k in range(2)])
        print(f"  vs dt/2 on {len(chk)} pairs: {out['models'][name]['vs_half_dt']['tip_mm_max']} mm", flush=True)
        if args.check_elements:
            fine = pyelastica_episodes(theta, tension, chk, args.dt / 2, args.check_elements, args.cache,
                                       args.pause_file)
            t_fine, _ = pyelastica_tips(fine, chk)
            de = np.linalg.norm(t_fine - t_half, axis=2)
            out["models"][name]["vs_elements"] = dict(
                n_elements=args.check_elements, n_pairs=int(len(chk)), pairs=chk.tolist(), tips=t_fine.tolist(),
                tip_mm_median=[1e3 * float(np.median(de[:, k])) for k in range(2)],
                tip_mm_max=[1e3 * float(np.max(de[:, k])) for k in range(2)])
            n1, n2 = args.elements, args.check_elements
            out["models"][name]["vs_elements"]["extrapolated_tips"] = ((n2 * t_fine - n1 * t_half) / (n2 - n1)).tolist()
            print(f"  {args.check_elements} vs {args.elements} elements (dt/2): "
                  f"{out['models'][name]['vs_elements']['tip_mm_median']} mm (median)", flush=True)
    out["roles"] = names(args.modes, args.fine_modes, args.elements)
    out["decomposition"] = decomposition(out)
    if args.validate and args.check_elements and "elements" not in out["tendon_validation"]:
        save_json(out, args.json)
        wait_for(args.pause_file)
        out["tendon_validation"]["elements"] = validate_elements(args)
    return out


def _radial_tangential(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Components of a - b (n, 2) along b's radius (outwards) and along the circle (counter-clockwise)."""
    u = b / np.linalg.norm(b, axis=-1, keepdims=True)
    dv = a - b
    return np.sum(dv * u, -1), dv[..., 1] * u[..., 0] - dv[..., 0] * u[..., 1]


def decomposition(out: dict) -> list[dict]:
    """End-of-step tip differences between pairs of models (median / max over the pairs), per step."""
    r = out["roles"]
    pairs = [("quadrature", "task", "gauss8"), ("basis truncation", "task", "bend"),
             ("basis convergence", "bend", "bend_fine"), ("stretch/shear", "bend", "ss"),
             ("stretch/shear damping", "ss", "ss_undamped"), ("the rest", "ss", "pyelastica"),
             ("the rest (undamped stretch/shear)", "ss_undamped", "pyelastica"),
             ("bending only vs PyElastica", "bend", "pyelastica"), ("total", "task", "pyelastica")]
    rows = []
    for what, a, b in pairs:
        if r[a] not in out["models"] or r[b] not in out["models"]:
            continue
        A, B = out["models"][r[a]], out["models"][r[b]]
        for k in range(2):
            ta, tb = np.array(A["tips"])[:, k], np.array(B["tips"])[:, k]
            dp = np.linalg.norm(tb - ta, axis=1)
            rad, tan = _radial_tangential(tb, ta)
            dd = np.array(B["distance"])[:, k] - np.array(A["distance"])[:, k]
            rows.append(dict(what=what, a=r[a], b=r[b], step=k + 1, tip_mm_median=1e3 * float(np.median(dp)),
                             tip_mm_max=1e3 * float(np.max(dp)), radial_mm_median=1e3 * float(np.median(rad)),
                             radial_abs_mm_median=1e3 * float(np.median(np.abs(rad))),
                             tangential_abs_mm_median=1e3 * float(np.median(np.abs(tan))),
                             distance_change_cm_median=1e2 * float(np.median(dd))))
    return rows


# ----------------------------------------------------------------------------- output

def plot(res: dict, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models, r = res["models"], res["roles"]
    targets = np.array(res["targets"])
    fig, axes = plt.subplots(2, 2, figsize=(13, 9.5))
    shown = [("task", "-", "C0"), ("gauss8", ":", "C4"), ("bend", "--", "C2"), ("ss", "-.", "C1"),
             ("ss_undamped", ":", "C3"), ("pyelastica", "-", "k")]
    for k in range(2):
        ax = axes[0, k]
        for role, ls, c in shown:
            if r[role] not in models:
                continue
            d = np.sort(np.array(models[r[role]]["distance"])[:, k])
            med = 100 * np.median(d)
            ax.plot(100 * d, np.arange(1, len(d) + 1) / len(d) * 100, ls, color=c, lw=1.6,
                    label=f"{r[role]}: median {med:.2f} cm")
        ax.set_xscale("log")
        ax.set_xlabel(f"step {k + 1}: tip-to-target distance (cm)")
        ax.set_ylabel(f"pairs with a smaller distance (%, of {res['n_pairs']})")
        ax.set_title(f"({'ab'[k]}) step {k + 1} ({'pick' if k == 0 else 'place'}): CDF of the distance", fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="upper left")
        bx = axes[1, k]
        pe = np.array(models[r["pyelastica"]]["tips"])[:, k]
        ang = np.degrees(np.arctan2(targets[:, k, 0], -targets[:, k, 1]))
        K = r["bend"].split()[1]
        short = {"task": "gvsjax 2 modes (task)", "bend": f"gvsjax {K} Legendre",
                 "ss": f"gvsjax {K} Leg. + stretch/shear", "ss_undamped": "the same, undamped"}
        for role, mk, c in (("task", "o", "C0"), ("bend", "s", "C2"), ("ss", "^", "C1"), ("ss_undamped", "v", "C3")):
            if r[role] not in models:
                continue
            tips = np.array(models[r[role]]["tips"])[:, k]
            bx.plot(ang, 1e3 * np.linalg.norm(tips - pe, axis=1), mk, ms=3.5, color=c, mfc="none",
                    label=short[role])
        chk = models[r["pyelastica"]].get("vs_elements")
        if chk:
            j = np.array(chk["pairs"])
            n1 = r["pyelastica"].split()[1]
            bx.plot(ang[j], 1e3 * np.linalg.norm(np.array(chk["tips"])[:, k] - pe[j], axis=1), "kx", ms=7, mew=1.5,
                    label=f"PyElastica {chk['n_elements']} (dt/2) vs {n1} el.")
            if r["ss"] in models and "extrapolated_tips" in chk:
                ss = np.array(models[r["ss"]]["tips"])[j, k]
                bx.plot(ang[j], 1e3 * np.linalg.norm(ss - np.array(chk["extrapolated_tips"])[:, k], axis=1), "P",
                        ms=7, color="C1", label=f"{short['ss']} vs PyElastica extrap.")
        bx.set_yscale("log")
        bx.set_xlabel(f"step {k + 1} target's angle from hanging (deg)")
        bx.set_ylabel("end-of-step tip difference (mm)")
        bx.set_title(f"({'cd'[k]}) step {k + 1}: tip differences per pair, from PyElastica "
                     f"{r['pyelastica'].split()[1]} elements unless marked", fontsize=10)
        bx.grid(alpha=0.3, which="both")
        bx.legend(fontsize=7, loc="upper center", ncol=2)
        lo, hi = bx.get_ylim()
        bx.set_ylim(lo, hi * 60)  # room for the legend above the points
    fig.tight_layout()
    os.makedirs(os.path.dirname(out), exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def print_tables(res: dict) -> None:
    models, r = res["models"], res["roles"]
    pe = np.array(models[r["pyelastica"]]["tips"])
    print(f"\n{res['n_pairs']} held-out pairs (seed {res['eval_seed']}), the policy's actions replayed in each model\n")
    print("| model | strain DoFs | step | median | p95 | max | < 2 cm | tip vs PyElastica: median / max (mm) "
          "| own time error (mm) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, m in models.items():
        for k in range(2):
            s = m["metrics"][k]
            dp = np.linalg.norm(np.array(m["tips"])[:, k] - pe[:, k], axis=1)
            err = m.get("vs_4x_steps_tip_mm")
            e = f"{err[k]:.3f} (4x steps)" if err else ""
            if "vs_half_dt" in m:
                e = f"{m['vs_half_dt']['tip_mm_max'][k]:.3f} (dt/2, {m['vs_half_dt']['n_pairs']} pairs)"
            print(f"| {name} | {m.get('strain_dofs', '')} | {k + 1} | {100 * s['median_m']:.2f} cm | "
                  f"{100 * s['p95_m']:.2f} cm | {100 * s['max_m']:.2f} cm | {100 * s['within_2cm']:.0f}% | "
                  f"{1e3 * np.median(dp):.2f} / {1e3 * np.max(dp):.2f} | {e} |")
    print("\n| what | from | to | step | tip: median / max (mm) | radial: median, median abs (mm) "
          "| along the circle: median abs (mm) | distance change, median (cm) |")
    print("|---|---|---|---|---|---|---|---|")
    for x in res["decomposition"]:
        print(f"| {x['what']} | {x['a']} | {x['b']} | {x['step']} | {x['tip_mm_median']:.2f} / {x['tip_mm_max']:.2f} "
              f"| {x['radial_mm_median']:+.2f}, {x['radial_abs_mm_median']:.2f} | "
              f"{x['tangential_abs_mm_median']:.2f} | {x['distance_change_cm_median']:+.2f} |")
    pm = models[r["pyelastica"]]
    if "vs_elements" in pm:
        v = pm["vs_elements"]
        chk = np.array(v["pairs"])
        fine, extra = np.array(v["tips"]), np.array(v["extrapolated_tips"])
        print(f"\nAgainst PyElastica with {v['n_elements']} elements (dt/2) and extrapolated in the element count "
              f"((n2 P_n2 - n1 P_n1) / (n2 - n1)), on {v['n_pairs']} pairs (end-of-step tip, median / max, mm)\n")
        print(f"| model | step 1 vs {v['n_elements']} | step 2 vs {v['n_elements']} | step 1 vs extrapolated "
              "| step 2 vs extrapolated |")
        print("|---|---|---|---|---|")
        for name, m in models.items():
            cells = []
            for ref in (fine, extra):
                dp = np.linalg.norm(np.array(m["tips"])[chk] - ref, axis=2)
                cells += [f"{1e3 * np.median(dp[:, k]):.2f} / {1e3 * np.max(dp[:, k]):.2f}" for k in range(2)]
            print(f"| {name} | {' | '.join(cells[:2] + cells[2:])} |")
        print(f"\nPyElastica max element stretch {pm['max_stretch']:.2e}, base angle error "
              f"{pm['max_base_angle_error']:.1e} rad")
    tv = res.get("tendon_validation")
    if tv:
        print("\nTendon validation (tip, mm)\n")
        for c in tv["cases"]:
            print({k: (np.round(np.array(v) * 1e3, 3).tolist() if isinstance(v, list) and k != "converged" else v)
                   for k, v in c.items()})
        print(tv["tendon_effect_horizontal"])
        if "elements" in tv:
            print(tv["elements"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--checkpoint", default="runs/pp-default", help="run folder or checkpoint file")
    ap.add_argument("--n-pairs", type=int, default=100, help=f"the first n of the {EVAL_N} evaluation pairs")
    ap.add_argument("--modes", type=int, default=6, help="Legendre bending modes of the converged basis")
    ap.add_argument("--fine-modes", type=int, default=8, help="Legendre bending modes of the check of the basis")
    ap.add_argument("--ss-order", type=int, default=2, help="Legendre order of stretch and shear")
    ap.add_argument("--dt", type=float, default=1e-4, help="PyElastica step (s)")
    ap.add_argument("--elements", type=int, default=100)
    ap.add_argument("--check-dt", type=int, default=6, help="pairs rerun at dt/2 (about; 0: none)")
    ap.add_argument("--check-elements", type=int, default=200, help="elements of the discretisation check (0: none)")
    ap.add_argument("--no-step-check", action="store_true", help="skip the gvsjax models' 4x-steps check")
    ap.add_argument("--validate", action="store_true", help="validate PyElastica's tendon first (statics)")
    ap.add_argument("--pause-file", default=None, help="wait before each model and episode while this file exists")
    ap.add_argument("--cache", default=os.path.join(ROOT, "benchmarks", "transfer_pickplace_pyelastica_episodes.json"))
    ap.add_argument("--json", default=os.path.join(ROOT, "benchmarks", "transfer_pickplace_pyelastica.json"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "figures", "transfer_pickplace_pyelastica.png"))
    ap.add_argument("--replot", action="store_true", help="only redraw the figure and tables from --json")
    args = ap.parse_args()
    if args.replot:
        with open(args.json) as fh:
            res = json.load(fh)
    else:
        if not 0 < args.n_pairs <= EVAL_N:
            ap.error(f"--n-pairs must be in 1..{EVAL_N}")
        res = run(args)
        save_json(res, args.json)
    plot(res, args.figure)
    print_tables(res)


if __name__ == "__main__":
    main()
