"""The clone stays light: what git tracks is code, assets, summary JSONs and the figures the docs show. Run
checkpoints and logs are not tracked, except the latest checkpoint of a run in progress (one folder) and the zoo."""

import json
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
IN_PROGRESS = "benchmarks/results/in_progress/"
ZOO = "dexart_lite/zoo/"
MAX_TREE_BYTES = 30 * 1024 * 1024  # the tracked tree outside IN_PROGRESS


def tracked() -> list[str]:
    done = subprocess.run(["git", "ls-files", "-z"], capture_output=True, cwd=ROOT)
    if done.returncode:
        pytest.skip("not a git checkout")
    return [name for name in done.stdout.decode().split("\0") if name and (ROOT / name).is_file()]


def test_the_tracked_tree_outside_runs_in_progress_is_at_most_30_mb():
    sizes = {name: (ROOT / name).stat().st_size for name in tracked() if not name.startswith(IN_PROGRESS)}
    biggest = sorted(sizes, key=sizes.get)[-3:]
    assert sum(sizes.values()) <= MAX_TREE_BYTES, f"{sum(sizes.values()) / 2**20:.1f} MiB tracked; largest: {biggest}"


def test_checkpoints_are_tracked_only_in_the_zoo_and_for_runs_in_progress_and_logs_not_at_all():
    names = tracked()
    stray = [n for n in names if n.endswith((".pt", ".pth", ".ckpt")) and not n.startswith((ZOO, IN_PROGRESS))]
    assert not stray, f"checkpoints outside {ZOO} and {IN_PROGRESS}: {stray[:5]}"
    logs = [n for n in names if n.startswith("benchmarks/results/") and n.endswith(".csv")]
    assert not logs, f"run logs are not tracked: {logs[:5]}"


def test_a_parked_run_is_unfinished_and_every_parked_folder_is_a_run_or_its_student():
    """A run that reached its frames is deleted from the in-progress folder; a student stays only while a parked
    run starts from it."""
    folders = {Path(n).parts[3] for n in tracked() if n.startswith(IN_PROGRESS) and len(Path(n).parts) > 4}
    records = {f: json.loads((ROOT / IN_PROGRESS / f / "run.json").read_text()) for f in folders}
    runs = {f for f, r in records.items() if "frames" in r["config"]}
    for name in runs:
        assert records[name]["frames"] < records[name]["config"]["frames"], f"{name} is finished: delete it"
        assert (ROOT / IN_PROGRESS / name / "checkpoint.pt").is_file()
    students = {Path(records[f]["config"]["init_from"]).parent.name for f in runs if records[f]["config"].get("init_from")}
    assert folders - runs <= students, f"parked folders no run needs: {sorted(folders - runs - students)}"
