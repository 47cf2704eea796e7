"""The training command line (gvsjax.train): its ``key=value`` arguments and their errors, a
tiny run's outputs and figures, resume, the training params a task gives, divergence (NaN
losses, non-finite weights: exit 3, the last good state kept), and runs killed, resumed and
repeated (bit-identical). Bad arguments fail before anything compiles."""

import gvsjax  # noqa: F401, I001  (first: it configures JAX)
import csv
import fcntl
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from bandit_env import BanditEnv
from helpers import capture_figures, finite_line, no_compile, raises_naming
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gvsjax import train
from gvsjax.ppo import FIELD_DOCS, PPOConfig, build_config, config_from_json, init
from gvsjax.ppo import checkpoint
from gvsjax.tasks import base, make

FAST = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])

TINY = ["task=basketball", "num_envs=16", "num_minibatches=2", "update_epochs=1",
        "total_episodes=64", "progress=false", "checkpoint_every=0"]


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


# ----------------------------------------------------------------------------- arguments


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
    with no_compile():
        assert train.main(["task=basketball", arg]) == 2
    err = capsys.readouterr().err
    for w in words:
        assert w in err


INT_FIELDS = [k for k in FIELD_DOCS if isinstance(getattr(PPOConfig(), k), int)
              and not isinstance(getattr(PPOConfig(), k), bool)]
FLOAT_FIELDS = [k for k in FIELD_DOCS if isinstance(getattr(PPOConfig(), k), float)]
BOOL_FIELDS = [k for k in FIELD_DOCS if isinstance(getattr(PPOConfig(), k), bool)]
CHOICE_FIELDS = {"network": ("shared", "separate"), "activation": ("relu", "tanh"),
                 "std_mode": ("learned", "network")}
junk = st.text(alphabet="xyz!@#% ", min_size=1, max_size=6)


def _bad_ppo(name):
    if name == "seed":  # jax.random.PRNGKey overflows at 2**63
        return st.one_of(junk, st.sampled_from(["1.5", "nan", "-1", "1e30", str(2**63), str(2**64)]))
    if name in INT_FIELDS:
        return st.one_of(junk, st.sampled_from(["1.5", "nan", "inf", "-1", "1e400"]))
    if name in FLOAT_FIELDS:  # every float field rejects NaN and -inf
        return st.one_of(junk, st.sampled_from(["nan", "-inf", "--1", "1,2"]))
    if name in BOOL_FIELDS:
        return st.one_of(junk, st.sampled_from(["2", "maybe", ""]))
    if name in CHOICE_FIELDS:
        return st.text(max_size=8).filter(lambda s: s.strip() not in CHOICE_FIELDS[name])
    return st.one_of(junk, st.sampled_from(["", "0", "-4,8", "8,0", "1.5,2", "()"]))


RUN_BAD = {
    "checkpoint_every": st.sampled_from(["nan", "-1", "x", ""]),
    "eval_targets": st.sampled_from(["-1", "1.5", "x"]),
    "eval_seed": st.sampled_from(["-2", "1.5", "x"]),
    "updates_per_call": st.sampled_from(["-3", "x"]),
    "resume": st.sampled_from(["maybe", "2", ""]),
    "progress": st.sampled_from(["maybe", "2", ""]),
    "sim_dtype": st.sampled_from(["float16", "x", "int32"]),
    "coordinator": st.sampled_from(["localhost", "host:0", "host:99999", ":80"]),
    "num_processes": st.sampled_from(["0", "-1", "1.5", "x"]),
    "process_id": st.sampled_from(["-1", "1", "1.5", "x"]),
    "task": junk,
    "preset": junk,
}


@FAST
@given(data=st.data(), name=st.sampled_from(sorted(FIELD_DOCS)))
def test_invalid_ppo_value_names_the_key(data, name):
    text = data.draw(_bad_ppo(name), label=name)

    def parse_and_build():
        run, overrides = train.parse_args(["task=basketball", f"{name}={text}"])
        build_config(train.task_defaults(run["task"]), run["preset"], overrides)

    raises_naming(name, parse_and_build)


@FAST
@given(data=st.data(), name=st.sampled_from(sorted(RUN_BAD)))
def test_invalid_run_option_names_the_key(data, name):
    text = data.draw(RUN_BAD[name], label=name)
    raises_naming(name, train.parse_args, [f"{name}={text}"])


