"""The animation command line (gvsjax.animate): dispatch to a task's ``animate`` and its keys, a
throw's GIF (a few frames, small dpi: the compile dominates), bad input named with exit code 2.
(The pick-and-place GIF is checked with its figure in test_pickplace.py: one compiled episode.)"""

from __future__ import annotations

import pytest
from helpers import no_compile
from PIL import Image

from gvsjax import animate


def _frames(path) -> int:
    with Image.open(path) as im:
        assert im.format == "GIF"
        return im.n_frames


def test_throw_gif_from_the_cli(tmp_path, capsys):
    out = tmp_path / "throw.gif"
    assert animate.main(["task=basketball", "T=2", "delta=0.9", f"out={out}", "frames=4", "dpi=30"]) == 0
    assert _frames(out) == 4
    assert "wrote" in capsys.readouterr().out


@pytest.mark.parametrize("argv, word", [
    (["task=basketball", "T=5"], "T=5.0"),  # T outside [0.5, 3] s
    (["task=basketball", "delta=0.5"], "delta=0.5"),
    (["task=basketball", "frames=1"], "frames=1"),
    (["task=basketball", "target=1,2,3"], "target='1,2,3'"),
    (["task=pickplace", "action=1,2,3"], "action="),  # 3 numbers, 4 needed
    (["task=pickplace", "action=0.5,1.5,0,0"], r"actions=[[0.5, 1.5], [0.0, 0.0]] must be (2, 2) numbers in [-1, 1]"),
    (["task=walk"], "task="),
    (["checkpoint=/no/such/run"], "/no/such/run"),
    (["speed=3"], "valid keys"),
])
def test_bad_input_is_named(argv, word, capsys, tmp_path):
    with no_compile():
        assert animate.main(argv + [f"out={tmp_path / 'never.gif'}"]) == 2
    assert word in capsys.readouterr().err
    assert not (tmp_path / "never.gif").exists()


def test_help_lists_each_tasks_keys(capsys):
    assert animate.main(["--help"]) == 0
    text = capsys.readouterr().out
    assert "task=basketball: T=2.0 delta=0.9" in text and "task=pickplace: action=0.5,0.6,-0.7,0.2" in text



@pytest.mark.extended
def test_a_checkpoints_policy_drives_a_closed_loop_gif(tmp_path, capsys):
    """``checkpoint=`` loads the policy and the task from a run (here a freshly initialised one)."""
    import dataclasses

    import jax

    from gvsjax.ppo import PPOConfig, checkpoint
    from gvsjax.ppo.train import init
    from gvsjax.tasks import make

    env = make("track3d")
    config = PPOConfig().replace(**{**env.ppo_defaults, "num_envs": 8, "num_steps": 4, "num_minibatches": 1})
    state = init(config, env, env.default_params(), jax.random.PRNGKey(0))
    path = tmp_path / "checkpoint.ckpt"
    checkpoint.save(path, state, {"task": env.name, **dataclasses.asdict(config)}, env.name, 0)
    out = tmp_path / "t3.gif"
    assert animate.main([f"checkpoint={tmp_path}", "seed=2", "dpi=30", f"out={out}"]) == 0
    assert _frames(out) == env.episode_length + 1
    assert animate.main([f"checkpoint={path}", "task=basketball", f"out={out}"]) == 2
    assert "checkpoint is for task='track3d'" in capsys.readouterr().err
