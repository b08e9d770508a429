"""The results tables in the docs are generated from the committed JSON: a table typed or left stale fails here."""

from pathlib import Path

import pytest

from dexart_lite.rl.evaluate import TEST_SEEDS
from dexart_lite.utils import sibling_script

TEST_SEED = TEST_SEEDS[0]
SCRIPT = Path(__file__).resolve().parent.parent / "benchmarks" / "rl" / "curriculum_table.py"


def load():
    return sibling_script(str(SCRIPT), "curriculum_table")  # loaded by path, registered where @dataclass looks


def test_the_rl_tables_match_their_json():
    assert load().stale_tables() == [], "run: python benchmarks/rl/curriculum_table.py --write"


def test_a_changed_number_is_caught(tmp_path, monkeypatch):
    tables = load()
    doc = tmp_path / "doc.md"
    typed = tables.runs_table().replace("0.00", "0.90")
    assert typed != tables.runs_table()
    doc.write_text(f"text\n<!-- curriculum-runs -->\n{typed}\n<!-- /curriculum-runs -->\n")
    monkeypatch.setitem(tables.TABLES, "curriculum-runs", (doc, tables.runs_table))
    assert "curriculum-runs" in tables.stale_tables()
    missing = tmp_path / "missing.md"
    missing.write_text("no markers\n")
    monkeypatch.setitem(tables.TABLES, "curriculum-runs", (missing, tables.runs_table))
    with pytest.raises(ValueError, match="no <!-- curriculum-runs -->"):
        tables.main(["--write"])


def test_nothing_in_the_repository_links_outside_it():
    """A user's clone has nothing beside it: no tracked text file may point to the reference notes next to ours."""
    import subprocess

    root = SCRIPT.parents[2]
    outside = ("../" + "shared", "shared/" + "reference")  # spelt in two parts, so this file does not match itself
    tracked = subprocess.run(["git", "ls-files"], cwd=root, capture_output=True, text=True, check=True).stdout.split()
    offenders = []
    for name in tracked:
        if Path(name).suffix not in {".py", ".md", ".ipynb", ".cfg", ".txt", ".toml", ".yml", ".yaml"} and name != "Makefile":
            continue
        text = (root / name).read_text(errors="replace")
        if any(link in text for link in outside):
            offenders.append(name)
    assert offenders == []


def test_every_relative_link_in_the_docs_resolves():
    """Each ``[text](path)`` in the README, docs/ and the READMEs beside the code names a file or folder that exists
    (the reports under benchmarks/results/ are run outputs copied as they were written, GIF links included)."""
    import re
    import subprocess

    root = SCRIPT.parents[2]
    tracked = subprocess.run(["git", "ls-files", "*.md"], cwd=root, capture_output=True, text=True, check=True).stdout.split()
    broken = []
    for name in (n for n in tracked if not n.startswith("benchmarks/results/")):
        path = root / name
        for target in re.findall(r"\]\(([^)\s]+)\)", path.read_text()):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue  # a web address or an anchor on the same page
            if not (path.parent / target.split("#")[0]).exists():
                broken.append(f"{name}: {target}")
    assert broken == []


def test_the_targets_table_marks_each_split_against_its_target(tmp_path, monkeypatch):
    """The targets table checks a run set's held-out success against DexArt's Table 2 and against its students +
    0.10, split by split, unrounded but for floating point (11/110 meets 0.00 + 0.10)."""
    import json

    tables = load()
    assert tables.verdict((0.1, 0.79), (0.0 + 0.1, 0.88)) == "0.10 / 0.88: met / missed"
    paired = tmp_path / "paired.json"
    entry = {"task": "laptop", "recipe": "student_anchored_release_flat", "seeds": [0, 1], "rl_frames": [756000, 760000],
             "seen": {"student": 0.62, "rl": 0.83}, "unseen": {"student": 0.70, "rl": 0.76}}
    weaker = {**entry, "recipe": "student_anchored", "seen": {"student": 0.62, "rl": 0.70}}

    def runs(e: dict) -> list[dict]:  # per seed: the figures the rule chooses on
        return [{"task": "laptop", "recipe": e["recipe"], "seed": k,
                 "rl": {s: {"success": e[s]["rl"]} for s in ("seen", "unseen")}} for k in (0, 1)]

    def write(*entries: dict) -> None:
        paired.write_text(json.dumps({"summary": list(entries), "runs": [r for e in entries for r in runs(e)],
                                      "episodes_per_object": 10, "eval_seed": 1000}))

    write(weaker, entry)
    monkeypatch.setattr(tables, "PAIRED", paired)
    assert tables.headline("laptop")["rl"]["name"] == "laptop_cloud_student_anchored_release_flat.json"
    row = tables.targets_table().splitlines()[-2]  # laptop's row (the tasks' order: faucet, bucket, laptop, toilet)
    assert "0.83 / 0.76 (`student_anchored_release_flat`, 756k / 760k)" in row
    assert "0.81 / 0.41: met / met" in row  # DexArt's laptop
    assert "0.72 / 0.80: met / missed" in row  # 0.76 < 0.70 + 0.10
    entry["rl_frames"] = [2_100_000, 760000]  # past the 2M budget: neither the headline nor among the best within it
    write(weaker, entry)
    assert tables.headline("laptop")["rl"]["name"] == "laptop_cloud_student_anchored.json"
    assert "(`student_anchored`, 756k / 760k)" in tables.targets_table().splitlines()[-2]
    paired.write_text(paired.read_text().replace('"eval_seed": 1000', f'"eval_seed": {TEST_SEED}'))
    with pytest.raises(ValueError, match=f"env seed {TEST_SEED} is not a validation seed"):
        tables.headline("laptop")  # test-seed results never choose


def test_a_headline_cell_shows_its_test_evaluation_only_for_the_chosen_candidate(tmp_path, monkeypatch):
    import json

    tables = load()
    monkeypatch.setattr(tables, "TEST", tmp_path)
    chosen = tables.headline("laptop")["rl"]
    assert "(validation)" in tables.cell("laptop", "rl", chosen, "x")
    final = {"source": chosen["name"], "seen": {"mean": 0.9, "se": 0.02}, "unseen": {"mean": 0.8, "se": 0.05}}
    (tmp_path / "laptop_rl.json").write_text(json.dumps(final))
    assert tables.cell("laptop", "rl", chosen, "x").startswith(
        "[0.90 ± 0.02 / 0.80 ± 0.05](benchmarks/results/test/laptop_rl.json) (test seed)")
    (tmp_path / "laptop_rl.json").write_text(json.dumps({**final, "source": "another_run_set.json"}))
    assert "(validation)" in tables.cell("laptop", "rl", chosen, "x")  # a stale final evaluation is not shown
