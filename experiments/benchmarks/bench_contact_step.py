"""Where reach_obstacles' env step spends its time: one control step at a batch, against variants.

Each variant is one control step (``arm3d.control_step``, 16 ``ars443`` substeps, as
``ReachObstacles.step``) of ``--batch`` envs under random actions, ``jit(vmap)``-ed; the time
is the median of ``--repeats`` calls after a compiling one. Variants: the task's cage (and with
the saved states' gaps the env reads), the cage moved far away, no obstacles (the samples'
kinematics and J^T w, a zero law), no contact at all (16 and 8 substeps), and the cage with
other numbers of samples. ``env`` times
``ReachObstacles.step`` itself. Episodes/s is the batch over 30 steps' time.

    python experiments/benchmarks/bench_contact_step.py --dtypes float32 float64
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time

import jax
import jax.numpy as jnp

import gvsjax as gv  # noqa: F401  (XLA flags first)
from gvsjax.tasks import arm3d, make
from gvsjax.tasks.reach_obstacles.env import SAVE_EVERY, scene

VARIANTS = ("env", "cage", "cage_gaps", "far", "none", "no_contact", "no_contact_8", "samples_2", "samples_21")


def variant_arm(params, name: str) -> arm3d.ArmParams:
    """The arm (with its obstacles) that variant ``name`` steps."""
    if name == "far":
        params = dataclasses.replace(params, start=params.start + 50.0, end=params.end + 50.0)
    arm = scene(params, 0.0)
    robot = arm.robot
    if name == "none":
        robot = dataclasses.replace(robot, contact=dataclasses.replace(robot.contact, obstacles=()))
    elif name.startswith("no_contact"):
        robot = dataclasses.replace(robot, contact=None)
    elif name.startswith("samples_"):
        robot = dataclasses.replace(robot, contact=dataclasses.replace(robot.contact, n_points=int(name[8:])))
    arm = dataclasses.replace(arm, robot=robot)
    return dataclasses.replace(arm, n_substeps=8) if name == "no_contact_8" else arm


def stepper(name: str, dtype: str):
    """A jitted batched step (q, qd, action) -> (q, qd) of variant ``name``."""
    env = make("reach_obstacles")
    params = env.with_sim_dtype(env.default_params(), dtype)
    if name == "env":
        _, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(jax.random.PRNGKey(0), 1), params)

        def one(q, qd, action):
            s = jax.tree_util.tree_map(lambda x: x[0], state)
            new = env.step(jax.random.PRNGKey(0), dataclasses.replace(s, q=q, qd=qd), action, params)[1]
            return new.q, new.qd
    else:
        arm = variant_arm(params, name)

        def one(q, qd, action):
            tr = arm3d.control_step(arm, q, qd, action, save_every=SAVE_EVERY)[0]
            if name == "cage_gaps":  # the saved states' gaps, as the env's penetration check reads them
                return tr.q[-1], tr.qd[-1] + jnp.min(tr.contact_gap)
            return tr.q[-1], tr.qd[-1]

    return jax.jit(jax.vmap(one))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--dtypes", nargs="+", default=["float32", "float64"])
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=VARIANTS)
    args = ap.parse_args()
    n = 9
    key = jax.random.PRNGKey(1)
    action = jax.random.uniform(key, (args.batch, 4), minval=-1.0, maxval=1.0)
    q = 0.1 * jax.random.normal(jax.random.PRNGKey(2), (args.batch, n))
    qd = jnp.zeros((args.batch, n))
    print(f"batch {args.batch}, median of {args.repeats}; episodes/s = batch / (30 x step)")
    print(f"{'variant':<14}{'dtype':<9}{'ms/step':>9}{'ep/s':>8}{'us/arm-substep':>16}{'compile s':>11}"
          f"{'HLO kchars':>12}")
    for dtype in args.dtypes:
        for name in args.variants:
            f = stepper(name, dtype)
            hlo = len(f.lower(q, qd, action).as_text()) / 1e3
            t0 = time.perf_counter()
            jax.block_until_ready(f(q, qd, action))
            compile_s = time.perf_counter() - t0
            times = []
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                jax.block_until_ready(f(q, qd, action))
                times.append(time.perf_counter() - t0)
            s = statistics.median(times)
            substeps = 8 if name == "no_contact_8" else 16
            print(f"{name:<14}{dtype:<9}{1e3 * s:>9.1f}{args.batch / (30 * s):>8.1f}"
                  f"{1e6 * s / (args.batch * substeps):>16.1f}{compile_s:>11.1f}{hlo:>12.0f}", flush=True)


if __name__ == "__main__":
    main()
