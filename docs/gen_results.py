"""The results tables and pages, made from the committed JSON in ``benchmarks/``: no number is typed twice.

``tables(root)`` returns ``{name: markdown}``: one table per result. A page shows one by holding the
line ``<!-- results: NAME -->`` (the mkdocs hook, ``docs/hooks.py``, puts the table there; GitHub shows
nothing). ``pages(root)`` returns the generated Results section: an overview of every task's default
run, a page per task with every recorded run and its command, and an index of the data files.
``task_table(root, docs)`` is the table of tasks of both front pages: the site's home page shows it (as
``tasks``), README.md holds it as printed with ``docs="docs/"`` (tests/test_docs.py compares them).

Sources: ``benchmarks/eval_<task>.json`` (each task's recorded evaluations: runs, their training, the
command, the metrics), ``benchmarks/time_to_quality*.json`` (basketball's five seeds) and the studies'
JSON (``track3d_basis``, ``*_substeps``, ``reach_obstacles_steps``, ``throw3d_convergence``,
``muscle_workspace``, ``tendon_reachability``, ``curvature_arm_basis``, ``env_throughput``, ``sim``,
``benchmark_task_runs``, ``elastica_twins``, ``elastica_twist``, ``twist_speed``,
``benchmark_tasks_speed``).

Run it alone to print every table: ``python docs/gen_results.py [NAME ...]``.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TASK_PAGES = {  # task -> its page (docs-relative); the eval files of these tasks are required
    "basketball": "tasks/basketball.md", "pickplace": "tasks/pickplace.md", "throw3d": "tasks/throw3d.md",
    "track3d": "tasks/track3d.md", "track3d_muscle": "tasks/track3d.md", "reach_pose": "tasks/reach_pose.md",
    "reach_pose_muscle": "tasks/reach_pose.md", "reach_obstacles": "tasks/reach_obstacles.md",
    "reach_obstacles_2d": "tasks/reach_obstacles.md", "balance": "tasks/balance.md",
}
# the table of tasks on both front pages (README.md, docs/index.md): what an episode is, by task
EPISODES = {
    "basketball": "one throw of the paper's arm at a target on the court (the paper: 100% / 55%)",
    "pickplace": "two 5 s motions of a tendon arm to a pick and a place target",
    "throw3d": "one throw from a base that also turns, at 3D targets all around the shooter",
    "track3d": "10 s of closed-loop tendon control of a 3D arm following a moving target",
    "reach_pose": "2 s of closed-loop control to a target tip position and direction",
    "reach_obstacles": "3 s of closed-loop control reaching into a cage of bars, with contact",
    "balance": "10 s of base torque swinging the paper's arm up and holding it upright",
}
# the benchmark tasks have no eval file: their row summarises tasks_benchmark.md's findings
BENCHMARK_ROW = ["[`follow_target`, `ik_4d` (`ik_4d_frame`), `obstacles_2d`, `obstacles_3d`](tasks_benchmark.md)",
                 "the soft-arm benchmark of Choi & Tong (natural-curvature control)",
                 "SAC: 81-89% of the published return on `follow_target` at their 5M steps with their network "
                 "(~60% with a smaller one), ~80% on `ik_4d` at 2M (PPO: a sixth and a ninth); obstacles in progress"]
GROUPS = {"default": "the default", "longer": "longer training", "reference": "references and baselines",
          "box": "on the whole box (before the reachable default)", "variant": "variants (studies)"}


# ---------------------------------------------------------------- formatting

def num(x, digits: int | None = None, unit: str = "") -> str:
    """A number as the table shows it: as stored (``digits`` None) or rounded; inf/nan as words."""
    if x is None:
        return ""
    if isinstance(x, str):
        return x
    if isinstance(x, float) and math.isinf(x):
        return "diverges"
    if isinstance(x, float) and math.isnan(x):
        return "-"
    if digits is None:
        s = str(x)
    elif digits == 0:
        s = f"{round(x):,}"
    else:
        s = f"{x:.{digits}f}"
    return f"{s} {unit}".strip() if unit and unit != "%" else (s + "%" if unit == "%" else s)


def sig(x, n: int = 2) -> str:
    """x to n significant digits, without exponent (0.0012, 13, 1,014)."""
    if x is None or (isinstance(x, float) and (math.isinf(x) or math.isnan(x))):
        return num(x)
    if x == 0:
        return "0"
    digits = max(0, n - 1 - int(math.floor(math.log10(abs(x)))))
    return f"{x:,.{digits}f}" if digits == 0 else f"{x:.{digits}f}"


def table(header: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def commands(runs: list[dict]) -> str:
    """The commands that make a table's rows, as a code block (``# the run`` after each)."""
    lines = [f"{r['command']}    # {r['run'].replace('`', '')}"
             for r in runs if r.get("command", "").startswith("python")]
    return "\n".join(["```bash", *lines, "```"]) if lines else ""


def load(root: Path, name: str):
    return json.loads((root / "benchmarks" / name).read_text())


# ---------------------------------------------------------------- the tasks' evaluations

def eval_file(root: Path, task: str) -> dict:
    return load(root, f"eval_{task}.json")


def cell(run: dict, column: dict) -> str:
    values = [run.get(k) for k in column["keys"]]
    if all(v is None for v in values):
        return ""
    unit = column.get("unit", "")
    parts = [num(v) for v in values]
    text = " / ".join(p if p else "-" for p in parts)
    return text + ("%" if unit == "%" else f" {unit}" if unit else "")


def eval_table(d: dict, groups: tuple[str, ...], with_commands: bool = True) -> str:
    """The runs of ``groups`` from an ``eval_<task>.json``: run, training, then its columns."""
    runs = [r for r in d["runs"] if r["group"] in groups]
    header = ["run", "training"] + [c["label"] for c in d["columns"]]
    rows = [[r["run"], r.get("training", "")] + [cell(r, c) for c in d["columns"]] for r in runs]
    out = table(header, rows)
    out += f"\n\nEvaluation: {d['evaluation']}. Data: `benchmarks/eval_{d['task']}.json`."
    if with_commands and commands(runs):
        out += "\n\n" + commands(runs)
    return out


