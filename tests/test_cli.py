"""Command line smoke tests: a tiny training run, its outputs, errors, resume, evaluate."""

import csv
import json

import pytest

import gvsjax  # noqa: F401
from gvsjax import checkpoint, evaluate, train

TINY = ["task=basketball", "num_envs=16", "num_minibatches=2", "update_epochs=1",
        "total_episodes=64", "progress=false", "checkpoint_every=0"]


def test_help_lists_every_key(capsys):
    assert train.main(["--help"]) == 0
    text = capsys.readouterr().out
    for key in list(train.RUN_DOCS) + list(train.FIELD_DOCS):
        assert f"  {key}=" in text


@pytest.mark.parametrize("arg, words", [
    ("bogus_key=1", ["unknown key 'bogus_key'", "num_envs", "total_episodes", "resume"]),
    ("num_envs=abc", ["num_envs='abc' is invalid"]),
    ("num_envs=0", ["num_envs=0 is invalid"]),
    ("task=chess", ["task='chess' is unknown", "basketball"]),
    ("noequals", ["key=value"]),
    ("train_targets=corners", ["train_targets='corners' is invalid", "'action', 'area', 'mixed'"]),
])
def test_bad_arguments_are_clear_errors(capsys, arg, words):
    assert train.main(["task=basketball", arg]) == 2
    err = capsys.readouterr().err
    for w in words:
        assert w in err


def test_tiny_run_resume_and_evaluate(tmp_path, capsys):
    out = tmp_path / "run"
    assert train.main(TINY + [f"out={out}", "eval_targets=8"]) == 0
    printed = capsys.readouterr().out
    assert str(out) in printed
    for name in ["config.json", "metrics.csv", "checkpoint.ckpt", "timing.json", "eval.json",
                 "eval_throws.csv", "learning_curve.png", "error_histogram.png", "throw.png"]:
        assert (out / name).is_file(), name
    saved = json.loads((out / "config.json").read_text())
    assert saved["num_envs"] == 16 and saved["train_targets"] == "" and saved["sim_dtype"] == "float64"
    with open(out / "metrics.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 4 and rows[-1]["episodes"] == "64"
    result = json.loads((out / "eval.json").read_text())
    assert result["n_targets"] == 8 and 0.0 <= result["success_rate_10cm"] <= 1.0
    with open(out / "eval_throws.csv") as f:
        throws = list(csv.DictReader(f))
    assert len(throws) == 8 and list(throws[0]) == ["target_x", "target_y", "T", "delta", "miss_m"]

    # resume with a larger budget: continues at update 4 with the saved optimizer and key
    before = checkpoint.load_raw(out / "checkpoint.ckpt")
    assert before["step"] == 4
    assert train.main(TINY + [f"out={out}", "resume=true", "total_episodes=96",
                              "eval_targets=0"]) == 0
    after = checkpoint.load_raw(out / "checkpoint.ckpt")
    assert after["step"] == 6 and after["config"]["total_episodes"] == 96
    with pytest.raises(ValueError, match="train_targets='area' differs"):  # it shaped the saved run
        train.train({**train.parse_args(TINY)[0], "out": str(out), "resume": True,
                     "train_targets": "area"}, {})
    with pytest.raises(ValueError, match="sim_dtype='float32' differs from the checkpoint's 'float64'"):
        train.train({**train.parse_args(TINY)[0], "out": str(out), "resume": True, "sim_dtype": "float32"}, {})
    with open(out / "metrics.csv") as f:
        updates = [int(r["update"]) for r in csv.DictReader(f)]
    assert updates == list(range(6))

    # evaluate from the command line into another folder
    ev = tmp_path / "ev"
    assert evaluate.main(["task=basketball", f"checkpoint={out / 'checkpoint.ckpt'}",
                          "n_targets=4", "seed=7", f"out={ev}"]) == 0
    assert json.loads((ev / "eval.json").read_text())["seed"] == 7
    assert evaluate.main(["task=basketball", "checkpoint=/nonexistent.ckpt"]) == 2


def test_corrupted_checkpoint_is_a_clear_error(tmp_path):
    path = tmp_path / "c.ckpt"
    checkpoint.save(path, {"w": [1.0, 2.0]}, {"a": 1}, "basketball", 3)
    assert checkpoint.load_raw(path)["step"] == 3
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(checkpoint.CheckpointError, match="truncated"):
        checkpoint.load_raw(path)
    flipped = bytearray(data)
    flipped[-5] ^= 0xFF
    path.write_bytes(bytes(flipped))
    with pytest.raises(checkpoint.CheckpointError, match="corrupted"):
        checkpoint.load_raw(path)
    assert not list(tmp_path.glob("*.tmp"))


def test_training_targets_differ_from_evaluation_only_where_the_task_says_so():
    from gvsjax.tasks import make

    basketball = make("basketball")
    assert train.training_params(basketball).target_sampling == "mixed"  # TRAIN_TARGETS
    assert train.training_params(basketball, "area").target_sampling == "area"
    assert basketball.default_params().target_sampling == "action"  # what evaluation draws
    pickplace = make("pickplace")
    assert not hasattr(pickplace, "train_params")
    with pytest.raises(ValueError, match="train_targets='mixed' is invalid for task='pickplace'"):
        train.training_params(pickplace, "mixed")
    with pytest.raises(ValueError, match="single target distribution"):
        train.parse_args(["task=pickplace", "train_targets=mixed"])


def test_sim_dtype_reaches_the_training_params_only():
    from gvsjax.tasks import make

    for task in ("basketball", "pickplace"):
        env = make(task)
        assert train.training_params(env, "", "float32").sim_dtype == "float32"
        assert train.training_params(env).sim_dtype == "float64"
        assert env.default_params().sim_dtype == "float64"  # what evaluation simulates with
    with pytest.raises(ValueError, match="sim_dtype='float16' is invalid; expected float64, float32"):
        train.parse_args(["task=basketball", "sim_dtype=float16"])
    from gvsjax.tasks import basketball, pickplace

    for module in (basketball, pickplace):
        with pytest.raises(ValueError, match="sim_dtype='float16' is invalid; choose 'float64' or 'float32'"):
            module.make_params(sim_dtype="float16")
