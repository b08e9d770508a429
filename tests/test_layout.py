"""The package's layering: no import circle between its modules, counting imports inside functions
(which hide a circle from Python but not from a reader)."""

import ast
import json
import re
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "dexart_lite"


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(package: Path = PACKAGE) -> dict[str, set[str]]:
    """module -> the package modules it imports anywhere in its source (top level or in functions)."""
    files = {module_name(p): p for p in package.rglob("*.py")}
    graph = {}
    for name, path in files.items():
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                deps.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                parts = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
                base = ".".join(parts[:len(parts) - node.level + 1] + [node.module or ""]).strip(".") \
                    if node.level else node.module
                deps.add(base)
                deps.update(f"{base}.{alias.name}" for alias in node.names)  # "from pkg import module"
        graph[name] = {d for d in deps if d in files and d != name}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_the_cycle_finder_finds_a_circle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_the_graph_sees_function_level_imports():
    graph = import_graph()
    # render imports the env maker inside run(); evaluate imports the checkpoint helpers at the top
    assert "dexart_lite.envs" in graph["dexart_lite.render"]
    assert "dexart_lite.rl.checkpoint" in graph["dexart_lite.rl.evaluate"]


def test_no_import_circle_in_the_package():
    assert cycles(import_graph()) == []


# The sealed simulator: the PyBullet client lives behind BulletSim (sim.py), which alone imports pybullet and opens
# a BulletClient; an env is read through its public view (``env.state``, ``read_state``, ``evaluate_state``), its
# underscore attributes stay inside envs/.
CLIENT = re.compile(r"\bsim\.c\b|\bsim\.client\b|\bself\.c\.\w+\(|\bBulletClient\b|\bimport pybullet\b|\bpybullet\.[a-zA-Z]")
ENV_PRIVATE = re.compile(r"\b(env|unwrapped|self\.env)\._[a-z]\w*")