BASKETBALL_FILES = [("0", "time_to_quality.json"), ("1", "time_to_quality_seed1.json"),
                    ("2", "time_to_quality_seed2.json"), ("3", "time_to_quality_seed3.json"),
                    ("4", "time_to_quality_seed4.json"),
                    ("0, `sim_dtype=float64`, the paper's trunk (another host)", "time_to_quality_float64.json")]


def basketball_rows(root: Path) -> list[tuple[str, dict]]:
    """(seed label, the final evaluation) of each committed basketball run."""
    return [(label, load(root, f)["curve"][-1]) for label, f in BASKETBALL_FILES]


def basketball_table(root: Path) -> str:
    rows = []
    for label, e in basketball_rows(root):
        rows.append([label, f"{e['episodes'] / 1e6:.1f}M", num(100 * e["success_rate_10cm"], 1, "%"),
                     num(100 * e["within_1cm"], 1, "%"), num(1000 * e["median_m"], 1, "mm"),
                     num(100 * e["p95_m"], 2, "cm"), num(100 * e["max_m"], 2, "cm")])
    paper = [r["curve"][-1] for r in load(root, "time_to_quality_paper_layers.json")["runs"].values()]
    lo_hi = [(min(e[k] for e in paper), max(e[k] for e in paper)) for k in ("success_rate_10cm", "within_1cm")]
    rows.append([f"0-{len(paper) - 1}, the paper's trunk (`shared_hidden=128,32,16`), the same host",
                 f"{paper[0]['episodes'] / 1e6:.1f}M"]
                + [f"{num(100 * lo, 1)}-{num(100 * hi, 1, '%')}" for lo, hi in lo_hi] + ["", "", ""])
    for r in eval_file(root, "basketball")["runs"]:
        rows.append([r["run"], "", num(r["within_10cm_pct"], None, "%"), num(r["within_1cm_pct"], None, "%"),
                     "", "", ""])
    return (table(["seed", "episodes", "< 10 cm", "< 1 cm", "median", "p95", "max"], rows)
            + "\n\nEvaluation: the 1000 held-out targets of `python -m gvsjax.evaluate` (seed 1,000,003 + seed), "
            "float64; the final evaluation of `experiments/studies/time_to_quality.py`, the default "
            "`python -m gvsjax.train task=basketball` program. "
            "Data: `benchmarks/time_to_quality*.json`, `benchmarks/eval_basketball.json`.\n\n"
            "```bash\npython experiments/studies/time_to_quality.py --json benchmarks/time_to_quality.json"
            "          # seed 0\n"
            "python experiments/studies/time_to_quality.py --json benchmarks/time_to_quality_seed1.json seed=1   "
            "# and seeds 2-4\npython experiments/studies/time_to_quality.py seed=0 shared_hidden=128,32,16"
            "                      # the paper's trunk\n"
            "python experiments/paper/baseline_basketball.py runs/a 1000 1000003"
            "          # the baseline\n```")


def headline(root: Path, task: str) -> str:
    """One result of the task's default (seed 0): the eval file's ``headline`` filled from its first
    default run."""
    if task == "basketball":
        e = basketball_rows(root)[0][1]
        return (f"{num(100 * e['success_rate_10cm'], 1, '%')} within 10 cm, "
                f"{num(100 * e['within_1cm'], 1, '%')} within 1 cm")
    d = eval_file(root, task)
    run = next(r for r in d["runs"] if r["group"] == "default")
    return d["headline"].format(**run)


# ---------------------------------------------------------------- studies

def track3d_basis(root: Path) -> str:
    d = load(root, "track3d_basis.json")["rows"]
    ref = d["reference"]
    cases = [c for c in ref["statics"] if c != "wall_s"]

    def dist(a, b):
        return 1000 * math.dist(a, b)

    rows = []
    for name, r in d.items():
        if name == "reference":
            continue
        c = r["config"]
        label = (f"bending {c['bending_order']}, torsion {c['torsion_order']}, "
                 + ("no stretch" if c["stretch_order"] < 0 else f"stretch {c['stretch_order']}")
                 + ("" if c["shear_order"] < 0 else f", shears {c['shear_order']}"))
        errs = [dist(a, b) for a, b in zip(r["dynamics"]["tip"], ref["dynamics"]["tip"])]
        rms = math.sqrt(sum(e * e for e in errs) / len(errs))
        rows.append([label, r["dofs"]] + [f"{dist(r['statics'][k]['tip'], ref['statics'][k]['tip']):.1f}"
                                          for k in cases] + [f"{max(errs):.1f}", f"{rms:.1f}", f"{errs[-1]:.1f}"])
    rc = ref["config"]
    return (table(["basis (Legendre orders)", "DoFs"] + [f"{k} (statics)" for k in cases]
                  + ["2 s step: max", "rms", "at 2 s"], rows)
            + f"\n\nTip distance (mm) from the reference basis (bending {rc['bending_order']}, torsion "
            f"{rc['torsion_order']}, stretch {rc['stretch_order']}, shears {rc['shear_order']}: {ref['dofs']} DoFs). "
            "Data: `benchmarks/track3d_basis.json`.\n\n"
            "```bash\npython experiments/studies/track3d_basis.py     # ~15 min\n```")


def substeps(root: Path, name: str, command: str) -> str:
    d = load(root, f"{name}.json")
    rows = [[r["n_substeps"], f"{sig(1000 * r['random_max_tip_error_m'])} / {sig(1000 * r['random_p95_tip_error_m'])}",
             f"{sig(1000 * r['held_max_tip_error_m'])} / {sig(1000 * r['held_p95_tip_error_m'])}",
             num(r["env_steps_per_s"], 0)] for r in d["rows"]]
    return (table(["steps per 0.1 s", "random actions: max / p95 tip error (mm)", "held 1 s: max / p95 (mm)",
                   f"env steps/s, batch {d['batch']}"], rows)
            + f"\n\nAgainst {d['reference_substeps']} steps, {d['episodes']} episodes. Data: `benchmarks/{name}.json`."
            f"\n\n```bash\n{command}\n```")


