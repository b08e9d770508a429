"""What the benchmark scripts share and the package does not need: side-by-side runs of an earlier commit.

Benchmarks are scripts, not a package: a script loads this module by path,

    harness = sibling_script(__file__, "_harness")   # dexart_lite.utils.sibling_script
    with harness.git_worktree(ROOT, "HEAD~3") as ref_root:
        rate = harness.run_in_checkout(ref_root, CODE, "laptop")

and the tests through ``load_benchmark("_harness")`` (tests/conftest.py).
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path


def run_in_checkout(root, code: str, *args: str) -> dict:
    """Run Python ``code`` with the ``dexart_lite`` found under ``root`` (a checkout), one thread, in a
    fresh interpreter; return the JSON it prints last. Benchmarks use it to time this checkout and an
    earlier commit (``git_worktree``) side by side, alternately, in one run."""
    root = Path(root).resolve()
    # An editable install could shadow the checkout's package: check which one the interpreter imports.
    check = (f"import dexart_lite, pathlib\nassert pathlib.Path(dexart_lite.__file__).resolve().is_relative_to("
             f"{str(root)!r}), 'dexart_lite imported from ' + dexart_lite.__file__\n")
    env = dict(os.environ, PYTHONPATH=str(root), OMP_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", check + code, *args], env=env, cwd=root, capture_output=True,
                         text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


@contextlib.contextmanager
def git_worktree(repo, ref: str):
    """``with git_worktree(repo, ref) as root:`` a temporary checkout of commit ``ref``, removed afterwards."""
    root = Path(tempfile.mkdtemp(prefix="dexart_lite_ref_"))
    subprocess.run(["git", "-C", str(repo), "worktree", "add", "--detach", str(root), ref], check=True,
                   capture_output=True)
    try:
        yield root
    finally:
        subprocess.run(["git", "-C", str(repo), "worktree", "remove", "--force", str(root)], capture_output=True)
