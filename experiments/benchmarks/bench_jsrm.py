"""gvsjax vs JSRM (planar piecewise-constant-strain rods in JAX) on the basketball swing.

JSRM (``pip install jsrm``) builds a planar PCS rod from pre-derived symbolic
expressions (``jsrm.systems.planar_pcs.factory``: sympy -> JAX) and returns
B(q), C(q, qd), G(q), K(q), D, alpha for B qdd + C qd + G + K + D qd = alpha tau.
It has a fixed base (the base angle ``th0`` is a constant parameter) and no
time integrator of its own (its examples use diffrax).

Two ways to give it the swing (``--model``):

* ``2seg`` (default): the arm as JSRM's 2-segment PCS rod (``planar_pcs_ns-2``,
  0.5 m each), its base angle swept as the parameter th0 = pi + theta(t). Same
  arm, time law, load, stiffness and damping, but JSRM's fixed-base equations
  have no inertial terms of the rotating base (centrifugal, Euler, Coriolis),
  so its release differs from the exact swing (reported). Throughput is what
  this variant measures: the cost per step is that of the exact model.
* ``3seg``: the exact swing, a 3-segment rod (``planar_pcs_ns-3``) whose first
  segment is a short "joint" (l0 = 1 mm) with prescribed bending strain
  kappa_0(t) = theta(t) / l0, which turns the frame of the two arm segments by
  exactly theta(t) (and moves their base by a 1 mm chord), imposed the way
  gvsjax imposes its joint (infinite-gain computed torque:
  B_uu qdd_u = (J^T f - C qd - G - K - D qd)_u - B_ua qdd_a). JSRM's 3-segment
  dynamics are 1,202,138 JAX equations (the 2-segment ones 13,012; gvsjax's
  whole right-hand side 2,863), and their jit did not finish lowering to MLIR
  within an hour on this machine.

Only bending strains are active (gvsjax's arm bends only); the base hangs
along -y (th0 = pi); gravity (0, -9.81); the ball is J_tip^T (0, -5.886) with
JSRM's own tip Jacobian. Stiffness is JSRM's (E I l per segment); damping is
Kelvin-Voigt 3 eta I l per segment (gvsjax's convention) through JSRM's D.

gvsjax runs with the basketball task's integrator (``ars443``), in float64
and in float32, and, as a like-for-like row, with RK4. JSRM is stepped by
classical RK4 (its 4 stages in a ``lax.scan``, as gvsjax's are; its steps in a
``fori_loop`` with a traced count, so one compiled program serves every step
count), twice: with stacked accelerations, and with gvsjax's complex packing
of them (``gvsjax.core.integrators._pack``); the faster sets the ratio. All run
jit+vmap over a batch of 1024 throws (T ~ U[0.5, 3] s, delta ~ U[0.85, 1]),
each at the smallest step count whose worst release tip position over the
batch is within 1 mm of its own converged run (8x the steps; for float32, of
the float64 run, so rounding counts against the budget). JSRM runs in float64
only: in float32 its closed forms, which divide by powers of the bending strain
(clamped to its global_eps = 1e-6), return non-finite releases.
Reported: simulated s per wall s (median of ``--repeats`` runs), XLA compile
time, and JSRM's one-time symbolic load (sympy lambdify).

    python experiments/benchmarks/bench_jsrm.py                 # 2seg, a few minutes
    python experiments/benchmarks/bench_jsrm.py --model 3seg    # did not compile within an hour here

Writes benchmarks/jsrm.json and prints a Markdown table.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from bench_sim import load_average, timed  # this folder is on sys.path when run as a script

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation
from gvsjax.core.integrators import _pack, _unpack

THETA_F = math.radians(210.0)
BALL = 5.886
P = gv.PAPER_ARM
L0 = 1e-3  # m, the prescribed "joint" segment
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def rk4(accel, q0, qd0, t_end, n_steps):
    """Classical RK4 on (q, qd), n_steps fixed steps (n_steps may be traced: one compiled
    program serves every step count). The four stages run as a 4-long ``lax.scan`` (as in
    gvsjax's RK4) so the dynamics appear once in the program."""
    dt = t_end / n_steps
    c = jnp.array([0.0, 0.5, 0.5, 1.0])
    w = jnp.array([1.0, 2.0, 2.0, 1.0]) / 6.0

    def step(i, state):
        q, qd = state
        t = i * dt

        def stage(carry, cw):
            (kq, kqd), (sq, sqd) = carry
            ci, wi = cw
            qi, qdi = q + ci * dt * kq, qd + ci * dt * kqd
            k = (qdi, accel(t + ci * dt, qi, qdi))
            return (k, (sq + wi * k[0], sqd + wi * k[1])), None

        zero = (jnp.zeros_like(q), jnp.zeros_like(qd))
        (_, (sq, sqd)), _ = jax.lax.scan(stage, (zero, zero), (c, w))
        return q + dt * sq, qd + dt * sqd

    return jax.lax.fori_loop(0, n_steps, step, (q0, qd0))


def rk4_packed(accel, q0, qd0, t_end, n_steps):
    """``rk4`` with gvsjax's packing of the accelerations (``gvsjax.core.integrators._pack``):
    each stage's acceleration leaves the stage as complex pairs and is unpacked by the next,
    so XLA computes it in one fusion instead of one per component. Same arithmetic."""
    dt = t_end / n_steps
    c = jnp.array([0.0, 0.5, 0.5, 1.0])
    w = jnp.array([1.0, 2.0, 2.0, 1.0]) / 6.0
    w_prev = jnp.array([0.0, 1.0, 2.0, 2.0]) / 6.0
    n = q0.shape[0]
    pack = lambda a: _pack([a[i] for i in range(n)])  # noqa: E731
    unpack = lambda z: jnp.stack(_unpack(z, n))  # noqa: E731

    def step(i, state):
        q, qd = state
        t = i * dt

        def stage(carry, cw):
            (kq, kqd_packed), (sq, sqd) = carry
            ci, wi, wp = cw
            kqd = unpack(kqd_packed)
            sqd = sqd + wp * kqd
            qi, qdi = q + ci * dt * kq, qd + ci * dt * kqd
            return ((qdi, pack(accel(t + ci * dt, qi, qdi))), (sq + wi * qdi, sqd)), None

        zero = jnp.zeros_like(q)
        ((_, acc), (sq, sqd)), _ = jax.lax.scan(stage, ((zero, pack(zero)), (zero, zero)), (c, w, w_prev))
        sqd = sqd + w[3] * unpack(acc)
        return q + dt * sq, qd + dt * sqd

    return jax.lax.fori_loop(0, n_steps, step, (q0, qd0))


def make_jsrm(model: str = "2seg"):
    """JSRM's planar PCS (bending only), params, and timings of its symbolic load.

    "3seg": the 1 mm joint segment plus the two arm halves; "2seg": the two arm halves."""
    import jsrm
    from jsrm.systems import planar_pcs

    n_seg = 3 if model == "3seg" else 2
    t0 = time.perf_counter()
    path = Path(jsrm.__file__).parent / "symbolic_expressions" / f"planar_pcs_ns-{n_seg}.dill"
    B_xi, fk, dyn, aux = planar_pcs.factory(path, strain_selector=jnp.array([True, False, False] * n_seg))
    load_s = time.perf_counter() - t0
    r, E, eta = P["radius"], P["youngs_modulus"], P["damping"]
    I = math.pi * r**4 / 4.0
    halves = [0.5 * P["length"], 0.5 * P["length"]]
    l = jnp.array([L0] + halves if n_seg == 3 else halves)
    d = []
    for li in l:  # per segment (bend, shear, axial): SoRoSim's eta (3I, A, 3A) times the length
        d += [3 * eta * I * li, eta * math.pi * r**2 * li, 3 * eta * math.pi * r**2 * li]
    params = dict(th0=jnp.array(math.pi), l=l, r=jnp.full(n_seg, r), rho=jnp.full(n_seg, P["density"]),
                  g=jnp.array([0.0, -P["gravity"]]), E=jnp.full(n_seg, E), G=jnp.full(n_seg, E / 3.0),
                  D=jnp.diag(jnp.array(d)))
    return dict(fk=fk, dyn=dyn, jac=aux["jacobian_fn"], params=params, load_s=load_s, model=model)


def jsrm_release_fn_2seg(js, integrate=rk4):
    """The two arm halves, the base angle swept as JSRM's (constant-base) parameter th0 = pi + theta(t):
    the same arm, time law, load and stiffness, but without the rotating base's inertial terms
    (centrifugal, Euler, Coriolis), which JSRM's fixed-base equations do not have."""
    fk, dyn, jac, params = js["fk"], js["dyn"], js["jac"], js["params"]
    s_tip = float(jnp.sum(params["l"]))
    f_tip = jnp.array([0.0, -BALL, 0.0])

    def rel(T, delta, n_steps):
        at = lambda t: dict(params, th0=math.pi + THETA_F * (t / T) ** 2)  # noqa: E731

        def accel(t, q, qd):
            p = at(t)
            B, C, G, K, D, _ = dyn(p, q, qd)
            f = jac(p, q, s_tip).T @ f_tip - C @ qd - G - K - D @ qd
            return jnp.linalg.solve(B, f)

        t_rel = delta * T
        q, _ = integrate(accel, jnp.zeros(2), jnp.zeros(2), t_rel, n_steps)
        return fk(at(t_rel), q, s_tip)[:2]

    return rel


def jsrm_release_fn(js, integrate=rk4):
    if js["model"] == "2seg":
        return jsrm_release_fn_2seg(js, integrate)
    fk, dyn, jac, params = js["fk"], js["dyn"], js["jac"], js["params"]
    s_tip = float(jnp.sum(params["l"]))
    f_tip = jnp.array([0.0, -BALL, 0.0])

    def rel(T, delta, n_steps):
        law = lambda t: THETA_F * (t / T) ** 2 / L0  # noqa: E731
        law_dd = 2.0 * THETA_F / T**2 / L0

        def accel(t, qu, qud):
            q = jnp.concatenate([law(t)[None], qu])
            qd = jnp.concatenate([(2.0 * THETA_F * t / T**2 / L0)[None], qud])
            B, C, G, K, D, _ = dyn(params, q, qd)
            f = jac(params, q, s_tip).T @ f_tip - C @ qd - G - K - D @ qd
            return jnp.linalg.solve(B[1:, 1:], f[1:] - B[1:, 0] * law_dd)

        t_rel = delta * T
        qu, qud = integrate(accel, jnp.zeros(2), jnp.zeros(2), t_rel, n_steps)
        q = jnp.concatenate([law(t_rel)[None], qu])
        return fk(params, q, s_tip)[:2]

    return rel


def gvsjax_release_fn(n_steps, integrator="rk4", dtype=jnp.float64):
    arm = gv.paper_arm(tip_force=BALL)

    def rel(T, delta):
        T, delta = T.astype(dtype), delta.astype(dtype)
        traj = gv.simulate(arm, delta * T, n_steps=n_steps, save_every=n_steps, check_stability=False,
                           integrator=integrator, base_angle=lambda t: THETA_F * (t / T) ** 2, dtype=dtype)
        return traj.tip[-1, :2].astype(jnp.float64)

    return rel


def steps_for_1mm(batched, T, d, candidates, reference=None):
    """Smallest step count whose worst release position over (T, d) is within 1 mm of 8x steps.
    ``batched(n)`` returns the batched release function for n steps; ``reference(n)``, if given,
    the one run at 8x steps (the float64 run for a float32 row: rounding counts against the budget)."""
    for n in candidates:
        coarse = np.asarray(batched(n)(T, d))
        fine = np.asarray((reference or batched)(8 * n)(T, d))
        err = float(np.max(np.linalg.norm(coarse - fine, axis=-1)))
        if np.isfinite(coarse).all() and err <= 1e-3:
            return n, err, fine
    raise RuntimeError(f"no step count in {candidates} reaches 1 mm")


def jsrm_float32_check(T, d, reference, n_steps, repeats, eps_values=(1e-6, 1e-4, 1e-3, 1e-2, 3e-2)):
    """JSRM (2seg) in float32 at each global_eps (its clamp of the bending strain, default 1e-6):
    the share of finite releases, their distance from ``reference`` (JSRM's converged float64
    run) and the throughput. Switches JAX's x64 off for good: run it last."""
    import jsrm
    from jsrm.systems import planar_pcs

    jax.config.update("jax_enable_x64", False)
    T32, d32 = jnp.asarray(T, jnp.float32), jnp.asarray(d, jnp.float32)
    path = Path(jsrm.__file__).parent / "symbolic_expressions" / "planar_pcs_ns-2.dill"
    out = []
    for eps in eps_values:
        js = make_jsrm("2seg")
        _, fk, dyn, aux = planar_pcs.factory(path, strain_selector=jnp.array([True, False, False] * 2),
                                             global_eps=eps)
        js.update(fk=fk, dyn=dyn, jac=aux["jacobian_fn"],
                  params={k: jnp.asarray(v, jnp.float32) for k, v in js["params"].items()})
        prog = jax.jit(jax.vmap(jsrm_release_fn(js), in_axes=(0, 0, None)))
        tip = np.asarray(prog(T32, d32, n_steps), np.float64)
        err = np.linalg.norm(tip - reference, axis=-1)
        _, run_s = timed(lambda T, d, p=prog: p(T, d, n_steps), T32, d32, repeats=repeats)
        finite = np.isfinite(err)
        row = dict(global_eps=eps, n_steps=n_steps, finite_share=float(finite.mean()),
                   error_max_m=float(err[finite].max()) if finite.any() else None,
                   error_median_m=float(np.median(err[finite])) if finite.any() else None, run_s=run_s)
        print("jsrm float32", row)
        out.append(row)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--batch", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=15, help="timed runs per row (the median is reported)")
    ap.add_argument("--jsrm-float32", action=argparse.BooleanOptionalAction, default=True,
                    help="also try JSRM in float32 at several global_eps (last: switches x64 off)")
    ap.add_argument("--json", default=os.path.join(ROOT, "benchmarks", "jsrm.json"))
    ap.add_argument("--model", choices=("2seg", "3seg"), default="2seg",
                    help="2seg: base angle as a parameter (no rotating-base inertia; compiles in seconds); "
                         "3seg: the exact swing through a 1 mm joint segment (1.2M-equation dynamics: did not "
                         "finish lowering in an hour here)")
    args = ap.parse_args()
    load_start = load_average()
    print("load at start:", load_start)
    k1, k2 = jax.random.split(jax.random.PRNGKey(0))
    T = jax.random.uniform(k1, (args.batch,), minval=0.5, maxval=3.0)
    d = jax.random.uniform(k2, (args.batch,), minval=0.85, maxval=1.0)
    sim_s = float(jnp.sum(T * d))
    # the accuracy search runs on the 64 slowest-to-converge candidates: the longest throws (largest dt)
    # and the fastest (largest accelerations)
    order = np.argsort(np.asarray(T * d))
    probe = np.concatenate([order[:32], order[-32:]])
    Tp, dp = T[probe], d[probe]

    js = make_jsrm(args.model)
    print(f"JSRM symbolic load (sympy lambdify): {js['load_s']:.0f} s")
    # JSRM: one compiled program for every step count (its compile is slow); gvsjax: one per count.
    # JSRM runs with both RK4 drivers (stacked, and with gvsjax's packing); the faster sets the ratio.
    js_programs, js_compile = {}, {}
    for name, integrate in (("jsrm", rk4), ("jsrm packed", rk4_packed)):
        js_programs[name] = jax.jit(jax.vmap(jsrm_release_fn(js, integrate), in_axes=(0, 0, None)))
        t0 = time.perf_counter()
        js_programs[name].lower(T, d, 100).compile()  # timed once: the compile of the batch-1024 program
        js_compile[name] = time.perf_counter() - t0
    makers = {"gvsjax ars443": lambda n: jax.jit(jax.vmap(gvsjax_release_fn(n, "ars443"))),
              "gvsjax ars443 float32": lambda n: jax.jit(jax.vmap(gvsjax_release_fn(n, "ars443", jnp.float32))),
              "gvsjax": lambda n: jax.jit(jax.vmap(gvsjax_release_fn(n))),
              **{name: (lambda n, p=p: (lambda T, d: p(T, d, n))) for name, p in js_programs.items()}}
    rk4_steps = (50, 100, 150, 175, 200, 210, 220, 230, 240, 250, 275, 300, 400, 600, 800, 1200)
    rows = {}
    ars_steps = (16, 20, 24, 28, 32, 36, 40, 44, 48, 56, 64, 80)
    for name, cands in (("gvsjax ars443", ars_steps), ("gvsjax ars443 float32", ars_steps),
                        ("gvsjax", rk4_steps), ("jsrm", rk4_steps), ("jsrm packed", rk4_steps)):
        ref = makers["gvsjax ars443"] if name.endswith("float32") else None
        n, err, conv = steps_for_1mm(makers[name], Tp, dp, cands, ref)
        compile_s, run_s = timed(makers[name](n), T, d, repeats=args.repeats)
        if name in js_compile:
            compile_s = js_compile[name]
        rows[name] = dict(n_steps=n, release_error_m=err, compile_s=compile_s, run_s=run_s,
                          sim_s_per_wall_s=sim_s / run_s, throws_per_s=args.batch / run_s,
                          converged_tip=conv.tolist())
        print(name, rows[name]["n_steps"], f"{err * 1e3:.3f} mm", f"{run_s:.3f} s", f"compile {compile_s:.1f} s")
    best_jsrm = max(("jsrm", "jsrm packed"), key=lambda k: rows[k]["sim_s_per_wall_s"])
    diff = np.linalg.norm(np.array(rows["gvsjax"]["converged_tip"]) - np.array(rows["jsrm"]["converged_tip"]), axis=-1)
    for r in rows.values():
        del r["converged_tip"]
    res = dict(batch=args.batch, jsrm_model=args.model, simulated_s=sim_s, rows=rows,
               jsrm_symbolic_load_s=js["load_s"],
               jsrm_row_for_ratio=best_jsrm,
               ratio_sim_s_per_wall_s=rows["gvsjax ars443"]["sim_s_per_wall_s"] / rows[best_jsrm]["sim_s_per_wall_s"],
               ratio_sim_s_per_wall_s_both_rk4=rows["gvsjax"]["sim_s_per_wall_s"] / rows[best_jsrm]["sim_s_per_wall_s"],
               ratio_sim_s_per_wall_s_float32=rows["gvsjax ars443 float32"]["sim_s_per_wall_s"]
               / rows[best_jsrm]["sim_s_per_wall_s"],
               release_gvsjax_vs_jsrm_cm=dict(median=1e2 * float(np.median(diff)), max=1e2 * float(np.max(diff))),
               joint_segment_m=L0, load_start=load_start, load_end=load_average(), jax=jax.__version__)
    if args.jsrm_float32:
        js_ref = np.asarray(js_programs["jsrm"](T, d, 8 * rows["jsrm"]["n_steps"]))
        res["jsrm_float32"] = jsrm_float32_check(T, d, js_ref, rows["jsrm"]["n_steps"], args.repeats)
    os.makedirs(os.path.dirname(args.json), exist_ok=True)
    with open(args.json, "w") as fh:
        json.dump(res, fh, indent=2)
    print(f"\nbatch {args.batch}; gvsjax with the basketball task's integrator (ars443) and with RK4, JSRM with "
          f"RK4; step count for <= 1 mm release error vs 8x steps (checked on the 64 longest/shortest throws)\n")
    print("| simulator | steps/throw | error (mm) | wall s | simulated s / wall s | compile s |")
    print("|---|---|---|---|---|---|")
    for name, r in rows.items():
        print(f"| {name} | {r['n_steps']} | {r['release_error_m'] * 1e3:.3f} | {r['run_s']:.3f} | "
              f"{r['sim_s_per_wall_s']:,.0f} | {r['compile_s']:.1f} |")
    print(f"\nratio gvsjax (ars443) / JSRM ({best_jsrm}): {res['ratio_sim_s_per_wall_s']:.1f}x "
          f"(gvsjax in float32: {res['ratio_sim_s_per_wall_s_float32']:.1f}x; both RK4: "
          f"{res['ratio_sim_s_per_wall_s_both_rk4']:.1f}x); JSRM symbolic load {js['load_s']:.0f} s; "
          f"release position gvsjax (2 modes) vs JSRM (2 PCS segments): median "
          f"{res['release_gvsjax_vs_jsrm_cm']['median']:.1f} cm, max {res['release_gvsjax_vs_jsrm_cm']['max']:.1f} cm")
    print(f"load: {load_start} -> {res['load_end']}")


if __name__ == "__main__":
    main()