def balance_substeps(root: Path) -> str:
    d = load(root, "balance_substeps.json")
    rows = [[r["substeps"], f"{sig(r['random_max_mm'])} / {sig(r['random_p95_mm'])}",
             f"{sig(r['baseline_max_mm'])} / {sig(r['baseline_p95_mm'])}",
             f"{num(100 * r['baseline_success'], 0, '%')}, {r['baseline_time_to_upright_s']:.2f} s"] for r in d["rows"]]
    return (table(["steps per 0.05 s", "random: max / p95 tip error (mm)", "baseline: max / p95 (mm)",
                   "baseline closed loop: success, time to upright"], rows)
            + f"\n\nAgainst {d['reference']} steps. Data: `benchmarks/balance_substeps.json`."
            "\n\n```bash\npython experiments/studies/balance_substeps.py --substeps 1,2,4,8,16\n```")


def reach_obstacles_steps(root: Path) -> str:
    d = load(root, "reach_obstacles_steps.json")
    rows = []
    for r in d["rows"]:
        tip = (f"{sig(100 * r['tip_error_max_m'])} / {sig(100 * r['tip_error_p95_m'])} cm"
               if not r.get("diverged") else f"{num(100 * r['diverged'], 0, '%')} diverged")
        rows.append([f"{r['stiffness']:.0e}".replace("e+0", "e"), r["n_substeps"], tip,
                     f"{1000 * r['deepest_m']:.0f} mm", f"{1000 * r['reference_deepest_m']:.0f} mm"])
    return (table(["bar stiffness k (N/m per m)", "ars443 steps per 0.1 s", "tip error: max / p95",
                   "deepest penetration", "the reference's"], rows)
            + f"\n\nAgainst {d['reference_substeps']} steps, a batch of {d['batch']} episodes of random actions. "
            "Data: `benchmarks/reach_obstacles_steps.json`.\n\n```bash\n"
            "python experiments/studies/reach_obstacles_steps.py --substeps 8 16 --batch 16    # ~15 min\n```")


def curvature_substeps(root: Path) -> str:
    d = load(root, "curvature_substeps.json")
    rows = [[r["dtype"], r["substeps"], f"{sig(r['tip_error_mm_median'])} / {sig(r['tip_error_mm_p95'])} / "
             f"{sig(r['tip_error_mm_max'])}", num(r["env_steps_per_s"], 0)] for r in d["rows"]]
    return (table(["dtype", "steps per 0.1 s", "tip error median / p95 / max (mm)",
                   f"env steps/s, batch {d['batch']}"], rows)
            + f"\n\nAgainst {d['reference']}. Data: `benchmarks/curvature_substeps.json`."
            "\n\n```bash\npython experiments/studies/curvature_substeps.py\n```")


def curvature_arm_basis(root: Path) -> str:
    d = load(root, "curvature_arm_basis.json")
    rows = [[k, m["dofs"], f"{sig(m['tip_error_mm_median'])} / {sig(m['tip_error_mm_max'])}",
             f"{sig(m['tangent_error_deg_median'])} / {sig(m['tangent_error_deg_max'])}"]
            for k, m in d["models"].items()]
    return (table(["model", "DoFs", "tip error median / max (mm)", "tangent error median / max (deg)"], rows)
            + f"\n\nAgainst the {d['reference']}, {d['n_samples']} samples ({d['actions']}). "
            "Data: `benchmarks/curvature_arm_basis.json`.\n\n"
            "```bash\npython experiments/studies/curvature_arm_basis.py\n```")


def throw3d_convergence(root: Path) -> str:
    d = load(root, "throw3d_convergence.json")
    rows = [[k, f"the same arm, {d['fine_steps']} steps",
             f"{sig(v['max_cm'])} / {sig(v['p95_cm'])} / {sig(v['median_cm'])}"] for k, v in d["integration"].items()]
    rows += [[k, "the richest arm, 400 steps" if "richest" not in k else "itself at 400 steps",
              f"{sig(v['max_cm'])} / {sig(v['p95_cm'])} / {sig(v['median_cm'])}"] for k, v in d["basis"].items()]
    rich = ", ".join(f"{k} {v}" for k, v in d["richest"].items())
    return (table(["model", "against", "landing difference max / p95 / median (cm)"], rows)
            + f"\n\nLanding points of {d['n_actions']} random actions. The richest arm: {rich}. "
            "Data: `benchmarks/throw3d_convergence.json`.\n\n"
            "```bash\npython experiments/studies/throw3d_convergence.py    # ~15 min\n```")


def muscle_workspace(root: Path) -> str:
    d = load(root, "muscle_workspace.json")
    rows = []
    for key, m in d.items():
        if not isinstance(m, dict):
            continue
        kind = "tendons" if key.startswith("tendon") else "muscles"
        unit = "N" if kind == "tendons" else "N m"
        low = " / ".join("-" if m["lowest_z_at_radius_m"][r] is None else f"{m['lowest_z_at_radius_m'][r]:.2f}"
                         for r in ("0.5", "0.6", "0.7", "0.8"))
        rows.append([f"{kind}, {m['limit']:g} {unit}", num(100 * m["box_within_5cm"], 1, "%"),
                     num(100 * m["box_within_10cm"], 1, "%"), low + " m", f"{m['max_radius_m']:.2f} m"])
    return (table(["actuation", "box within 5 cm", "within 10 cm",
                   "lowest tip at 0.5 / 0.6 / 0.7 / 0.8 m from the axis", "furthest from the axis"], rows)
            + f"\n\n{d['samples']} held actions per actuation, {d['box_points']} points of the target box. "
            "Data: `benchmarks/muscle_workspace.json`.\n\n```bash\npython experiments/studies/muscle_workspace.py\n```")


def env_throughput(root: Path) -> str:
    d = load(root, "env_throughput.json")
    rows = [[f"`{r['task']}`", num(r["env_steps_per_s"], 0), f"{r['first_call_s']:.1f} s",
             f"{r['load_average_1min']:.1f}"] for r in d]
    return (table(["task", f"env steps/s, batch {d[0]['batch']}", "first call (compile)", "load average"], rows)
            + "\n\n`jit(vmap(step))` with auto-reset and random actions, float64. "
            "Data: `benchmarks/env_throughput.json`."
            "\n\n```bash\npython experiments/benchmarks/bench_env.py --task reach_pose --batch 1024"
            "   # and the other tasks\n```")


