"""The results tables in the docs are generated from the committed JSON: a table typed or left stale fails here."""

import importlib.util
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parent.parent / "benchmarks" / "curriculum_table.py"


def load():
    spec = importlib.util.spec_from_file_location("curriculum_table", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_rl_tables_match_their_json():
    assert load().stale_tables() == [], "run: python benchmarks/curriculum_table.py --write"


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