def sealing_breaches(root: Path) -> list[str]:
    """``file:line`` of each use of the client outside sim.py and of an env's underscore attribute outside envs/."""
    found = []
    for folder in ("dexart_lite", "benchmarks"):
        for path in sorted((root / folder).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            for number, line in enumerate(path.read_text().splitlines(), 1):
                if rel != "dexart_lite/sim.py" and CLIENT.search(line):
                    found.append(f"{rel}:{number}: {line.strip()}")
                if not rel.startswith("dexart_lite/envs/") and ENV_PRIVATE.search(line):
                    found.append(f"{rel}:{number}: {line.strip()}")
    return found


def test_only_sim_py_touches_the_client_and_nothing_reads_an_env_s_privates():
    assert sealing_breaches(PACKAGE.parent) == []


def test_the_sealing_check_finds_a_breach(tmp_path):
    (tmp_path / "dexart_lite").mkdir()
    (tmp_path / "benchmarks").mkdir()
    (tmp_path / "dexart_lite" / "sim.py").write_text("self.c.stepSimulation()\n")  # its own client: fine
    (tmp_path / "dexart_lite" / "robot.py").write_text("x = self.sim.c.getJointInfo(1, 2)\n")
    (tmp_path / "benchmarks" / "probe.py").write_text("s = env.unwrapped._state\nq = env._t\n")
    # a module with a world of its own (what objects/feasibility.py had before it used BulletSim)
    (tmp_path / "dexart_lite" / "checks.py").write_text("c = BulletClient(connection_mode=pybullet.DIRECT)\n")
    assert [b.split(":")[0] + ":" + b.split(":")[1] for b in sealing_breaches(tmp_path)] == [
        "dexart_lite/checks.py:1", "dexart_lite/robot.py:1", "benchmarks/probe.py:1", "benchmarks/probe.py:2"]


def test_benchmarks_live_in_theme_folders_and_record_their_provenance():
    """Every benchmark script sits in ``benchmarks/<theme>/`` beside a ``benchmarks/results/<theme>/`` folder,
    finds it through ``utils.benchmark_results`` (no hand-built results path) and names itself in its JSON
    through ``utils.provenance`` (no hand-typed script path that a move would leave stale)."""
    from dexart_lite.utils import benchmark_results, provenance

    bench = PACKAGE.parent / "benchmarks"
    assert sorted(p.name for p in bench.glob("*.py")) == ["_harness.py"]  # no script outside a theme, one shared module
    scripts = sorted(bench.glob("*/*.py"))
    themes = {p.parent.name for p in scripts}
    assert themes == {"perf", "experts", "students", "rl", "pretraining"}
    assert all((bench / "results" / theme).is_dir() for theme in themes)
    for path in scripts:
        text = path.read_text()
        assert 'Path(__file__).parent / "results"' not in text and 'command_line("benchmarks/' not in text, path.name
    script = bench / "perf" / "bench_sim.py"
    assert benchmark_results(str(script)) == bench / "results" / "perf"
    record = provenance(str(script), ["--task", "laptop"])
    assert record["command"] == "python benchmarks/perf/bench_sim.py --task laptop"
    assert set(record) == {"command", "machine", "fast_mode"} and record["machine"]["cores"] >= 1


def test_benchmark_runner_resumes_rows_of_the_same_settings(tmp_path, load_benchmark):
    """``_harness.run_grid``, the benchmarks' one experiment runner: rows come back in the grid's order, each its
    parameters plus the job's result; the JSON written after every row is read back by a later call with the
    same settings (only the missing rows run) and ignored under other settings (every row runs again)."""
    harness = load_benchmark("_harness")
    calls = []

    def job(seed, x):
        calls.append((seed, x))
        return {"y": 10 * seed + x}

    path, grid = tmp_path / "grid.json", [{"seed": s, "x": x} for s in (0, 1) for x in (1, 2)]
    rows = harness.run_grid(job, grid, path=path, settings={"episodes": 3}, summarise=lambda done: {"n": len(done)})
    assert rows == [{**p, "y": 10 * p["seed"] + p["x"]} for p in grid] and calls == [(0, 1), (0, 2), (1, 1), (1, 2)]
    written = json.loads(path.read_text())
    assert (written["n"], written["rows"], written["settings"]) == (4, rows, {"episodes": 3})
    calls.clear()
    more = harness.run_grid(job, [*grid, {"seed": 2, "x": 1}], path=path, settings={"episodes": 3})
    assert calls == [(2, 1)] and more[:4] == rows and more[4]["y"] == 21
    calls.clear()
    harness.run_grid(job, grid, path=path, settings={"episodes": 5})
    assert calls == [(0, 1), (0, 2), (1, 1), (1, 2)]
    # two at once, in spawned workers: the rows still come back in the grid's order
    assert list(harness.each(dict, [{"seed": s} for s in range(3)], jobs=2)) == [{"seed": s} for s in range(3)]


def test_benchmark_options_share_one_meaning(load_benchmark):
    """``_harness.options``: the shared flags, typed from ``Options`` (lists take several values), with a script's
    own defaults; a task outside the package's is refused by argparse, naming the choices."""
    import argparse

    harness = load_benchmark("_harness")
    parser = argparse.ArgumentParser()
    harness.options(parser, "task", "jobs", seeds=[0], json=Path("x.json"))
    args = parser.parse_args(["--seeds", "3", "4", "--jobs", "2"])
    assert (args.task, args.seeds, args.jobs, args.json) == ("laptop", [3, 4], 2, Path("x.json"))
    assert parser.parse_args([]).seeds == [0]
    with pytest.raises(SystemExit):
        parser.parse_args(["--task", "kettle"])
    with pytest.raises(ValueError, match=r"Options has no field \['sede'\].*its fields: task, tasks"):
        harness.options(argparse.ArgumentParser(), sede=1)