def sim_throughput(root: Path) -> str:
    d = load(root, "sim.json")
    rows = []
    for c in d["configurations"]:
        for r in c["rows"]:
            rows.append([f"{c['n_steps']} {c['integrator']}", c["dtype"], r["batch"], num(r["throws_per_s"], 0),
                         num(r["sim_seconds_per_wall_second"], 0), f"{1000 * c['release_error_m']:.2f} mm"])
    return (table(["integration", "dtype", "batch", "throws/s", "simulated s per wall s", "release error"], rows)
            + "\n\nBasketball swings to release, batched with `vmap`. Data: `benchmarks/sim.json`."
            "\n\n```bash\npython experiments/benchmarks/bench_sim.py --json benchmarks/sim.json\n```")


CONTACT_COST_RUNS = """python experiments/benchmarks/bench_contact_cost.py --batches 1024 \\
    --layouts none "0 obstacles" sphere \\
    "1 capsules" "4 capsules" "12 capsules" "48 capsules" "12 capsules, 8 pairs" \\
    "12 capsules, nearest 4" "48 capsules, nearest 4" "12 capsules, all pairs" "48 capsules, all pairs" \\
    --check-layouts none sphere "12 capsules" "48 capsules" "48 capsules, all pairs" --json benchmarks/contact_cost.json
python experiments/benchmarks/bench_contact_cost.py --append --batches 1 64 \\
    --layouts none sphere "12 capsules" "48 capsules" \\
    --check-layouts --rounds 7 --json benchmarks/contact_cost.json
python experiments/benchmarks/bench_contact_cost.py --figure figures/contact_cost.png
"""


def contact_cost(root: Path) -> str:
    """The obstacle tasks' arm: cost of contact per layout and batch, against the code before the hand
    derivatives and the broad phase (``contact_cost_before.json``: that code, measured the same way)."""
    d, before = load(root, "contact_cost.json"), load(root, "contact_cost_before.json")
    batches = sorted({r["batch"] for r in d["rows"]})
    old = {r["layout"]: r for r in before["rows"] if r["batch"] == max(batches)}
    cell = lambda r: f"{r['ratio_to_no_contact']:.2f}x ({r['us_per_arm_step']:.0f} us)" if r else ""  # noqa: E731
    names = list(dict.fromkeys(r["layout"] for r in d["rows"]))
    pick = lambda name, b: next((r for r in d["rows"] if r["layout"] == name and r["batch"] == b), None)  # noqa: E731
    rows = [[name] + [cell(pick(name, b)) for b in batches] + [cell(old.get(name.replace(", all pairs", "")))]
            for name in names]
    acc = {r["layout"]: r for r in d["accuracy"]}
    checks = [[r["layout"], f"{1e3 * max(r['deepest_penetration_m'], 0.0):.2f} mm",
               f"{1e3 * max(acc[r['layout']]['deepest_penetration_m'], 0.0):.2f} mm",
               f"{r['fraction_touching']:.0%}", f"{acc[r['layout']]['fraction_touching']:.0%}",
               f"{abs(acc[r['layout']]['mean_final_q'] - r['mean_final_q']):.1e}"]
              for r in before["accuracy"] if r["layout"] in acc]
    load_avg = ", ".join(f"{x:.1f}" for x in d["loadavg_before"])
    return (table(["layout"] + [f"batch {b}" for b in batches] + [f"before, batch {max(batches)}"], rows)
            + f"\n\nThe cost per arm-step against the same arm without contact (`Robot.contact` None), "
            f"{d['dtype']}, `{d['integrator']}` at {1e3 * d['dt']:g} ms, median of {d['rounds']} round-robin rounds "
            f"(load average {load_avg} on 2 cores at the start). A layout without a suffix is the task's "
            "arm, which runs the law on at most 16 (piece, bar) pairs in reach (`Contact.pairs`); \"8 pairs\": "
            "the same with 8; \"nearest 4\": "
            "the earlier broad phase, each piece's 4 nearest bars (`Contact.nearest`); \"all pairs\": no broad "
            "phase. \"before\": the "
            "code before the hand-written derivatives and the broad phase, measured the same way in its own run. "
            "Data: `benchmarks/contact_cost.json`, `benchmarks/contact_cost_before.json`.\n\n"
            + table(["layout", "deepest penetration, before", "now", "runs touching, before", "now",
                     "mean final q, difference"], checks)
            + f"\n\n{d['accuracy_batch']} runs of {d['accuracy_steps']} steps ({d['accuracy_steps'] * d['dt']:g} s) "
            "under random held tendon tensions up to "
            f"{d['tension_max']:g} N.\n\n```bash\n{CONTACT_COST_RUNS}```")


def contact_swing(root: Path) -> str:
    """The paper's swing with contact (``benchmarks/contact.json``, ``benchmarks/contact_swing_*.json``),
    one table per run."""
    parts = []
    names = ["contact.json", *sorted(p.name for p in (root / "benchmarks").glob("contact_swing_*.json"))]
    for name in names:
        d = load(root, name)
        rows = [[r["layout"], num(r["throws_per_s"], 0), f"{r['slowdown_vs_first']:.1f}x", f"{r['compile_s']:.1f} s",
                 f"{1e3 * r['deepest_penetration_m']:.1f} mm", f"{r['loadavg'][0]:.1f}"] for r in d["rows"]]
        header = ["layout", "throws/s", "slowdown", "compile", "deepest penetration", "load after (1 min)"]
        parts.append(table(header, rows)
                     + f"\n\nThe paper's swing, `{d['integrator']}`, {d['n_steps']} steps per throw, batch "
                     f"{d['rows'][0]['batch']}; {d['load_average_before']}. Data: `benchmarks/{name}`."
                     f"\n\n```bash\n{d['command']}\n```")
    return "\n\n".join(parts)


def benchmark_task_runs(root: Path) -> str:
    """Every kept training run of the four benchmark tasks (``benchmarks/curvature_ppo_study/``)."""
    sys.path.insert(0, str(root / "experiments" / "studies"))
    import curvature_ppo_study

    return (curvature_ppo_study.table(root / "benchmarks" / "curvature_ppo_study")
            + "\n\nData: `benchmarks/curvature_ppo_study/*.json`, one file per run, each with its command."
            "\n\n```bash\npython experiments/studies/curvature_ppo_study.py --table\n```")


def mpc_derivative(root: Path) -> str:
    """The gradient planner's passes in both solve layouts (``benchmarks/mpc_derivative*.json``)."""
    sys.path.insert(0, str(root / "experiments" / "benchmarks"))
    import bench_mpc_derivative

    parts = []
    for path in sorted((root / "benchmarks").glob("mpc_derivative*.json")):
        parts.append(bench_mpc_derivative.report(str(path)) + f"\n\nData: `benchmarks/{path.name}`."
                     f"\n\n```bash\n{json.loads(path.read_text())['command']}\n```")
    return "\n\n".join(parts)


