"""gvsjax.animate writes GIFs (a few frames, small dpi: the compile dominates) and rejects bad input."""

from __future__ import annotations

import numpy as np
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


def test_pickplace_gif(tmp_path):
    # save_every=250 of 500 steps: 3 states per step, 5 frames for the two steps
    path = animate.pickplace_gif(tmp_path / "pp.gif", np.array([[0.5, 0.6], [-0.7, 0.2]]),
                                 save_every=250, dpi=30)
    assert _frames(path) == 5


@pytest.mark.parametrize("argv, word", [
    (["task=basketball", "T=5"], "T=5.0"),  # T outside [0.5, 3] s
    (["task=basketball", "delta=0.5"], "delta=0.5"),
    (["task=pickplace", "action=1,2,3"], "action="),  # 3 numbers, 4 needed
    (["task=walk"], "task="),
    (["speed=3"], "valid keys"),
])
def test_bad_input_is_named(argv, word, capsys):
    assert animate.main(argv) == 2
    assert word in capsys.readouterr().err


def test_pickplace_action_range():
    with pytest.raises(ValueError, match=r"actions=.*\[-1, 1\]"):
        animate.pickplace_gif("never.gif", np.array([[0.5, 1.5], [0.0, 0.0]]))