@FAST
@given(word=st.text(max_size=12))
def test_word_without_equals_or_unknown_key(word):
    key = word.partition("=")[0].strip()
    if "=" in word and (key in train.RUN_DOCS or key in FIELD_DOCS):
        return  # a known key: covered above
    message = raises_naming("", train.parse_args, [word])
    assert "key=value" in message or "unknown key" in message


def test_resume_needs_out_and_main_exits_2(capsys):
    raises_naming("out", train.parse_args, ["resume=true"])
    assert train.main(["resume=true"]) == 2
    assert "out=" in capsys.readouterr().err


def test_task_defaults_are_the_tasks_ppo_defaults():
    for task in ("basketball", "pickplace"):
        defaults = train.task_defaults(task)
        assert defaults == dict(make(task).ppo_defaults) and defaults
        config = build_config(defaults, "none", {})
        assert all(getattr(config, k) == (tuple(v) if isinstance(v, list) else v) for k, v in defaults.items())


# ----------------------------------------------------------------------------- a tiny run


@pytest.mark.slow
def test_tiny_run_its_figures_and_a_refused_resume(tmp_path, capsys, monkeypatch):
    out = tmp_path / "run"
    figures = capture_figures(monkeypatch)
    assert train.main(TINY + [f"out={out}", "eval_targets=8"]) == 0
    printed = capsys.readouterr().out
    assert str(out) in printed
    saved = json.loads((out / "config.json").read_text())
    assert saved["num_envs"] == 16 and saved["train_targets"] == "" and saved["sim_dtype"] == "float32"
    rows = _rows(out / "metrics.csv")
    assert len(rows) == 4 and rows[-1]["episodes"] == "64"
    timing = json.loads((out / "timing.json").read_text())
    assert (timing["updates"], timing["episodes"]) == (4, 64) and timing["train_s"] > 0
    result = json.loads((out / "eval.json").read_text())
    throws = _rows(out / "eval_throws.csv")
    assert len(throws) == 8 and list(throws[0]) == ["target_x", "target_y", "T", "delta", "miss_m"]
    miss = np.array([float(t["miss_m"]) for t in throws])
    assert result["n_targets"] == 8 and result["task"] == "basketball"
    assert result["success_rate_10cm"] == np.mean(miss < 0.10) and result["median_m"] == pytest.approx(np.median(miss))

    # the figures draw finite data: the learning curve of metrics.csv, the histogram of the
    # misses, the throw at the median miss (arm and ball)
    curve = figures["learning_curve.png"]
    per_update = finite_line(curve, "per update (mean over its episodes)", min_points=4)
    np.testing.assert_allclose(per_update["x"], [16, 32, 48, 64])
    np.testing.assert_allclose(per_update["y"], [float(r["episode_reward"]) for r in rows], rtol=1e-6)
    finite_line(curve, "100-episode moving average", min_points=4)
    bars = finite_line(figures["error_histogram.png"], "bars", min_points=11)
    assert bars["y"].sum() == pytest.approx(100.0)
    finite_line(figures["throw.png"], "arm at release", min_points=3)
    finite_line(figures["throw.png"], "ball", min_points=200)

    # resume refuses a changed option that shaped the saved run, before compiling anything (a
    # resume that trains on is checked by the killed run below and, with a longer budget, by
    # test_randomize.py's run: a cheap task, where this one would compile basketball's update again)
    assert checkpoint.load_raw(out / "checkpoint.ckpt")["step"] == 4
    with no_compile(), pytest.raises(ValueError, match="train_targets='area' differs"):
        train.train({**train.parse_args(TINY)[0], "out": str(out), "resume": True,
                     "train_targets": "area"}, {})
    with no_compile(), pytest.raises(ValueError, match="sim_dtype='float64' differs from the checkpoint's 'float32'"):
        train.train({**train.parse_args(TINY)[0], "out": str(out), "resume": True, "sim_dtype": "float64"}, {})