def gradient(root: Path) -> str:
    """Reverse mode against the forward pass (``benchmarks/gradient.json``)."""
    sys.path.insert(0, str(root / "experiments" / "benchmarks"))
    import bench_gradient

    parts = []
    for name, title in (("gradient_before", "Before (the code at the tree named in the data)"),
                        ("gradient", "Now")):
        path = root / "benchmarks" / f"{name}.json"
        d = json.loads(path.read_text())
        note = f" {d['note'][0].upper()}{d['note'][1:]}." if "note" in d else ""
        parts.append(f"**{title}.**{note}\n\n{bench_gradient.report(str(path))}\n\nData: `benchmarks/{name}.json`."
                     f"\n\n```bash\n{d['command']}\n```")
    return "\n\n".join(parts)


def mpc_bc(root: Path) -> str:
    """Behaviour cloning of the gradient MPC against the PPO default (``benchmarks/mpc_bc/*.json``)."""
    sys.path.insert(0, str(root / "experiments" / "studies"))
    import mpc_behaviour_cloning

    return mpc_behaviour_cloning.table(root)


def mpc_reference(root: Path) -> str:
    """The MPC on each task it was run on, beside the task's policy on the same episodes
    (``benchmarks/mpc_reference/<task>.json``)."""
    import gvsjax  # noqa: F401
    from gvsjax.tasks import make

    rows = []
    for f in sorted((root / "benchmarks" / "mpc_reference").glob("*.json")):
        d = json.loads(f.read_text())
        c, env = d["controller"], make(d["task"])
        s = c["controller"]
        policy = env.summary(d["policy"]) if "policy" in d else "not evaluated on these episodes"
        how = (f"mppi, {s['samples']} samples, noise {s['noise']}" if s.get("planner") == "mppi"
               else f"adam, {s['gradient']} gradient")
        rows.append([d["task"], f"H {s['horizon']}, {s['iterations']} it., {how}", d["episodes"],
                     env.summary({**c, "who": "MPC"}), policy, _fraction(env, c, d.get("policy")), _per_step(c),
                     f"`{d['command']}`"])
    if not rows:
        return "No MPC run is committed yet."
    return (table(["task", "MPC settings", "episodes", "MPC", "trained policy, same episodes",
                   "policy / MPC (the task's headline)", "MPC ms per control step and episode (batched)", "command"],
                  rows)
            + "\n\nData: `benchmarks/mpc_reference/*.json` (settings, metrics, wall time, machine load).")


def _fraction(env, mpc: dict, policy: dict | None) -> str:
    """The policy's headline metric as a fraction of the MPC's."""
    a, b = env.headline(mpc), env.headline(policy) if policy else None
    if a is None or b is None:
        return "-"
    if a[1] > 0 and b[1] >= 0:
        return f"{b[1] / a[1]:.2f} ({a[0]}: {b[1]:.3g} / {a[1]:.3g})"
    return f"no ratio: a value below 0 ({a[0]}: {b[1]:.3g} / {a[1]:.3g})"


def _per_step(c: dict) -> str:
    """Run time per control step (compile separate) where recorded; older runs: wall time with compile."""
    if "run_ms_per_control_step" in c:
        return f"{c['run_ms_per_control_step']:.0f} (+ {c['compile_s']:.0f} s compiling)"
    return f"{c['wall_ms_per_control_step']:.0f} (compile included)"


def _metric_cells(task: str, m: dict) -> str:
    """A task's physical metrics in one cell."""
    if task == "follow_target":
        return (f"mean distance {100 * m['mean_distance_m']:.1f} cm, within 5 / 10 cm "
                f"{100 * m['within_5cm']:.1f} / {100 * m['within_10cm']:.1f}%")
    if task == "ik_4d":
        return (f"final distance {100 * m['final_distance_m']['median']:.1f} cm, "
                f"orientation {m['final_orientation_deg']['median']:.1f} deg (medians)")
    return (f"final distance {100 * m['final_distance_m']['median']:.1f} cm (median), within 5 cm "
            f"{100 * m['within_5cm']:.0f}%, deepest {1000 * m['deepest_m']['median']:.1f} mm (median), "
            f"> 1 cm {100 * m['penetrating']:.0f}%")


def elastica_twins(root: Path) -> str:
    """The benchmark tasks in gvsjax and in their PyElastica twins, the same episodes
    (``benchmarks/elastica_twins.json``)."""
    d = load(root, "elastica_twins.json")
    shape = d.pop("_rest_shape_gap", None)
    rows = []
    order = ("follow_target", "ik_4d", "obstacles_2d", "obstacles_3d")
    for r in sorted(d.values(), key=lambda r: (order.index(r["task"]), r.get("contact") or "")):
        p = r["paired"]
        rel = p["relative_mean_difference"]
        for sim in ("gvsjax", "pyelastica"):
            ret = r[sim]["discounted_return_average"]
            law = " (PyElastica with gvsjax's contact law)" if r.get("contact") == "gvsjax" else ""
            label = f"`{r['task']}`{law}" + (f" ({r['label']} policy)" if r.get("label") else "")
            rows.append([label if sim == "gvsjax" else "", r["n_episodes"] if sim == "gvsjax" else "",
                         "gvsjax" if sim == "gvsjax" else "PyElastica",
                         f"{ret['mean']:.2f} ({ret['median']:.2f})", _metric_cells(r["task"], r[sim]),
                         "" if sim == "gvsjax" else
                         f"{p['return_difference']['median']:+.2f}"
                         + (f" ({100 * rel:+.1f}% of the mean" if rel is not None else " (")
                         + (f"; r = {p['return_correlation']:.3f})" if p["return_correlation"] is not None
                            else "; every episode the same)"),
                         "" if sim == "gvsjax" else f"{100 * p['tip_distance_m']['median']:.1f} / "
                         f"{100 * p['tip_distance_m']['p95']:.1f} cm"])
    cmds = "\n".join(r["command"] for r in d.values())
    return (table(["task", "episodes", "simulator", "return: mean (median)", "physical metrics",
                   "PyElastica - gvsjax, per episode: median (mean's share; correlation)",
                   "tip apart: median / p95"], rows)
            + "\n\nReturn: the benchmark's discounted return averaged over start steps (gamma 0.99). "
            "A row named after a policy runs that gvsjax-trained policy, deterministic; the other rows of "
            "follow_target and ik_4d run the PPO defaults, and those of the obstacle tasks open-loop random "
            "actions held 10 steps. obstacles_2d has one fixed start, layout and target, so a policy's "
            "episodes are all the same one. Data: `benchmarks/elastica_twins.json`."
            + ("\n\nThe curvature mappings alone (no load, rest shapes): the discrete rod's tip and gvsjax's "
               "continuum's are " + ", ".join(f"{1000 * r['tip_gap_m']['median']:.1f} mm" for r in shape["rows"])
               + " apart (median over " + str(shape["rows"][0]["n"]) + " random turning angles uniform in "
               + ", ".join(f"[-{r['amplitude_rad']:g}, {r['amplitude_rad']:g}]" for r in shape["rows"])
               + " rad per point and direction)." if shape else "")
            + f"\n\n```bash\n{cmds}" + (f"\n{shape['command']}" if shape else "") + "\n```")


