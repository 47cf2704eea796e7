"""A reach_obstacles policy, and the open-loop ramp, on random layouts (``layout_jitter``).

Each capsule of each held-out episode moves by its own uniform draw within +-j in each coordinate
(the planar task: in its plane); the targets are those of ``python -m gvsjax.evaluate`` (the same
``reset`` keys: the layout's draw does not change the target's). Every number comes from the task's
own ``evaluate`` (its policy row and its ramp baseline's).

    python experiments/studies/reach_obstacles_layouts.py checkpoint=runs/ro
    python experiments/studies/reach_obstacles_layouts.py checkpoint=runs/ro-rise residual_scale=1 residual_rise=1 \\
        final_weight=10 jitter=0,0.03,0.06

A run trained by ``experiments/studies/train_variant.py`` needs the same ``name=value`` replacements (they
register its ``<task>_variant``). Options: ``jitter=`` (m, comma-separated; default 0,0.02,0.04,0.06),
``n=`` episodes (1000), ``seed=`` (the evaluation's, 1000003), ``out=`` (a JSON file; default
``<checkpoint folder>/layouts.json``; each jitter's evaluation figures go to ``layouts_<j>cm/`` beside it).
~5-10 min per jitter and 1000 episodes on 2 cores.
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
from pathlib import Path

import gvsjax  # noqa: F401  (configures JAX first)
from gvsjax.ppo.checkpoint import load_policy, load_raw, make_policy, resolve

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from train_variant import parse, variant  # noqa: E402


def main(argv: list[str]) -> int:
    pairs = dict(a.split("=", 1) for a in argv)
    if "checkpoint" not in pairs:
        raise SystemExit(__doc__)
    path = resolve(pairs.pop("checkpoint"))
    jitters = [float(j) for j in pairs.pop("jitter", "0,0.02,0.04,0.06").split(",")]
    n, seed = int(pairs.pop("n", 1000)), int(pairs.pop("seed", 1_000_003))
    out = Path(pairs.pop("out", path.parent / "layouts.json"))
    task = load_raw(path)["task"]
    if pairs:  # a variant's replacements: register it under the name its checkpoint carries
        if not task.endswith("_variant"):
            raise SystemExit(f"{sorted(pairs)}: checkpoint {str(path)!r} is a {task} run, trained with its default "
                             "params; replacements apply to runs of experiments/studies/train_variant.py only")
        variant(task.removesuffix("_variant"), {k: parse(v) for k, v in pairs.items()})
    config, env, params, net = load_policy(path)
    if not hasattr(env, "reference_action"):
        raise SystemExit(f"checkpoint {str(path)!r} is a {env.name} run, not reach_obstacles'")
    policy = make_policy(config, env.action_size, net)
    rows = []
    for j in jitters:
        moved = dataclasses.replace(params, layout_jitter=(j, 0.0 if env.planar else j, j))
        result = env.evaluate(moved, policy, n, seed)
        m = result.metrics
        folder = out.parent / f"layouts_{100 * j:g}cm"  # the evaluation's figures, the moved bars drawn
        folder.mkdir(parents=True, exist_ok=True)
        env.figures(moved, result, folder)
        rows.append({"jitter_m": j, **{k: m[k] for k in ("policy", "ramped_action", "held_action")}})
        p, r = m["policy"], m["ramped_action"]
        print(f"jitter {100 * j:.0f} cm: policy success {100 * p['success']:.1f}% (penetration > 1 cm "
              f"{100 * p['penetrated']:.1f}%, median {100 * p['distance_median_m']:.1f} cm); ramp "
              f"{100 * r['success']:.1f}% ({100 * r['penetrated']:.1f}%, {100 * r['distance_median_m']:.1f} cm)",
              flush=True)
    out.write_text(json.dumps({"checkpoint": str(path), "task": env.name, "n_episodes": n, "seed": seed,
                               "rows": rows}, indent=2))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
