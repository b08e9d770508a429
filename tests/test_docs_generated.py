"""docs/tables.py generates every results table in docs/ from the committed JSON: a table typed over, left stale after
a JSON changed, or added to docs/ by hand without a generator fails here."""

import re
from pathlib import Path

import pytest

from dexart_lite.utils import sibling_script

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "docs" / "tables.py"


def load():
    return sibling_script(str(SCRIPT), "tables")  # loaded by path, registered where @dataclass looks


TABLES = load().TABLES


@pytest.mark.parametrize("name", list(TABLES))
def test_each_table_matches_its_json(name):
    tables = load()
    path, make = tables.TABLES[name]
    found = tables.block(path.read_text(), name)
    assert found is not None, f"{path} lacks the <!-- {name} --> markers"
    assert found.group(1) == make() + "\n", f"stale: python docs/tables.py --write {name}"


def test_a_changed_number_is_caught(tmp_path, monkeypatch):
    tables = load()
    made = tables.env_throughput()
    typed = made.replace("| faucet | ", "| faucet | 1", 1)  # one figure typed over
    assert typed != made
    doc = tmp_path / "doc.md"
    doc.write_text(f"text\n<!-- env-throughput -->\n{typed}\n<!-- /env-throughput -->\nmore text\n")
    monkeypatch.setattr(tables, "TABLES", {"env-throughput": (doc, tables.env_throughput)})
    assert tables.stale_tables() == ["env-throughput"]
    tables.write(tables.TABLES)  # --write restores it, the text around it untouched
    assert doc.read_text() == f"text\n<!-- env-throughput -->\n{made}\n<!-- /env-throughput -->\nmore text\n"
    assert tables.stale_tables() == []


def test_a_file_without_the_markers_is_refused_before_anything_is_written(tmp_path, monkeypatch):
    tables = load()
    doc, missing = tmp_path / "doc.md", tmp_path / "missing.md"
    doc.write_text("<!-- env-throughput -->\nold\n<!-- /env-throughput -->\n")
    missing.write_text("no markers\n")
    monkeypatch.setattr(tables, "TABLES", {"env-throughput": (doc, tables.env_throughput),
                                           "physics-speed": (missing, tables.physics_speed)})
    with pytest.raises(ValueError, match="no <!-- physics-speed -->"):
        tables.write(tables.TABLES)
    assert doc.read_text() == "<!-- env-throughput -->\nold\n<!-- /env-throughput -->\n"
    assert "physics-speed" in tables.stale_tables()


def test_every_table_in_the_docs_is_generated_or_declared_typed():
    """A results table added to docs/ by hand fails here until docs/tables.py generates it (or, if it holds no
    results, TYPED says why it stays typed)."""
    tables = load()
    loose, typed = [], set()
    for path in sorted((ROOT / "docs").rglob("*.md")):
        lines = path.read_text().splitlines()
        typed |= set(lines) & set(tables.TYPED)
        inside = None
        for k, line in enumerate(lines):
            marker = re.fullmatch(r"<!-- (/?)([\w-]+) -->", line)
            if marker:
                inside = None if marker.group(1) else marker.group(2)
            elif line.startswith("|") and not lines[k - 1].startswith("|") and inside is None and line not in tables.TYPED:
                loose.append(f"{path.relative_to(ROOT)}:{k + 1}: {line[:80]}")
    assert loose == []
    assert typed == set(tables.TYPED), "TYPED names a table that is no longer in docs/"


def test_the_command_refreshes_the_rl_tables_too():
    """``docs/tables.py --write`` covers benchmarks/rl/curriculum_table.py's tables as well, under their own names."""
    tables = load()
    every = tables.all_tables()
    curriculum = tables.curriculum_tables()
    assert set(curriculum) <= set(every) and set(tables.TABLES) <= set(every)
    assert {"rl-headline", "targets", "scaling"} <= set(curriculum)