def elastica_twist(root: Path) -> str:
    """The 3D benchmark arm against its PyElastica twin under random walks (``benchmarks/elastica_twist.json``)."""
    d = load(root, "elastica_twist.json")

    def cells(x: list) -> list[str]:
        return [f"{_percentile(x, 50):.2f}", f"{_percentile(x, 95):.2f}", f"{max(x):.2f}"]

    dyn, st = d["dynamic_gap_cm"], d["settled_gap_cm"]
    arms = {"torsion": "gvsjax, twisting (default)", "rigid_torsion": "gvsjax, rigid in torsion (before)"}
    rows = [[label, "during the walks", "PyElastica, 20 elements", *cells(dyn[k])] for k, label in arms.items()]
    for n in d["refined"]:
        rows += [[label, "settled", f"PyElastica, {n} elements", *cells(st[f"{k}_vs_{n}"])]
                 for k, label in arms.items()]
    rows += [["PyElastica, 20 elements", "settled", f"PyElastica, {n} elements", *cells(st[f"twin20_vs_{n}"])]
             for n in d["refined"]]
    rows.append(["PyElastica, 40 elements", "settled", "PyElastica, 60 elements", *cells(st["twin40_vs_60"])])
    return (table(["arm", "when", "against", "tip distance (cm): median", "p95", "max"], rows)
            + f"\n\n{d['episodes']} smooth random walks of {d['seconds']:g} s (10 bending actions), then "
            f"{d['hold_s']:g} s without action (settled). Twin: {d['twin']}. Data: `benchmarks/elastica_twist.json`."
            f"\n\n```bash\n{d['command']}\n```")


def twist_speed(root: Path) -> str:
    """Env steps/s of the 3D tasks before and after their arm twisted (``benchmarks/twist_speed.json``)."""
    d = load(root, "twist_speed.json")
    r = d["env_steps_per_s"]
    rows = [[task, num(r[f"{task} before"], 0), num(r[f"{task} after"], 0),
             f"{r[f'{task} after'] / r[f'{task} before']:.2f}"] for task in ("follow_target", "ik_4d")]
    load_avg = d["load_average_1min"]
    return (table(["task", "before: env steps/s", "after", "after / before"], rows)
            + f"\n\nBatch {d['batch']}, {d['dtype']}, median of {d['repeats']} calls of {d['steps_per_call']} steps, "
            f"the four cases interleaved (load average {min(load_avg):.1f}-{max(load_avg):.1f}). Before: "
            "`follow_target` rigid in torsion with `ars443`, `ik_4d` with `ars443` at 4 steps per 0.1 s; after: "
            "the defaults. Data: `benchmarks/twist_speed.json`.\n\n"
            f"```bash\n{d['command']}\n```")


def _percentile(x: list, q: float) -> float:
    s = sorted(x)
    k = (len(s) - 1) * q / 100
    lo = math.floor(k)
    return s[lo] + (s[min(lo + 1, len(s) - 1)] - s[lo]) * (k - lo)


def benchmark_tasks_speed(root: Path) -> str:
    """Env steps/s of the benchmark tasks, gvsjax against the PyElastica twins
    (``benchmarks/benchmark_tasks_speed.json``)."""
    d = load(root, "benchmark_tasks_speed.json")
    rows = []
    for name, r in d["tasks"].items():
        pe = r["pyelastica"]
        for g in r["gvsjax"]:
            rows.append([f"`{name}`", "yes" if r["contact"] else "no", g["batch"], g.get("devices", 1),
                         num(g["env_steps_per_s"], 0),
                         sig(pe["env_steps_per_s_2_cores"], 3), f"{g['ratio_to_pyelastica_2_cores']:.1f}x",
                         f"{r['target_ratio']:.0f}x", _duration(5e6 / g["env_steps_per_s"]),
                         f"{g['loadavg_before'][0]:.1f}"])
    return (table(["task", "contact", "batch", "devices", "gvsjax env steps/s", "PyElastica env steps/s (2 cores)",
                   "ratio", "issue 48's target", "5M env steps (their budget), the env alone", "load (1 min)"],
                  rows)
            + "\n\ngvsjax: `jit(vmap(env.step))`, float32 (the training dtype), median of 3 calls after "
            "compiling, on one JAX device or with the batch split over 2 CPU devices, one per core "
            "(`XLA_FLAGS=--xla_force_host_platform_device_count=2`); PyElastica: one twin per process, its rate "
            "x 2 cores. "
            f"Machine: {d['machine']}; `uptime` before: {d['uptime_before']}. "
            "Data: `benchmarks/benchmark_tasks_speed.json`."
            f"\n\n```bash\n{d['command']}\n```")


def _duration(seconds: float) -> str:
    """A duration in minutes, or in hours past two."""
    return f"{seconds / 60:.0f} min" if seconds < 7200 else f"{seconds / 3600:.1f} h"


def _first_and_held(curve: list[dict], ok) -> tuple[int | None, int | None]:
    """The episodes at which ``ok`` first holds, and from which it holds at every later evaluation."""
    first = next((c["episodes"] for c in curve if ok(c)), None)
    held = next((c["episodes"] for i, c in enumerate(curve) if all(ok(x) for x in curve[i:])), None)
    return first, held


