"""What the benchmark scripts share and the package does not need: their common flags, one experiment runner,
and side-by-side runs of an earlier commit.

Benchmarks are scripts, not a package: a script loads this module by path,

    harness = sibling_script(__file__, "_harness")   # dexart_lite.utils.sibling_script
    harness.options(parser, "task", "seeds", "jobs", json=RESULTS / "x.json")   # --task, --seeds, --jobs, --json
    rows = harness.run_grid(measure, grid, jobs=args.jobs, path=args.json, summarise=summarise, settings=...)
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
from dataclasses import dataclass, field
from pathlib import Path

from dexart_lite import TASKS
from dexart_lite.cli import add_config_arguments
from dexart_lite.objects import SPLITS


@dataclass
class Options:
    """The flags the benchmark scripts share, one meaning each; a script takes those it needs with ``options``.
    Settings of a learner or an env are not here: a script takes those from its config dataclass
    (``add_config_arguments(parser, DistillConfig, names=[...])``), and its own flags from a ``Flags`` dataclass
    beside its ``main`` (``add_config_arguments(parser, Flags, overrides=False)``)."""

    task: str = field(default="laptop", metadata={"help": "the task", "choices": TASKS})
    tasks: list[str] = field(default_factory=lambda: list(TASKS), metadata={"help": "the tasks", "choices": TASKS})
    split: str = field(default="seen", metadata={"help": "the objects", "choices": list(SPLITS)})
    splits: list[str] = field(default_factory=lambda: ["seen", "unseen"],
                              metadata={"help": "the object splits", "choices": list(SPLITS)})
    seed: int = field(default=0, metadata={"help": "the seed (env resets, noise, network initialisation)"})
    seeds: list[int] = field(default_factory=lambda: [0, 1, 2], metadata={"help": "one run per seed"})
    jobs: int = field(default=1, metadata={"min": 1, "help": "runs or evaluations at once, one process each (2 on "
                                                             "a 2-core machine)"})
    episodes_per_object: int = field(default=3, metadata={"min": 1, "help": "episodes per object"})
    eval_episodes: int = field(default=3, metadata={"min": 1,
                                                    "help": "evaluation episodes per seen and unseen object"})
    frames: int = field(default=100_000, metadata={"min": 1, "help": "environment frames per run"})
    epochs: int = field(default=10, metadata={"min": 1, "help": "passes over the training data"})
    runs: Path = field(default=Path("runs"), metadata={"help": "parent of the per-run folders"})
    json: Path | None = field(default=None, metadata={"help": "write the results here"})
    note: str | None = field(default=None, metadata={"help": "a line stored in the JSON (e.g. how a run was stopped)"})
    obs: str = field(default="state", metadata={"help": "the learner's observation: the object's state or the point "
                                                        "cloud", "choices": ["state", "cloud"]})
    results: Path | None = field(default=None, metadata={"help": "the folder the JSON and PNG files go to"})
    png: Path | None = field(default=None, metadata={"help": "also plot the result to this PNG"})
    cache: Path = field(default=Path("runs/checkpoints_from_git"),
                        metadata={"help": "where checkpoints named REV:path are extracted from git"})
    threads: int = field(default=0, metadata={"help": "torch threads (0: all cores)"})
    sigmas: list[float] = field(default_factory=lambda: [0.0, 0.1, 0.2],
                                metadata={"min": 0.0,
                                          "help": "std of the Gaussian noise on the executed actions, one run each"})
    expert: str | None = field(default=None, metadata={"help": "another expert of the task than its own, by class "
                                                                "name (dexart_lite.experts.TASK_EXPERTS)"})
    # timings (benchmarks/perf): each measurement repeated, interleaved with the others, its median reported
    steps: int = field(default=400, metadata={"min": 1, "help": "env steps per timed measurement"})
    resets: int = field(default=400, metadata={"help": "env resets per timed measurement"})
    rounds: int = field(default=3, metadata={"min": 1,
                                             "help": "repeats of each timed measurement, interleaved (median)"})
    ref: str | None = field(default=None, metadata={"help": "an earlier commit measured side by side (in a git "
                                                           "worktree)"})


def options(parser, *names: str, helps: dict | None = None, required: tuple[str, ...] = (), **defaults) -> None:
    """Add the ``Options`` flags ``names`` (and those given a default here) to ``parser``:
    ``options(parser, "task", "jobs", seeds=[0], json=RESULTS / "x.json")`` adds ``--task``, ``--jobs``,
    ``--seeds`` (default 0) and ``--json``. ``helps``: a script's own help line for a flag; ``required``: the flags
    the script cannot run without (argparse then refuses a command line that lacks one)."""
    add_config_arguments(parser, Options, names=[*names, *defaults], overrides=False, defaults=defaults, helps=helps,
                         required=required)


def run_grid(job, grid: list[dict], *, jobs: int = 1, path: Path | None = None, summarise=None,
             settings: dict | None = None, rows_key: str = "rows", desc: str = "runs") -> list[dict]:
    """The one experiment runner: ``job(**params)`` for every ``params`` of ``grid`` (seeds x settings), ``jobs``
    at once (one spawned process each; a stopped runner stops them all), rows returned in the grid's order, each
    ``{**params, **job(...)}``.

    With ``path``, it is resumable: after every finished row ``summarise(rows)`` (a dict; the finished rows go
    under ``rows_key``, with ``settings`` beside them) is written to ``path``, and a later call with the same
    ``settings`` reads those rows back instead of running them again. A training job is resumable on its own
    as well (``study.run_arm`` continues a run from its folder)."""
    from dexart_lite.utils import write_json

    settings = settings or {}
    earlier = json.loads(path.read_text()) if path is not None and path.exists() else {}
    reusable = earlier.get(rows_key, []) if earlier.get("settings") == settings else []
    rows = [next((r for r in reusable if all(r.get(k) == v for k, v in params.items())), None) for params in grid]
    todo = [i for i, row in enumerate(rows) if row is None]
    if len(todo) < len(grid):
        print(f"{path}: {len(grid) - len(todo)} of {len(grid)} rows read back (same settings)")

    for i, row in zip(todo, each(job, [grid[i] for i in todo], jobs=jobs, desc=desc)):
        rows[i] = {**grid[i], **row}
        if path is not None:
            done = [r for r in rows if r is not None]
            write_json(path, {**(summarise(done) if summarise else {}), rows_key: done, "settings": settings})
    return rows


def rows_not_rerun(previous: dict, rows: list[dict], key, rows_key: str = "rows") -> list[dict]:
    """The rows of an earlier result ``previous`` (its ``rows_key`` list) that no row of ``rows`` measures again (by
    ``key(row)``), each with the command and machine that measured it (its own where it has them, else the earlier
    file's): for a script that measures part of its grid again and keeps the rest of its JSON."""
    fresh = {key(r) for r in rows}
    return [{"command": previous["command"], "machine": previous["machine"], **r} for r in previous[rows_key]
            if key(r) not in fresh]


def each(job, grid: list[dict], *, jobs: int = 1, desc: str = "runs"):
    """``job(**params)`` for every ``params`` of ``grid``, yielded in the grid's order as they finish, ``jobs`` at
    once in spawned processes (``job`` must then be a module-level function): with a progress bar, and a stopped
    caller (an error, Ctrl-C, ``kill``) stops every worker. The job's rows come back as they are; ``run_grid``
    adds the parameters to them and the resumable JSON."""
    from tqdm import tqdm

    from dexart_lite.utils import process_pool, sigterm_interrupts

    # the bar closes last, also when stopped: its line ends before whatever the caller prints next
    with tqdm(total=len(grid), desc=desc, unit="run", disable=len(grid) < 2) as bar, sigterm_interrupts(), \
            process_pool(max(1, jobs)) if jobs > 1 else contextlib.nullcontext() as pool:
        # submit(job, **params): only job and its arguments cross to a worker, nothing of this module (a script's
        # module-level job pickles by reference, this file is not importable there)
        results = (f.result() for f in [pool.submit(job, **params) for params in grid]) if pool else \
            (job(**params) for params in grid)
        for row in results:
            bar.update()
            yield row


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
