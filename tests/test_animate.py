"""GIF animations (gvsjax.animate dispatching to a task's ``animate``; the tasks' ``throw_gif``
and ``episode_gif``): frame counts, and bad input named with exit code 2 (a few frames, small
dpi: the compile dominates)."""

from __future__ import annotations

import pytest
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


def test_pickplace_gif_from_the_cli(tmp_path):
    # 500 drawing steps per 5 s step, saved every 5th: 201 states over both steps, a frame every 5th (0.25 s)
    out = tmp_path / "pp.gif"
    assert animate.main(["task=pickplace", "action=0.5,0.6,-0.7,0.2", f"out={out}", "dpi=30"]) == 0
    assert _frames(out) == 41


@pytest.mark.parametrize("argv, word", [
    (["task=basketball", "T=5"], "T=5.0"),  # T outside [0.5, 3] s
    (["task=basketball", "delta=0.5"], "delta=0.5"),
    (["task=basketball", "frames=1"], "frames=1"),
    (["task=basketball", "target=1,2,3"], "target='1,2,3'"),
    (["task=pickplace", "action=1,2,3"], "action="),  # 3 numbers, 4 needed
    (["task=pickplace", "action=0.5,1.5,0,0"], r"actions=[[0.5, 1.5], [0.0, 0.0]] must be (2, 2) numbers in [-1, 1]"),
    (["task=walk"], "task="),
    (["speed=3"], "valid keys"),
])
def test_bad_input_is_named(argv, word, capsys, tmp_path):
    assert animate.main(argv + [f"out={tmp_path / 'never.gif'}"]) == 2
    assert word in capsys.readouterr().err
    assert not (tmp_path / "never.gif").exists()