def test_training_targets_differ_from_evaluation_only_where_the_task_says_so():
    basketball = make("basketball")
    assert train.training_params(basketball).target_sampling == "mixed"  # TRAIN_TARGETS
    assert train.training_params(basketball, "area").target_sampling == "area"
    assert basketball.default_params().target_sampling == "action"  # what evaluation draws
    pickplace = make("pickplace")
    assert pickplace.train_variants == ()
    with pytest.raises(ValueError, match="train_targets='mixed' is invalid for task='pickplace'"):
        train.training_params(pickplace, "mixed")
    with pytest.raises(ValueError, match="single training distribution"):
        train.parse_args(["task=pickplace", "train_targets=mixed"])


@pytest.mark.extended
def test_sim_dtype_reaches_the_training_params_only():
    for task, trains_in in (("basketball", "float32"), ("pickplace", "float64")):
        env = make(task)
        assert train.training_params(env, "", "float32").sim_dtype == "float32"
        assert train.training_params(env, "", "float64").sim_dtype == "float64"
        assert env.train_sim_dtype == trains_in and train.training_params(env).sim_dtype == trains_in
        assert env.default_params().sim_dtype == "float64"  # what evaluation simulates with
    with pytest.raises(ValueError, match="sim_dtype='float16' is invalid; expected float64, float32"):
        train.parse_args(["task=basketball", "sim_dtype=float16"])
    from gvsjax.tasks import basketball, pickplace

    for module in (basketball, pickplace):
        with pytest.raises(ValueError, match="sim_dtype='float16' is invalid; choose 'float64' or 'float32'"):
            module.make_params(sim_dtype="float16")


# ----------------------------------------------------------------------------- divergence


@pytest.fixture
def bandit_tasks(monkeypatch):
    """Registers the test bandit ("bandit") and one whose reward is NaN on 1% of valid steps."""

    class NanBandit(BanditEnv):
        name = "nanbandit"

        def step(self, key, state, action, params):
            obs, new, reward, done, info = super().step(key, state, action, params)
            return obs, new, jnp.where(state.target[0] > 0.98, jnp.nan, reward), done, info

    monkeypatch.setitem(base._REGISTRY, "bandit", BanditEnv)
    monkeypatch.setitem(base._REGISTRY, "nanbandit", NanBandit)


BANDIT = ["num_envs=16", "num_minibatches=2", "update_epochs=1", "total_episodes=960",
          "progress=false", "eval_targets=0", "updates_per_call=1", "checkpoint_every=1e9"]


def test_nan_loss_stops_training_and_keeps_the_last_good_checkpoint(bandit_tasks, tmp_path, capsys):
    out = tmp_path / "nan"
    assert train.main(["task=nanbandit", f"out={out}"] + BANDIT) == 3
    err = capsys.readouterr().err
    assert "training stopped: metric" in err and "=nan at update" in err and str(out / "checkpoint.ckpt") in err
    bad_update = int(err.split("=nan at update ")[1].split(".")[0].split()[0])
    assert 0 < bad_update < 60  # NaN rewards on ~1% of steps: it fails early, not at update 0
    rows = _rows(out / "metrics.csv")
    assert [int(r["update"]) for r in rows] == list(range(bad_update + 1))
    assert math.isnan(float(rows[-1]["loss"])) and all(math.isfinite(float(r["loss"])) for r in rows[:-1])
    meta = checkpoint.load_raw(out / "checkpoint.ckpt")
    assert meta["step"] == bad_update  # the state before the failing update, saved on the way out
    assert not (out / "timing.json").exists()
    config = config_from_json(meta["config"])
    template = init(config, BanditEnv(), BanditEnv().default_params(), jax.random.PRNGKey(0))
    state = checkpoint.restore_state(template, meta["train_state"])
    assert all(np.all(np.isfinite(x)) for x in jax.tree.leaves(state.params))


def test_non_finite_weights_stop_training(bandit_tasks, tmp_path, capsys, monkeypatch):
    real = train.update_fn
    calls = []

    def poisoned(*args, **kwargs):
        step = real(*args, **kwargs)

        def run(state):
            state, metrics = step(state)
            calls.append(1)
            if len(calls) == 3:  # metrics stay finite, one weight does not
                state = state.replace(params=jax.tree.map(lambda x: x.at[(0,) * x.ndim].set(jnp.inf),
                                                          state.params))
            return state, metrics

        return run

    monkeypatch.setattr(train, "update_fn", poisoned)
    out = tmp_path / "inf"
    assert train.main(["task=bandit", f"out={out}", "checkpoint_every=0"] + BANDIT[:-1]) == 3
    err = capsys.readouterr().err
    assert "params" in err and "non-finite by update 2" in err
    assert checkpoint.load_raw(out / "checkpoint.ckpt")["step"] == 2  # saved after call 2, kept