def time_to_quality(root: Path) -> str:
    def k(n):
        return "not reached" if n is None else f"{round(n / 1000)}k"

    def paper(c):
        return c["success_rate_10cm"] >= 1.0 and c["within_1cm"] >= 0.55

    def p93(c):
        return c["within_1cm"] >= 0.93

    def cells(curve):
        first, held = _first_and_held(curve, paper)
        end = curve[-1]
        return [f"{k(first)} ({'not held' if held is None else k(held)})", k(_first_and_held(curve, p93)[0]),
                f"{100 * end['success_rate_10cm']:.1f}% / {100 * end['within_1cm']:.1f}%"]

    trunk = load(root, "time_to_quality_paper_layers.json")["runs"]
    rows = [[seed, *cells(load(root, f)["curve"]), *cells(trunk[seed]["curve"])]
            for seed, f in BASKETBALL_FILES[:5]]
    return (table(["seed", "paper's level (100% within 10 cm, >= 55% within 1 cm): first (held from)",
                   "93% within 1 cm, first", "end: within 10 / 1 cm", "paper's trunk: paper's level",
                   "paper's trunk: 93%", "paper's trunk: end"], rows)
            + "\n\nEpisodes of the default program (trunk 128-64-32) and of the paper's trunk (128-32-16) at "
            "which each level is first reached on the 1000 held-out targets. "
            "Data: `benchmarks/time_to_quality*.json`."
            "\n\n```bash\n"
            "python experiments/studies/time_to_quality.py --json benchmarks/time_to_quality.json  # seed 0\n"
            "python experiments/studies/time_to_quality.py --json benchmarks/time_to_quality_seed1.json seed=1\n"
            "    # seeds 1-4\n"
            "python experiments/studies/time_to_quality.py seed=0 shared_hidden=128,32,16    # the paper's trunk\n```")


def tendon_arm(root: Path) -> str:
    d = load(root, "tendon_arm.json")
    cases: dict[str, dict[int, dict]] = {}
    for r in d["rows"]:
        cases.setdefault(r["case"], {})[r["batch"]] = r
    rows = [[case, by[1]["dofs"], f"{by[1]['compile_s']:.1f} s / {by[1024]['compile_s']:.1f} s",
             num(by[1]["steps_per_s"], 0), num(by[1024]["steps_per_s"], 0)] for case, by in cases.items()]
    st = d["statics"]
    return (table(["case", "DoFs", "compile, batch 1 / 1024", "arm-steps/s, batch 1", "arm-steps/s, batch 1024"],
                  rows)
            + f"\n\n`{d['integrator']}` at dt = {1000 * d['dt']:g} ms for {d['duration']:g} s, float64. Statics: "
            f"`equilibrium` compiles in {st['equilibrium']['compile_s']:.0f} s and solves in "
            f"{1000 * st['equilibrium']['solve_s']:.0f} ms, `inverse_statics` in "
            f"{st['inverse_statics']['compile_s']:.0f} s and {1000 * st['inverse_statics']['solve_s']:.0f} ms. "
            "Data: `benchmarks/tendon_arm.json`.\n\n"
            "```bash\npython experiments/benchmarks/bench_tendon_arm.py --json benchmarks/tendon_arm.json\n```")


def compile_time(root: Path) -> str:
    """``experiments/benchmarks/bench_compile.py``'s JSON: compile and step time per model and Gauss points,
    each tree."""
    d = load(root, "compile_time.json")
    trees = list(d["trees"])
    by = {(r["model"], r["n_gauss"], r["tree"]): r for r in d["rows"]}
    rows = []
    dofs = {r["model"]: r["dofs"] for r in d["rows"]}
    for model, g in sorted(dict.fromkeys((r["model"], r["n_gauss"]) for r in d["rows"]),
                           key=lambda mg: (dofs[mg[0]], mg[0], mg[1])):
        cells = [f"`{model}`", next(r["dofs"] for r in d["rows"] if r["model"] == model), g]
        runs = [by.get((model, g, t)) for t in trees]
        for r in runs:
            ok = r is not None and r.get("status") == "ok"
            cells.append(f"{r['b1']['compile_s']:.1f} s" if ok else (r or {}).get("status", "-"))
        for key in ("b1", "big"):
            for r in runs:
                ok = r is not None and r.get("status") == "ok" and key in r
                cells.append(sig(min(r[key]["runs_s"]) / d["n_steps"] * 1e3) if ok else "")
        rows.append(cells)
    big = d["big_batch"]
    header = (["model", "DoFs", "Gauss points"] + [f"compile, {t}" for t in trees]
              + [f"step ms, batch 1, {t}" for t in trees] + [f"step ms, batch {big}, {t}" for t in trees])
    loads = [x for r in d["rows"] for x in (r["load_before"][0], r["load_after"][0])]
    return (table(header, rows)
            + f"\n\n`{d['integrator']}`, {d['dtype']}, {d['n_steps']} steps of {1e3 * d['dt']:g} ms per call, "
            f"compile time at batch 1 (tracing, lowering and XLA), step time the fastest of {d['repeats']} calls "
            "(on a loaded machine the least disturbed); "
            f"each model and tree in its own process, the trees interleaved; 1-minute load average "
            f"{min(loads):.1f}-{max(loads):.1f} on {d['cpu_count']} cores. Data: `benchmarks/compile_time.json`."
            "\n\n```bash\n" + "\n".join(d.get("commands") or [d.get("command", "")]) + "\n```")


def reachability_table(d: dict, policy) -> str:
    """``experiments/studies/tendon_reachability.py``'s JSON as a table: each row at the largest action sample,
    how far its shares moved over the last doubling, and ``policy(task)``, the committed policy's result."""
    what = {"box": "the published box (the policy's)", "reachable": "the reachable part (the default now)",
            "table": "the held-out poses", "reset": "the task's own draws"}
    rows = []
    for row in d["rows"]:
        sizes = list(row["by_samples"])
        last, before = row["by_samples"][sizes[-1]], row["by_samples"][sizes[-2]]
        keys = [k for k in last if k.startswith("within_")]
        held = ", ".join(k[len("within_"):].replace("_", " & ").replace("deg", " deg").replace("cm", " cm")
                         + f": {100 * last[k]:.1f}%" for k in keys)
        moved = max(abs(last[k] - before[k]) for k in keys)
        rows.append([row["task"], what[row["targets"]], f"{100 * last['median_m']:.1f} cm", held,
                     f"{100 * moved:.1f} points ({sizes[-2]} -> {sizes[-1]} actions)",
                     policy(row["task"]) if row["targets"] != "reachable" else ""])
    return table(["task", "targets", "median distance to the nearest held tip", "targets held within",
                  "change at the last doubling", "the committed policy (default, seed 0)"], rows)


