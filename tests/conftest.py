"""Shared test set-up: fast mode for tutorials and scripts, a private cache folder per session."""

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

os.environ.setdefault("DEXART_LITE_FAST", "1")


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory):
    """Generated files (the composed robot URDF) go to a fresh folder, as on a new machine."""
    os.environ["DEXART_LITE_CACHE"] = str(tmp_path_factory.mktemp("dexart_cache"))


@pytest.fixture
def load_benchmark():
    """``load_benchmark("bench_distill")`` -> the module of ``benchmarks/students/bench_distill.py``, and
    ``load_benchmark("_harness")`` the scripts' shared ``benchmarks/_harness.py`` (the benchmarks are scripts, not a
    package, so tests load them by path)."""
    folder = Path(__file__).resolve().parent.parent / "benchmarks"

    def load(name: str):
        path, = [*folder.glob(f"*/{name}.py"), *folder.glob(f"{name}.py")]  # benchmarks/[<theme>/]<name>.py
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # where @dataclass and pickle look a module up
        spec.loader.exec_module(module)
        return module

    return load


@pytest.fixture
def git_checkout():
    """Skips the test where the suite does not run inside a git checkout (``--ref`` needs ``git worktree``)."""
    if subprocess.run(["git", "-C", str(Path(__file__).parent), "rev-parse", "HEAD"], capture_output=True).returncode:
        pytest.skip("not a git checkout: --ref needs git worktree")