# ----------------------------------------------------------------------------- killed, resumed, repeated runs

ROOT = Path(__file__).resolve().parents[1]
# The killed, resumed and repeated runs train the test bandit: what they check (a SIGKILL mid-run,
# the atomic checkpoint, resume, bit-identical reruns) does not depend on the task, and a physics
# task's compile would be most of their time. Two basketball processes ending bit-identical are
# checked by the compile-cache test (extended tier).
N_UPDATES = 400  # 16 episodes each, a checkpoint after every one; b is killed past the middle
SUB = ["task=bandit", "num_envs=16", "num_steps=1", "num_minibatches=2", "update_epochs=1",
       f"total_episodes={16 * N_UPDATES}", "progress=false", "eval_targets=0", "updates_per_call=1",
       "checkpoint_every=0", "seed=5"]
BASKETBALL = ["task=basketball", *SUB[1:]]
# python -m gvsjax.train with the test bandit registered (it lives in tests/, not in the package)
LAUNCH = ("import sys; sys.path.insert(0, 'tests'); from bandit_env import BanditEnv; "
          "from gvsjax.tasks import register; register('bandit', BanditEnv); "
          "from gvsjax import train; sys.exit(train.main(sys.argv[1:]))")


def _start(out, *args, task_args=SUB):
    entry = ["-c", LAUNCH] if task_args[0] == "task=bandit" else ["-m", "gvsjax.train"]
    return subprocess.Popen([sys.executable, *entry, *task_args, f"out={out}", *args], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _finish(proc, timeout=900):
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out + err


def _saved_step(path):
    try:
        return checkpoint.load_raw(path)["step"]
    except checkpoint.CheckpointError:  # not written yet
        return -1


@pytest.fixture(scope="session")
def runs(tmp_path_factory):
    """Two trainings of one config: a runs through; b, started once a is training, is SIGKILLed
    once its checkpoint is past the middle (config.json then garbled) and resumed to the end.

    Made once per test run: under pytest-xdist the first worker to ask makes them in the run's
    shared temporary folder (holding a lock) and the others read them."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        shared = tmp_path_factory.getbasetemp().parent  # one per test run, shared by its workers
        with open(shared / "train_runs.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            if not (shared / "train_runs" / "info.json").exists():
                _make_runs(shared / "train_runs")
        root = shared / "train_runs"
    else:
        root = tmp_path_factory.mktemp("train_runs")
        _make_runs(root)
    return root, json.loads((root / "info.json").read_text())


def _make_runs(root):
    root.mkdir(exist_ok=True)
    deadline = time.monotonic() + 900
    procs = {"a": _start(root / "a")}
    while _saved_step(root / "a" / "checkpoint.ckpt") < 1:  # b starts once a has compiled (and cached) its programs
        if procs["a"].poll() is not None:
            pytest.fail(f"run a ended before its first checkpoint: {_finish(procs['a'])}")
        assert time.monotonic() < deadline, "run a wrote no checkpoint in 900 s"
        time.sleep(0.01)
    procs["b"] = _start(root / "b")
    ckpt = root / "b" / "checkpoint.ckpt"
    while _saved_step(ckpt) < N_UPDATES // 2:
        if procs["b"].poll() is not None:
            pytest.fail(f"run b ended before the kill: {_finish(procs['b'])}")
        assert time.monotonic() < deadline, "run b did not reach the middle in 900 s"
        time.sleep(0.01)
    running = procs["b"].poll() is None
    os.kill(procs["b"].pid, signal.SIGKILL)
    killed = _finish(procs["b"])
    info = {"running_at_kill": running, "killed_rc": killed[0],
            "killed_step": checkpoint.load_raw(ckpt)["step"],
            "rows_at_kill": _complete_rows(root / "b" / "metrics.csv")}
    (root / "b" / "config.json").write_text('{"num_envs": 1, garbled')  # resume must not read it
    procs["b"] = _start(root / "b", "resume=true")
    info["done"] = {name: _finish(p) for name, p in procs.items()}
    (root / "info.json").write_text(json.dumps(info))


def _complete_rows(path):
    """Rows of a CSV a kill may have cut inside its last line (that line is left out)."""
    text = path.read_text()
    return list(csv.DictReader(text[: text.rfind("\n") + 1].splitlines()))


def _comparable(rows):
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in rows]


def test_killed_run_resumes_and_completes(runs):
    root, info = runs
    for name, (rc, text) in info["done"].items():
        assert rc == 0, f"run {name}: exit {rc}\n{text}"
    assert info["running_at_kill"] and info["killed_rc"] == -signal.SIGKILL
    assert N_UPDATES // 2 <= info["killed_step"] < N_UPDATES  # killed mid-run
    b = root / "b"
    assert checkpoint.load_raw(b / "checkpoint.ckpt")["step"] == N_UPDATES
    updates = [int(r["update"]) for r in _rows(b / "metrics.csv")]
    assert updates == list(range(N_UPDATES))  # every update once: rows past the checkpoint were dropped
    assert json.loads((b / "config.json").read_text())["num_envs"] == 16  # rewritten from the checkpoint
    assert not list(b.glob(".*.tmp"))
    assert json.loads((b / "timing.json").read_text())["updates"] == N_UPDATES


def test_resumed_run_is_bit_identical_to_an_uninterrupted_one(runs):
    root, _ = runs
    a, b = root / "a", root / "b"
    assert _comparable(_rows(b / "metrics.csv")) == _comparable(_rows(a / "metrics.csv"))
    assert (checkpoint.load_raw(b / "checkpoint.ckpt")["train_state"]
            == checkpoint.load_raw(a / "checkpoint.ckpt")["train_state"])  # weights, Adam, key, envs


def test_same_config_and_seed_give_bit_identical_runs(runs):
    # b's rows up to the kill (over half the run) came from another process than a's
    root, info = runs
    before = _comparable(info["rows_at_kill"])
    rows = _comparable(_rows(root / "a" / "metrics.csv"))
    assert len(before) >= N_UPDATES // 2 and len(rows) == N_UPDATES
    assert before == rows[: len(before)]


@pytest.mark.parametrize("damage", ["truncate", "flip"])
def test_resume_from_a_damaged_checkpoint_is_a_clear_error(runs, bandit_tasks, tmp_path, capsys, damage):
    root, _ = runs
    run = tmp_path / "b"
    shutil.copytree(root / "b", run)
    blob = (run / "checkpoint.ckpt").read_bytes()
    if damage == "truncate":
        blob = blob[: len(blob) * 2 // 3]
    else:
        blob = blob[:-100] + bytes([blob[-100] ^ 0x5A]) + blob[-99:]
    (run / "checkpoint.ckpt").write_bytes(blob)
    with no_compile():
        rc = train.main(SUB + [f"out={run}", "resume=true", f"total_episodes={32 * N_UPDATES}"])
    err = capsys.readouterr().err
    assert rc == 2 and str(run / "checkpoint.ckpt") in err
    assert ("truncated" in err) if damage == "truncate" else ("corrupted" in err)


@pytest.mark.extended
def test_a_compile_cache_is_written_once_and_then_read(tmp_path):
    """Two processes train the same program with ``compile_cache``: the first fills the folder,
    the second finds every program there (no new entry) and trains to the same checkpoint."""
    cache = tmp_path / "cache"
    tiny = ["total_episodes=128", "updates_per_call=8"]
    code, log = _finish(_start(tmp_path / "a", f"compile_cache={cache}", *tiny, task_args=BASKETBALL))
    assert code == 0, log
    entries = sorted(p.name for p in cache.iterdir())
    assert entries, "the first run wrote no compiled program"
    code, log = _finish(_start(tmp_path / "b", f"compile_cache={cache}", *tiny, task_args=BASKETBALL))
    assert code == 0, log
    assert sorted(p.name for p in cache.iterdir()) == entries  # every program came from the cache
    a, b = (checkpoint.load_raw(tmp_path / r / "checkpoint.ckpt")["train_state"] for r in "ab")
    jax.tree.map(np.testing.assert_array_equal, a, b)


def test_compile_cache_is_a_folder_option():
    run, _ = train.parse_args(["compile_cache=~/cache"])
    assert run["compile_cache"] == "~/cache" and train.parse_args([])[0]["compile_cache"] == ""
