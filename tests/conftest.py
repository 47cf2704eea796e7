"""Suite-wide setup: cheaper compiles and one JAX compilation cache for the whole run.

Most of the suite's time is XLA compiling the unrolled GVS programs, and many tests
(and the training runs they start as subprocesses, and the notebooks' kernels) compile
the same program again. JAX's persistent cache lets every process of one run reuse a
program another has compiled. The cache starts empty in a fresh temporary folder each
run, so no result depends on an earlier run; set ``JAX_COMPILATION_CACHE_DIR`` yourself
to keep one across runs.
"""

import gc
import os
import shutil
import tempfile

# The suite is compile-bound, and LLVM's optimisation of the generated code is a large share of
# each compile. Level 0 cut the default run's CPU time by about a fifth on two cores; the
# programs compute the same operations (the tests' tolerances hold). Set before JAX starts its
# backend; subprocesses inherit it. Speed is measured by benchmarks, which keep XLA's defaults.
_OPT = "--xla_backend_optimization_level"
if _OPT not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + f" {_OPT}=0").strip()

import gvsjax  # noqa: E402, F401, I001  (before JAX: it configures JAX)
import jax  # noqa: E402

# Tracing a GVS program allocates hundreds of thousands of long-lived objects, and each of
# Python's full collections then rescans everything imported (JAX, NumPy, SciPy, Matplotlib):
# a quarter of a 3D task's trace time. Freezing the imported objects and collecting the
# youngest generation less often removes most of it; the programs are unchanged.
gc.freeze()
gc.set_threshold(10_000, 10, 10)

_OWNED = "GVSJAX_TEST_CACHE_OWNER"


def pytest_configure(config):
    if "JAX_COMPILATION_CACHE_DIR" not in os.environ:  # the first process of the run makes it
        os.environ["JAX_COMPILATION_CACHE_DIR"] = tempfile.mkdtemp(prefix="gvsjax-test-jit-")
        os.environ[_OWNED] = str(os.getpid())
    # subprocesses (training runs, notebook kernels) read these from the environment
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.5")
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES", "0")
    jax.config.update("jax_compilation_cache_dir", os.environ["JAX_COMPILATION_CACHE_DIR"])
    jax.config.update("jax_persistent_cache_min_compile_time_secs",
                      float(os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"]))
    jax.config.update("jax_persistent_cache_min_entry_size_bytes",
                      int(os.environ["JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES"]))


# The files that take longest (measured per test over one default run on 2 cores), longest first.
# Under ``--dist loadfile`` a worker takes a whole file at a time, so these go out first and
# the workers end on short files together. Only the order depends on this list.
LONGEST_FILES = ("test_reach_obstacles.py", "test_ppo_train.py", "test_throw3d.py", "test_train_cli.py",
                 "test_simulation.py", "test_basketball.py", "test_balance.py", "test_reach_pose.py",
                 "test_track3d.py", "test_pickplace.py", "test_sections.py", "test_physics_references.py",
                 "test_contact.py", "test_statics.py", "test_gym.py")


def pytest_collection_modifyitems(config, items):
    """The longest files first (above), and within a file the tests marked slow."""
    rank = {name: i for i, name in enumerate(LONGEST_FILES)}
    items.sort(key=lambda item: (rank.get(item.path.name, len(rank)), item.get_closest_marker("slow") is None))


def pytest_unconfigure(config):
    if os.environ.get(_OWNED) == str(os.getpid()):
        shutil.rmtree(os.environ["JAX_COMPILATION_CACHE_DIR"], ignore_errors=True)