def tendon_reachability(root: Path) -> str:
    d = load(root, "tendon_reachability.json")
    return (reachability_table(d, lambda task: headline(root, task)) + "\n\nData: "
            f"`benchmarks/tendon_reachability.json`.\n\n```bash\n{d['command'].strip()}\n```")


STUDIES = {
    "track3d_basis": track3d_basis,
    "track3d_substeps": lambda r: substeps(r, "track3d_substeps", "python experiments/studies/track3d_substeps.py "
                                          "--substeps 2,4,8,16 --episodes 32"),
    "track3d_muscle_substeps": lambda r: substeps(
        r, "track3d_muscle_substeps", "python experiments/studies/track3d_substeps.py --task track3d_muscle "
        "--substeps 8 "
        "--episodes 16 --batch 64 --json benchmarks/track3d_muscle_substeps.json"),
    "balance_substeps": balance_substeps,
    "reach_obstacles_steps": reach_obstacles_steps,
    "curvature_substeps": curvature_substeps,
    "curvature_arm_basis": curvature_arm_basis,
    "throw3d_convergence": throw3d_convergence,
    "muscle_workspace": muscle_workspace,
    "tendon_reachability": tendon_reachability,
    "env_throughput": env_throughput,
    "sim": sim_throughput,
    "benchmark_task_runs": benchmark_task_runs,
    "mpc_reference": mpc_reference,
    "mpc_derivative": mpc_derivative,
    "gradient": gradient,
    "mpc_bc": mpc_bc,
    "elastica_twins": elastica_twins,
    "elastica_twist": elastica_twist,
    "twist_speed": twist_speed,
    "benchmark_tasks_speed": benchmark_tasks_speed,
    "time_to_quality": time_to_quality,
    "tendon_arm": tendon_arm,
    "compile_time": compile_time,
    "contact_cost": contact_cost,
    "contact_swing": contact_swing,
}


# ---------------------------------------------------------------- what the docs use

def tables(root: Path = ROOT) -> dict[str, str]:
    """Every generated table by name (``<!-- results: NAME -->`` in a page)."""
    out = {"basketball": basketball_table(root)}
    for task in TASK_PAGES:
        if task == "basketball":
            continue
        d = eval_file(root, task)
        out[task] = eval_table(d, ("default", "longer", "reference", "box"))
        if any(r["group"] == "variant" for r in d["runs"]):
            out[f"{task}_variants"] = eval_table(d, ("variant",))
    for name, make in STUDIES.items():
        out[name] = make(root)
    out["tasks"] = task_table(root)
    return out


def task_table(root: Path = ROOT, docs: str = "") -> str:
    """The front pages' table of tasks; links relative to docs/ behind ``docs`` (the README's: ``"docs/"``)."""
    rows = [[f"[`{task}`]({docs}{TASK_PAGES[task]})", episode, headline(root, task)]
            for task, episode in EPISODES.items()]
    page, *cells = BENCHMARK_ROW
    rows.append([page.replace("](", f"]({docs}"), *cells])
    return table(["task", "episode", "default run (seed 0)"], rows)


def pages(root: Path = ROOT) -> dict[str, str]:
    """The generated Results section: {docs-relative path: markdown}."""
    t = tables(root)
    overview = ["# Results", "",
                "Every number on these pages is read from the committed files in `benchmarks/` when the site "
                "is built (`docs/gen_results.py`); none is typed by hand. A new run of a task is a new entry of "
                "its `benchmarks/eval_<task>.json` ([adding a task](../adding_a_task.md#its-page-and-its-results)).",
                "",
                "## The tasks' defaults", ""]
    rows = [[f"[`{task}`](../{page})", headline(root, task)] for task, page in TASK_PAGES.items()]
    rows.append(["[`follow_target`, `ik_4d`, `obstacles_2d`, `obstacles_3d`](../tasks_benchmark.md)",
                 "not trained to their targets yet: [every run](benchmark_tasks.md)"])
    overview += [table(["task", "default run (1000 held-out episodes)"], rows), "",
                 "## Every run, by task", ""]
    overview += [f"- [{task}]({task}.md)" for task in TASK_PAGES]
    overview += ["- [the benchmark tasks](benchmark_tasks.md)", "", "## The data files", "",
                 "Each JSON file of `benchmarks/`, with what made it where the file says; "
                 "[benchmarks/README.md](../benchmarks/README.md) has the benchmark tables and their commands.", ""]
    for f in sorted((root / "benchmarks").glob("*.json")):
        d = json.loads(f.read_text())
        about = d.get("note") or d.get("about") or d.get("command") if isinstance(d, dict) else None
        overview.append(f"- [`{f.name}`](../benchmarks/{f.name})" + (f": {about}" if about else ""))
    out = {"results/index.md": "\n".join(overview) + "\n"}
    for task, page in TASK_PAGES.items():
        body = [f"# {task}: every run", "", f"The task: [{page}](../{page}).", ""]
        if task == "basketball":
            body += [t["basketball"]]
        else:
            d = eval_file(root, task)
            body += [d["about"] + ".", "", f"Recorded: {d['source']}.", ""]
            for g, title in GROUPS.items():
                if any(r["group"] == g for r in d["runs"]):
                    body += [f"## {title.capitalize()}", "", eval_table(d, (g,)), ""]
        out[f"results/{task}.md"] = "\n".join(body) + "\n"
    out["results/benchmark_tasks.md"] = ("# The benchmark tasks: every run\n\nThe tasks: "
                                         "[tasks_benchmark.md](../tasks_benchmark.md).\n\n"
                                         + t["benchmark_task_runs"] + "\n")
    return out


if __name__ == "__main__":
    made = tables()
    for name in sys.argv[1:] or made:
        print(f"## {name}\n\n{made[name]}\n")
