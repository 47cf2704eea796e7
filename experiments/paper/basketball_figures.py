"""Fig. 2 of the paper for gvsjax's basketball task.

    python experiments/paper/basketball_figures.py [out_dir]   (default: figures/)

Writes ``basketball_workspace.png`` (flight paths of actions spread over the
box, the target window and 2000 targets drawn by ``reset``: Fig. 2 left),
``basketball_workspace_area.png`` (the same with area-uniform targets) and
``basketball_shapes_T2.png`` (arm at release and ball paths for T = 2 s,
delta = 0.85, 0.9, 0.95, 1: Fig. 2 right). The drawings are the task's own
(``gvsjax.tasks.basketball.figures``), so every arm shape and release is the
env's ``swing``/``release``.
"""

import sys
from pathlib import Path

import jax

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax.tasks import basketball as bb
from gvsjax.tasks.basketball import figures


def main(out="figures"):
    if out in ("-h", "--help", "help"):
        print(__doc__.strip())
        return
    out = Path(out)
    for mode, name in (("action", "basketball_workspace.png"),
                       ("area", "basketball_workspace_area.png")):
        params = bb.make_params(target_sampling=mode)
        keys = jax.random.split(jax.random.PRNGKey(0), 2000)
        targets, _ = jax.vmap(bb.sample_target, in_axes=(0, None))(keys, params)
        print("wrote", figures.workspace(params, out / name, targets=targets))
    print("wrote", figures.shapes(bb.make_params(), out / "basketball_shapes_T2.png", T=2.0))


if __name__ == "__main__":
    main(*sys.argv[1:])
