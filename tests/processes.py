"""The process tree, read from /proc (Linux): for the tests that stop a launcher and check that no worker
outlives it."""

from __future__ import annotations

from pathlib import Path


def living_processes() -> dict[int, int]:
    """``{pid: parent pid}`` of every living process (Linux, from /proc/<pid>/stat; a zombie counts as gone)."""
    parents = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            state, ppid = stat.read_text().rsplit(")", 1)[1].split()[:2]  # after "pid (command)"
        except OSError:  # the process ended while we looked
            continue
        if state != "Z":
            parents[int(stat.parent.name)] = int(ppid)
    return parents


def descendants(pid: int) -> set[int]:
    """The pids of every living process below ``pid`` (children, their children, ...)."""
    parents, found, frontier = living_processes(), set(), {pid}
    while frontier:
        frontier = {child for child, parent in parents.items() if parent in frontier} - found
        found |= frontier
    return found


def wait_until_gone(pids: set[int], what: str, timeout: float = 30.0) -> None:
    """Fail unless every process of ``pids`` has ended within ``timeout`` seconds (``what`` names them)."""
    import time

    deadline = time.monotonic() + timeout
    while pids & set(living_processes()):
        assert time.monotonic() < deadline, f"{what} outlived their launcher"
        time.sleep(0.2)


def kill_all(pids: set[int]) -> None:
    """SIGKILL each of ``pids`` that still lives (a test's clean-up, whatever it found)."""
    import os
    import signal

    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def kill_once_started(command: list[str], started, what: str, stderr: Path, env: dict | None = None,
                      timeout: float = 300.0) -> int:
    """Start ``command`` (its stderr to the file ``stderr``: a pipe would be held open by a leftover), wait until
    ``started(pid)`` holds for its pid (spawned workers import torch first: up to ``timeout`` s), send it SIGTERM as ``kill`` does,
    and return its exit status once every process that was below it (``what`` names them, at least two) has ended
    too. Whatever still lives at the end, pass or fail, is killed."""
    import signal
    import subprocess
    import time

    workers: set[int] = set()
    with stderr.open("w") as err:
        main = subprocess.Popen(command, env=env, stderr=err)
    try:
        deadline = time.monotonic() + timeout
        while not started(main.pid):
            assert main.poll() is None and time.monotonic() < deadline, f"the {what} did not start"
            time.sleep(0.2)
        workers = descendants(main.pid)
        assert len(workers) >= 2
        main.send_signal(signal.SIGTERM)
        status = main.wait(timeout=60)
        wait_until_gone(workers, what)
        return status
    finally:
        kill_all(workers | descendants(main.pid) | {main.pid})
