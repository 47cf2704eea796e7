"""gvsjax vs SoRoMoX (JAX PCS/GVS rods, the successor of JSRM) on the same rods, side by side.

SoRoMoX (``pip install soromox``, 0.5.0, MIT) requires ``jax>=0.10`` and brings diffrax, equinox,
lineax and optimistix; its pins agree with gvsjax's (it is in the ``bench`` extra), but it runs in a
process of its own, so that gvsjax's process-wide XLA flag does not touch it: this script starts
itself with ``--peer`` under ``--peer-python`` (default /work/venv-soromox/bin/python if it exists,
else this interpreter) and the two sides exchange JSON. Neither side imports the other.

Workloads (all float64, t = 0..1 s from rest, straight, clamped at the origin along world +x,
gravity 9.81 m/s^2 along world -y; radius 5 cm, E = 5 MPa, G = E/3 (Poisson 0.5), density
1000 kg/m^3, material damping eta = 1e5 Pa s in SoRoSim's convention, D = eta diag(J, 3I, 3I, 3A,
A, A) per unit length, which is also SoRoMoX's ``material_damping_coefficient`` convention; five
Gauss points per segment on both sides):

* ``a``: the paper's planar arm, 1 m, bending only, curvature kappa_z(X) = q_1 + q_2 X (two
  monomial modes), its revolute base held at pi/2 (horizontal) and released under gravity.
  gvsjax: ``gv.paper_arm()`` with q0 = (pi/2, 0, 0) and the prescribed joint held. SoRoMoX: its
  spatial GVS (``GVS.from_segments``; it has no planar GVS) with a fixed joint, the horizontal
  mounting and a monomial basis of order 1 on kappa_z alone: the same two coordinates.
* ``b1``, ``b2``, ``b4``: a 1 m rod with all six strains, constant per segment, in 1, 2 and 4
  equal segments (6, 12, 24 DoFs): a horizontal cantilever falling under gravity. gvsjax: a chain
  of ``SoftLink``s on fixed joints, each with an order-0 basis on all six strains (what
  ``gv.rod_3d(order=0)`` builds for one segment). SoRoMoX: ``PCS.from_links`` (piecewise constant
  strain), horizontal mounting.
* ``c``: ``b1`` with four straight tendons 4 cm off the midline (local +y, +z, -y, -z), fixed at
  the tip, each with a step tension at t = 0 drawn per batch element from U[0, 150] N. gvsjax:
  ``Tendon``; SoRoMoX: ``ThreadlikeActuator.tendons`` on linear routings with zero slope.

The batch: (c) varies the tensions; in (a) and (b) every element is the same rollout from rest, but
each lane's initial state (gvsjax: the velocities, SoRoMoX: the state vector) is a vmapped input, so
every lane is computed: vmap computes a value that depends on no batched input only once.

Integration. gvsjax: ``simulate(..., integrator="ars443")`` (third-order IMEX Runge-Kutta, its
default for the basketball task). SoRoMoX: its ``rollout_to`` with diffrax's Tsit5 (its default
solver; the tip at the save times comes from diffrax's dense output) and a constant step; its
rollout integrates to t1 + dt, one step past the horizon (counted in its cost, as a user pays it).
Each library runs at the largest fixed step (of 1 s / N, N from ``CANDIDATES``) whose tip, at
t = 0.1, 0.2, ..., 1 s, stays within 1 mm of its own run at 10x the steps; the step search
compiles one program with a traced step (gvsjax: a ``fori_loop`` of one-step ``simulate`` calls,
checked against the timed ``simulate(n_steps=N)`` program). Both run with ``jit(vmap(...))``.

Reported per workload and batch (1, 256, 1024): simulated s per wall s (batch x 1 s / median wall
time of ``--repeats`` runs), compile time (first call minus the median run), the tip difference
between the two libraries' converged (10x) runs (max over the ten save times), and the ratio
gvsjax / SoRoMoX of simulated s per wall s. SoRoMoX's explicit solver needs tens of thousands of
steps per simulated second on the segmented rods, so its timed rollouts may be shorter than 1 s:
each batch is timed over a horizon h <= 1 s (at least 100 steps) for which one run would take about
``--peer-budget`` s (default 10) at the search run's cost per element times the batch, and its wall
time is scaled by 1 s / h (a constant step costs the same every step; ``timed_horizon_s`` in the
JSON). gvsjax is always timed over the full second.

Differences that remain (none changes the physics): in (a) gvsjax carries the held base angle as a
prescribed coordinate (3 DoFs listed, 2 integrated) and SoRoMoX computes the planar arm with its
spatial GVS kinematics; gvsjax saves the tip at step ends, SoRoMoX through diffrax's interpolation;
SoRoMoX's rollout takes one step past the horizon; SoRoMoX's model without actuators still takes
one (zero) input per strain. The converged tips agree to about a micrometre.

XLA flags: gvsjax sets ``--xla_cpu_use_fusion_emitters=false`` on import (its own choice); the
SoRoMoX process runs with JAX's defaults (``--peer-xla-flags`` to change that).

    python experiments/benchmarks/bench_soromox.py --quick                   # correctness pass (batch 1, 2 repeats)
    python experiments/benchmarks/bench_soromox.py                   # everything: an hour or more, idle (estimate)
    python experiments/benchmarks/bench_soromox.py --workloads a,b1 --batches 1,256 --libs soromox   # a part
    python experiments/benchmarks/bench_soromox.py --report                  # table and figure from the JSON

Results are merged into benchmarks/soromox.json (a partial run replaces only what it measured),
and a Markdown table is printed; ``--figure`` (with ``--report``) draws figures/soromox.png.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
JSON_PATH = os.path.join(ROOT, "benchmarks", "soromox.json")
# SoRoMoX's own venv if there is one, else this interpreter (``pip install -e ".[bench]"`` installs it
# beside gvsjax: the pins agree); either way it runs in a separate process
PEER_PYTHON = "/work/venv-soromox/bin/python" if os.path.exists("/work/venv-soromox/bin/python") else sys.executable

WORKLOADS = ("a", "b1", "b2", "b4", "c")
DESCRIPTION = {
    "a": "paper arm (planar, 2 bending modes), base held horizontal, falls under gravity",
    "b1": "spatial rod, 6 constant strains, 1 segment, horizontal cantilever under gravity",
    "b2": "spatial rod, 6 constant strains per segment, 2 segments",
    "b4": "spatial rod, 6 constant strains per segment, 4 segments",
    "c": "b1 with 4 straight tendons (4 cm), step tensions U[0, 150] N",
}
T_END = 1.0  # s
N_SAVE = 10  # tip sampled at t = 0.1, ..., 1 s
LENGTH, RADIUS, YOUNG, DENSITY, ETA, GRAVITY = 1.0, 0.05, 5e6, 1000.0, 1e5, 9.81
SHEAR = YOUNG / 3.0  # Poisson 0.5 (SoRoSim's default; SoRoMoX takes the shear modulus itself)
N_GAUSS = 5
TENDON_OFFSET = 0.04  # m
TENDON_DIRS = ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))  # (y, z) in the section
TENSION_MAX = 150.0  # N
# step counts per simulated second tried, fewest first (multiples of N_SAVE)
CANDIDATES = (10, 20, 30, 40, 50, 60, 80, 100, 120, 150, 200, 250, 300, 400, 500, 600, 800, 1000, 1200,
              1500, 2000, 2500, 3000, 4000, 5000, 6000, 8000, 10000, 12000, 15000, 20000, 25000, 30000, 40000,
              50000, 60000, 80000, 100000)
TOL = 1e-3  # m
PROBE_C = 4  # batch elements of workload c in the step search and the tip comparison (else 1: all alike)


def probe(workload: str) -> int:
    return PROBE_C if workload == "c" else 1


def n_segments(workload: str) -> int:
    return {"a": 1, "b1": 1, "b2": 2, "b4": 4, "c": 1}[workload]


def tensions(batch: int, seed: int = 0) -> np.ndarray:
    """(batch, 4) step tensions of workload c (the same on both sides)."""
    return np.random.default_rng(seed).uniform(0.0, TENSION_MAX, size=(batch, len(TENDON_DIRS)))


def fmt(v: float) -> str:
    """Simulated s per wall s: thousands separators, three significant digits below 10."""
    return f"{v:,.1f}" if v >= 10 else f"{v:.3g}"


def load_average() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def timed(fn, *args, repeats: int) -> tuple[float, float]:
    """(compile + first run - median run, median of ``repeats`` runs) in s."""
    import jax

    t0 = time.perf_counter()
    jax.block_until_ready(fn(*args))
    first = time.perf_counter() - t0
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        runs.append(time.perf_counter() - t0)
    med = float(np.median(runs))
    return max(first - med, 0.0), med


def search_steps(run, inputs, log) -> tuple[int, float, np.ndarray, float]:
    """Fewest steps N (of CANDIDATES) whose tips (probe, N_SAVE, 3) are finite and within TOL of
    the run at 10 N. ``run(inputs, n)`` returns the tips. Returns N, the error, the 10 N run's
    tips and the wall time of the run at N."""
    def ok(n):
        t0 = time.perf_counter()
        coarse = np.asarray(run(inputs, n))
        wall = time.perf_counter() - t0
        if not np.isfinite(coarse).all():
            log(f"  N={n}: not finite")
            return None
        fine = np.asarray(run(inputs, 10 * n))
        err = float(np.max(np.linalg.norm(coarse - fine, axis=-1)))
        log(f"  N={n}: {err * 1e3:.4f} mm vs 10N")
        return (n, err, fine, wall) if err <= TOL and np.isfinite(fine).all() else None

    # the smallest finite candidate by bisection (an explicit solver's stability limit is a sharp
    # edge), then up the list until the tip is within TOL, then refined between the last failure and it
    lo, hi = 0, len(CANDIDATES) - 1
    while lo < hi:
        mid = (lo + hi) // 2
        coarse = np.asarray(run(inputs, CANDIDATES[mid]))
        finite = np.isfinite(coarse).all()
        log(f"  N={CANDIDATES[mid]}: {'finite' if finite else 'not finite'}")
        lo, hi = (lo, mid) if finite else (mid + 1, hi)
    prev = CANDIDATES[lo - 1] if lo else 0
    for n in CANDIDATES[lo:]:
        found = ok(n)
        if found:
            for m in sorted({int(round(x / N_SAVE)) * N_SAVE for x in np.linspace(prev, n, 6)[1:-1]}):
                if prev < m < n and (better := ok(m)):
                    return better
            return found
        prev = n
    raise RuntimeError(f"no step count in {CANDIDATES} keeps the tip within {TOL} m")


def measure(name: str, workload: str, make_batched, make_search, batches, repeats, log,
            budget: float | None = None) -> dict:
    """The step search, then timing at each batch. ``make_search()`` -> run(inputs, n) for the
    search (probe inputs); ``make_batched(n, batch, horizon)`` -> (fn, args) to time.

    ``budget`` (s): time each batch b over a horizon h <= 1 s (h >= 100 steps) for which one run
    would take about ``budget`` s if the cost were the search's run at N times b / probe, and scale
    the wall time to 1 s (only where the search program is the timed one: SoRoMoX)."""
    t0 = time.perf_counter()
    run, probe_inputs = make_search()
    n, err, fine, search_run_s = search_steps(run, probe_inputs, log)
    out = dict(n_steps_per_s=n, dt_s=T_END / n, step_error_m=err, search_wall_s=time.perf_counter() - t0,
               converged_tip=fine.tolist(), compile_s={}, run_s={}, sim_s_per_wall_s={}, timed_horizon_s={})
    log(f"{name} {workload}: N = {n} steps/s (dt = {T_END / n:.3g} s), {err * 1e3:.3f} mm vs 10N")
    for b in batches:
        h = T_END
        if budget is not None:
            per_element = search_run_s / fine.shape[0]
            h = float(np.clip(budget / (per_element * b), 100 * T_END / n, T_END))
        fn, args = make_batched(n, b, h)
        compile_s, run_s = timed(fn, *args, repeats=repeats)
        scaled = run_s * T_END / h
        out["compile_s"][str(b)] = compile_s
        out["run_s"][str(b)] = scaled
        out["timed_horizon_s"][str(b)] = h
        out["sim_s_per_wall_s"][str(b)] = b * T_END / scaled
        log(f"{name} {workload} batch {b}: {scaled:.4g} s per {T_END:g} s ({fmt(b * T_END / scaled)} sim s / wall s), "
            f"compile {compile_s:.1f} s" + ("" if h == T_END else f" (timed over {h:g} s)"))
    out["load_end"] = load_average()
    return out


# ----------------------------------------------------------------------------------------------
# gvsjax (this process)


def gvsjax_robot(workload: str):
    import gvsjax as gv
    from gvsjax.core.model import Joint, Material, Robot, SoftLink, StrainBasis, Tendon

    if workload == "a":
        return gv.paper_arm(), np.array([math.pi / 2, 0.0, 0.0])
    k = n_segments(workload)
    links = tuple(SoftLink(length=LENGTH / k, radius=RADIUS, material=Material(YOUNG, DENSITY, ETA, 0.5),
                           basis=StrainBasis(orders=(0,) * 6, kind="legendre"), joint=Joint("fixed"),
                           n_gauss=N_GAUSS) for _ in range(k))
    tendons = ()
    if workload == "c":
        tendons = tuple(Tendon(offset=TENDON_OFFSET, link=0, direction=d) for d in TENDON_DIRS)
    robot = Robot(links=links, gravity=GRAVITY, tendons=tendons)
    return robot, np.zeros(robot.n_dofs)


def gvsjax_side(workloads, batches, repeats, log) -> dict:
    import jax

    import gvsjax  # noqa: F401  (sets its XLA flag before JAX starts its backend; importing jax does not)

    return {w: gvsjax_workload(w, batches, repeats, log) | dict(jax=jax.__version__, gvsjax_commit=git_commit())
            for w in workloads}


def gvsjax_workload(w, batches, repeats, log) -> dict:
    import jax
    import jax.numpy as jnp

    import gvsjax as gv

    robot, q0 = gvsjax_robot(w)
    ten_of = (lambda ten: ten) if w == "c" else (lambda ten: None)
    cache: dict = {}  # compiled programs of this workload

    def inputs_of(b):
        """(initial velocities, tensions) of b lanes: every lane's rollout depends on its own row, so
        vmap batches all of the work (a value that depends on no batched input is computed once)."""
        return jnp.zeros((b, robot.n_dofs)), jnp.asarray(tensions(b))

    def tips_one(qd0, ten, n):
        traj = gv.simulate(robot, T_END, n_steps=n, save_every=n // N_SAVE, integrator="ars443",
                           q0=jnp.asarray(q0), qd0=qd0, tendon_force=ten_of(ten), check_stability=False)
        return traj.tip[1:]

    def one_step_loop(qd0, ten, n):  # n traced: N_SAVE chunks of n / N_SAVE single steps
        dt = T_END / n

        def step(_, state):  # (q, qd, tip) after one step
            tr = gv.simulate(robot, dt, n_steps=1, q0=state[0], qd0=state[1], integrator="ars443",
                             tendon_force=ten_of(ten), check_stability=False)
            return tr.q[-1], tr.qd[-1], tr.tip[-1]

        def chunk(state, _):
            state = jax.lax.fori_loop(0, n // N_SAVE, step, state)
            return state, state[2]

        return jax.lax.scan(chunk, (jnp.asarray(q0), qd0, jnp.zeros(3)), None, length=N_SAVE)[1]

    def make_search():
        if "search" not in cache:  # one compiled program for the search and the check below
            cache["search"] = jax.jit(jax.vmap(one_step_loop, in_axes=(0, 0, None)))
        prog = cache["search"]
        return (lambda inp, n: prog(*inp, n)), inputs_of(probe(w))

    def make_batched(n, b, h):
        if (n, b) not in cache:
            cache[n, b] = jax.jit(jax.vmap(lambda qd0, ten: tips_one(qd0, ten, n)))
        return cache[n, b], inputs_of(b)

    r = measure("gvsjax", w, make_batched, make_search, batches, repeats, log)
    # the timed program (simulate with n_steps=N) against the search's one-step loop
    n_found = r["n_steps_per_s"]
    prog, probe_inputs = make_batched(n_found, probe(w), T_END)
    run_search, _ = make_search()
    gap = float(np.max(np.abs(np.asarray(prog(*probe_inputs)) - np.asarray(run_search(probe_inputs, n_found)))))
    r["timed_vs_search_program_m"] = gap
    log(f"gvsjax {w}: timed program vs search program {gap:.2e} m")
    r.update(integrator="ars443", n_dofs=int(robot.n_dofs))
    return r


def git_commit() -> str:
    out = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    return out.stdout.strip()


# ----------------------------------------------------------------------------------------------
# SoRoMoX (run with --peer in its own venv)


def soromox_robot(workload: str):
    import jax.numpy as jnp
    from soromox.actuation import ThreadlikeActuator, ThreadlikeRouting
    from soromox.systems import GVS, PCS, GVSSegment, JointSpec, LinkSpec, StrainBasisSpec

    horizontal = jnp.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])  # scalar-last quaternion, then position
    gravity = jnp.array([0.0, -GRAVITY, 0.0])
    k = n_segments(workload)
    link = LinkSpec.circular(length=LENGTH / k, radius=RADIUS, density=DENSITY,
                             reference_strain=[0.0, 0.0, 0.0, 1.0, 0.0, 0.0], young_modulus=YOUNG,
                             shear_modulus=SHEAR, material_damping_coefficient=ETA)
    if workload == "a":
        seg = GVSSegment(link=link, joint=JointSpec.fixed(), num_gauss_points=N_GAUSS,
                         basis=StrainBasisSpec(type="monomial", strain_selector=("kappa_z",), basis_order=1))
        return GVS.from_segments([seg], gravity=gravity, base_pose=horizontal)
    kwargs = {}
    if workload == "c":
        intercept = jnp.array([[0.0, TENDON_OFFSET * y, TENDON_OFFSET * z] for y, z in TENDON_DIRS])
        kwargs["actuators"] = ThreadlikeActuator.tendons(ThreadlikeRouting.linear(intercept=intercept, slope=0.0))
    from soromox.systems.pcs.structures import PCSStructure

    return PCS.from_links([link] * k, gravity=gravity, base_pose=horizontal,
                          structure=PCSStructure(num_gauss_points=N_GAUSS), **kwargs)


def soromox_side(workloads, batches, repeats, budget, log) -> dict:
    import jax

    jax.config.update("jax_enable_x64", True)
    import diffrax
    import jax.numpy as jnp
    import soromox
    from soromox.systems import SystemState

    res = {}
    for w in workloads:
        t0 = time.perf_counter()
        robot = soromox_robot(w)
        build_s = time.perf_counter() - t0
        n_q = robot.num_coordinates
        s_tip = LENGTH  # arc length of the tip
        n_u = robot.num_actuators

        def tips_one(y0, u, dt, h, robot=robot, n_q=n_q, s_tip=s_tip):
            save_ts = jnp.linspace(0.0, h, N_SAVE + 1)
            tr = robot.rollout_to(SystemState(t=0.0, y=y0), u=u, t1=h, solver_dt=dt, save_ts=save_ts,
                                  solver=diffrax.Tsit5())
            q = tr.y[1:, :n_q]
            return jax.vmap(lambda qi: robot.forward_kinematics(qi, s_tip)[:3, 3])(q)

        def inputs_of(b, n_u=n_u, w=w, robot=robot):
            """(initial states, inputs) of b lanes: rest, and the tensions (c) or zeros (without
            actuators SoRoMoX's default is one input per strain)."""
            u = jnp.asarray(tensions(b)) if w == "c" else jnp.zeros((b, n_u))
            return jnp.zeros((b, robot.state_size)), u

        def make_search(tips_one=tips_one, inputs_of=inputs_of, w=w):
            prog = jax.jit(jax.vmap(lambda y0, u, dt: tips_one(y0, u, dt, T_END), in_axes=(0, 0, None)))
            return (lambda inp, n: prog(*inp, T_END / n)), inputs_of(probe(w))

        def make_batched(n, b, h, tips_one=tips_one, inputs_of=inputs_of):
            prog = jax.jit(jax.vmap(lambda y0, u, dt: tips_one(y0, u, dt, h), in_axes=(0, 0, None)))
            return prog, (*inputs_of(b), T_END / n)

        r = measure("soromox", w, make_batched, make_search, batches, repeats, log, budget=budget)
        r.update(solver="diffrax.Tsit5, constant step (rollout_to)", model=type(robot).__name__,
                 n_dofs=int(n_q), build_s=build_s, soromox=soromox.__version__, jax=jax.__version__,
                 xla_flags=os.environ.get("XLA_FLAGS", ""), backend=str(getattr(robot, "backend", "")))
        res[w] = r
    return res


# ----------------------------------------------------------------------------------------------
# driver


def run_peer(args, log) -> dict:
    """Start this script with --peer in SoRoMoX's venv; its JSON comes back through a file."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "peer.json")
        cmd = [args.peer_python, os.path.abspath(__file__), "--peer", "--peer-out", out,
               "--workloads", ",".join(args.workloads), "--batches", ",".join(map(str, args.batches)),
               "--repeats", str(args.repeats), "--peer-budget", str(args.peer_budget)]
        env = dict(os.environ)
        env.pop("XLA_FLAGS", None)
        if args.peer_xla_flags:
            env["XLA_FLAGS"] = args.peer_xla_flags
        log("peer: " + " ".join(cmd))
        subprocess.run(cmd, check=True, env=env)
        with open(out) as fh:
            return json.load(fh)


def merge(data: dict, part: dict) -> dict:
    """``part`` (this run's workloads and conditions) merged into ``data`` (the JSON so far)."""
    data.setdefault("workloads", {})
    for w, sides in part.pop("workloads").items():
        entry = data["workloads"].setdefault(w, {})
        entry["description"] = DESCRIPTION[w]
        for lib, r in sides.items():
            old = entry.get(lib, {})
            # a run with fewer batches keeps the other batches' numbers
            for key in ("compile_s", "run_s", "sim_s_per_wall_s", "timed_horizon_s"):
                r[key] = {**old.get(key, {}), **r[key]}
            entry[lib] = r
        summarise(entry)
    data.update(part)
    return data


def summarise(entry: dict) -> None:
    g, s = entry.get("gvsjax"), entry.get("soromox")
    if not (g and s):
        return
    d = np.linalg.norm(np.array(g["converged_tip"]) - np.array(s["converged_tip"]), axis=-1)
    entry["tip_difference_m"] = dict(max=float(d.max()), final=float(np.max(d[:, -1])))
    entry["ratio_sim_s_per_wall_s"] = {b: g["sim_s_per_wall_s"][b] / s["sim_s_per_wall_s"][b]
                                       for b in g["sim_s_per_wall_s"] if b in s["sim_s_per_wall_s"]}


def report(data: dict, figure: bool) -> None:
    print(f"\nmachine: {data.get('machine')}; t = 0..{T_END:g} s, float64; gvsjax ars443, SoRoMoX Tsit5 "
          "(diffrax); each at the fewest steps within 1 mm of its own 10x run\n")
    print("| workload | library | DoFs | steps / s | batch | simulated s / wall s | compile s | "
          "gvsjax / SoRoMoX |")
    print("|---|---|---|---|---|---|---|---|")
    for w in WORKLOADS:
        entry = data.get("workloads", {}).get(w)
        if not entry:
            continue
        for lib in ("gvsjax", "soromox"):
            r = entry.get(lib)
            if not r:
                continue
            for b in sorted(r["sim_s_per_wall_s"], key=int):
                ratio = entry.get("ratio_sim_s_per_wall_s", {}).get(b) if lib == "gvsjax" else None
                print(f"| {w} | {lib} | {r['n_dofs']} | {r['n_steps_per_s']} | {b} | {fmt(r['sim_s_per_wall_s'][b])} | "
                      f"{r['compile_s'][b]:.1f} | {'' if ratio is None else f'**{ratio:,.0f}x**'} |")
    print("\n| workload | tip difference gvsjax vs SoRoMoX, max over t (mm) | at t = 1 s (mm) |")
    print("|---|---|---|")
    for w in WORKLOADS:
        d = data.get("workloads", {}).get(w, {}).get("tip_difference_m")
        if d:
            print(f"| {w} | {d['max'] * 1e3:.4f} | {d['final'] * 1e3:.4f} |")
    if figure:
        draw(data)


def draw(data: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ws = [w for w in WORKLOADS if "ratio_sim_s_per_wall_s" in data.get("workloads", {}).get(w, {})]
    batches = ("1", "256", "1024")
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    x = np.arange(len(ws))
    for i, b in enumerate(batches):
        for lib, hatch in (("gvsjax", None), ("soromox", "//")):
            vals = [data["workloads"][w][lib]["sim_s_per_wall_s"].get(b, np.nan) for w in ws]
            axes[0].bar(x + (i - 1) * 0.27 + (0.065 if lib == "soromox" else -0.065), vals, 0.13,
                        color=f"C{i}", hatch=hatch, label=f"{lib}, batch {b}")
        axes[1].bar(x + (i - 1) * 0.27, [data["workloads"][w]["ratio_sim_s_per_wall_s"].get(b, np.nan)
                                         for w in ws], 0.25, color=f"C{i}", label=f"batch {b}")
    for ax in axes:
        ax.set_yscale("log")
        ax.set_xticks(x, ws)
        ax.set_xlabel("workload")
    axes[0].set_ylabel("simulated s / wall s")
    axes[0].legend(fontsize=7, ncol=2)
    axes[1].axhline(500, color="k", ls="--", lw=0.8, label="target, batch 1024 (500x)")
    axes[1].axhline(50, color="k", ls=":", lw=0.8, label="target, batch 1 (50x)")
    axes[1].set_ylabel("gvsjax / SoRoMoX")
    axes[1].legend(fontsize=7)
    fig.suptitle(f"gvsjax (ars443) vs SoRoMoX (Tsit5), float64, each at its largest step within 1 mm of its 10x run; "
                 f"machine: {data.get('machine')}",
                 fontsize=9)
    fig.tight_layout()
    path = os.path.join(ROOT, "figures", "soromox.png")
    fig.savefig(path, dpi=120)
    print("wrote", path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workloads", default=",".join(WORKLOADS), help="comma-separated, of " + ",".join(WORKLOADS))
    ap.add_argument("--batches", default="1,256,1024")
    ap.add_argument("--repeats", type=int, default=5, help="timed runs per row (the median is reported)")
    ap.add_argument("--libs", default="soromox,gvsjax", help="which sides to run")
    ap.add_argument("--quick", action="store_true", help="batch 1 only, 2 repeats, JSON not written")
    ap.add_argument("--machine", default="shared, nice 19", help="recorded with the timings")
    ap.add_argument("--json", default=JSON_PATH)
    ap.add_argument("--peer-python", default=PEER_PYTHON, help="python of SoRoMoX's venv")
    ap.add_argument("--peer-budget", type=float, default=10.0,
                    help="SoRoMoX at batch > 1 is timed over a horizon (<= 1 s, scaled to 1 s) for which one "
                         "run would take about this many s at batch-1 cost x batch")
    ap.add_argument("--peer-xla-flags", default="", help="XLA_FLAGS for the SoRoMoX process (default: none)")
    ap.add_argument("--report", action="store_true", help="print the table from the JSON, run nothing")
    ap.add_argument("--figure", action="store_true", help="with --report: draw figures/soromox.png")
    ap.add_argument("--peer", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--peer-out", help=argparse.SUPPRESS)
    args = ap.parse_args()
    args.workloads = [w for w in args.workloads.split(",") if w]
    unknown = set(args.workloads) - set(WORKLOADS)
    if unknown:
        ap.error(f"unknown workloads {sorted(unknown)}")
    args.batches = [int(b) for b in args.batches.split(",")]
    if args.quick:
        args.batches, args.repeats = [1], 2

    def log(msg):
        print(msg, flush=True)

    if args.peer:
        res = soromox_side(args.workloads, args.batches, args.repeats, args.peer_budget, log)
        with open(args.peer_out, "w") as fh:
            json.dump(res, fh)
        return
    if args.report:
        with open(args.json) as fh:
            report(json.load(fh), args.figure)
        return
    load_start = load_average()
    log(f"load at start: {load_start}")
    libs = args.libs.split(",")
    sides = {}
    if "soromox" in libs:
        sides["soromox"] = run_peer(args, log)
    if "gvsjax" in libs:
        sides["gvsjax"] = gvsjax_side(args.workloads, args.batches, args.repeats, log)
    part = dict(workloads={w: {lib: r[w] for lib, r in sides.items()} for w in args.workloads},
                machine=args.machine, t_end_s=T_END, tolerance_m=TOL, load_start=load_start,
                load_end=load_average(), repeats=args.repeats)
    if args.quick:
        data = merge({}, part)
    else:
        data = {}
        if os.path.exists(args.json):
            with open(args.json) as fh:
                data = json.load(fh)
        data = merge(data, part)
        os.makedirs(os.path.dirname(args.json), exist_ok=True)
        with open(args.json, "w") as fh:
            json.dump(data, fh, indent=2)
        log(f"wrote {args.json}")
    report(data, figure=False)


if __name__ == "__main__":
    main()
