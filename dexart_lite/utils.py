"""Small helpers shared by scripts, tutorials and tests."""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import sys
import threading


def fast_mode() -> bool:
    """True when ``DEXART_LITE_FAST=1``: tutorials and scripts shrink their budgets for the test suite."""
    return os.environ.get("DEXART_LITE_FAST", "0") not in ("", "0", "false", "False")


def check_choice(kind: str, value, choices) -> None:
    """Raise ``ValueError`` naming ``value`` and the valid ``choices`` unless ``value`` is one of them."""
    choices = list(choices)
    if value not in choices:
        raise ValueError(f"unknown {kind} {value!r}; valid choices: {', '.join(map(str, choices))}")


def machine_info() -> dict:
    """What a benchmark ran on: CPU model, core count, Python and platform."""
    import os
    import platform

    cpu = "unknown"
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()}


def command_line(script: str, argv: list[str] | None = None) -> str:
    """How a benchmark was run, for its JSON: ``python <script> <args>`` (``argv`` None: this process's)."""
    return " ".join(["python", script, *(sys.argv[1:] if argv is None else argv)])


def provenance(script_file: str, argv: list[str] | None = None) -> dict:
    """What every benchmark JSON records about its run: ``command`` (``python benchmarks/<theme>/<script>.py
    <args>``, the path found from the script's ``__file__``), ``machine`` (``machine_info``) and ``fast_mode``
    (a smoke run, not evidence)."""
    from pathlib import Path

    path = Path(script_file).resolve()
    return {"command": command_line(path.relative_to(path.parents[2]).as_posix(), argv), "machine": machine_info(),
            "fast_mode": fast_mode()}


def save_figure(fig, path, dpi: int = 100):
    """A benchmark's PNG: ``fig`` laid out tightly, written to ``path`` (its folder made), and closed (pyplot
    keeps every open figure alive). Returns ``path``."""
    from pathlib import Path

    import matplotlib.pyplot as plt

    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def benchmark_results(script_file: str):
    """The folder a benchmark script (its ``__file__``, ``benchmarks/<theme>/<script>.py``) writes its results
    to: ``benchmarks/results/<theme>``."""
    from pathlib import Path

    path = Path(script_file).resolve()
    return path.parents[1] / "results" / path.parent.name


def sibling_script(script_file: str, name: str):
    """The script ``<name>.py`` beside ``script_file`` (a benchmark's ``__file__``), or else the benchmarks' shared
    module one folder up (``benchmarks/_harness.py``), as a module: benchmarks are scripts, not a package, so one
    that builds on another loads it by path."""
    import importlib.util
    from pathlib import Path

    path = Path(script_file).resolve().with_name(f"{name}.py")
    if not path.is_file() and path.parent.with_name(f"{name}.py").is_file():
        path = path.parent.with_name(f"{name}.py")
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # where @dataclass and pickle look a module up
    spec.loader.exec_module(module)
    return module


def resident_mb() -> float:
    """This process's resident memory now (MB), from ``/proc/self/statm``; NaN where there is none (not Linux)."""
    try:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[1])
    except (OSError, ValueError, IndexError):
        return float("nan")
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def release_freed_memory() -> None:
    """Hand the heap's free pages back to the OS (glibc's ``malloc_trim(0)``); nothing where libc has no such call.

    Why: a PPO update on point clouds allocates and frees hundreds of MB per batch (activations of ~4,000 clouds
    through the PointNet, several epochs), and glibc keeps the freed pages in its arenas instead of returning them.
    Without it a faucet run's resident memory grew to 7-8 GB per process in 100 minutes, and a run from random
    weights by ~780 MB per batch; ``benchmarks/perf/bench_train_memory.py`` measures both ways."""
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


@functools.cache
def _malloc_trim():
    """glibc's ``malloc_trim``, looked up once per process (``find_library`` runs ``ldconfig``); None off glibc."""
    import ctypes
    import ctypes.util

    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
    except (OSError, AttributeError):  # not glibc (macOS, musl, Windows)
        return None


def write_json(path, obj) -> None:
    """Write ``obj`` as indented JSON to ``path``, creating its folder."""
    import json
    from pathlib import Path

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(obj, indent=2) + "\n")


def changed_settings(recorded: dict, cfg, paths=(), execution=()) -> list[str]:
    """The fields of the dataclass config ``cfg`` whose value differs from a run's recorded config (``asdict`` of
    one such as ``DistillConfig`` or ``PPOConfig``). A field added after the run was recorded counts as equal when
    ``cfg`` leaves it at its default, which is what the run did: runs keep being read back and resumed when the
    config gains an option. Fields in ``paths`` are compared as resolved paths (runs/x and /abs/runs/x are one
    folder); fields in ``execution`` (how a run executes, not what it learns: torch threads, the progress bar) are
    not compared."""
    from dataclasses import asdict
    from pathlib import Path

    def value(key, v):
        return str(Path(v).resolve()) if key in paths and isinstance(v, str) else v

    settings, defaults = asdict(cfg), asdict(type(cfg)())
    return [k for k, v in settings.items()
            if k not in execution and value(k, recorded.get(k, defaults[k])) != value(k, v)]


def same_settings(recorded: dict, cfg, paths=(), execution=()) -> bool:
    """Whether a finished run's recorded config is ``cfg`` (``changed_settings``); a recorded field ``cfg`` no longer
    has makes it another run."""
    from dataclasses import asdict

    return set(recorded) <= set(asdict(cfg)) and not changed_settings(recorded, cfg, paths, execution)


def parse_overrides(pairs: list[str], config_class) -> dict:
    """``["rounds=8", "drop_state=palm_velocity"]`` -> fields of the dataclass ``config_class``, typed like
    their defaults (a field whose default is None gets a number if the value reads as one)."""
    from dataclasses import fields

    defaults = {f.name: f.default for f in fields(config_class)}
    out = {}
    for pair in pairs:
        name, sep, value = pair.partition("=")
        if not sep:
            raise ValueError(f"--set takes FIELD=VALUE, got {pair!r}")
        check_choice(f"{config_class.__name__} field", name, defaults)
        default = defaults[name]
        if isinstance(default, bool):
            out[name] = value.lower() in ("1", "true", "yes")
        elif isinstance(default, (int, float, str)):
            out[name] = type(default)(value)
        else:
            out[name] = next((kind(value) for kind in (int, float) if _parses(kind, value)), value)
    return out


def _parses(kind, value: str) -> bool:
    try:
        kind(value)
    except ValueError:
        return False
    return True


DEVICES = ("cpu", "cuda", "auto")


def resolve_device(name: str, log=None):
    """``--device``: the ``torch.device`` the networks, losses and optimizers live on. ``cuda`` on a machine
    without CUDA is an error, never a silent fallback; ``auto`` takes cuda where it exists, else cpu, and says
    which through ``log`` (default: stderr). Collection always runs on the CPU."""
    import torch

    check_choice("device", name, DEVICES)
    has_cuda = torch.cuda.is_available()
    if name == "cuda" and not has_cuda:
        raise ValueError("--device cuda: this machine has no CUDA device (torch.cuda.is_available() is False); "
                         "use --device cpu, or --device auto to take cuda only where there is one")
    chosen = torch.device("cuda" if name == "cuda" or (name == "auto" and has_cuda) else "cpu")
    if name == "auto":
        (log or (lambda line: print(line, file=sys.stderr)))(
            f"--device auto: using {chosen.type}" + ("" if has_cuda else " (no CUDA device)"))
    return chosen


def to_cpu(state):
    """A copy of ``state`` (a state dict, or nested dicts / lists of tensors) with every tensor on the CPU: what
    a checkpoint saves, so that it loads on any machine."""
    import torch

    if isinstance(state, torch.Tensor):
        return state.cpu()
    if isinstance(state, dict):
        return type(state)((k, to_cpu(v)) for k, v in state.items())
    if isinstance(state, (list, tuple)):
        return type(state)(to_cpu(v) for v in state)
    return state


def optimizer_to(optimizer, device) -> None:
    """Move an optimizer's state (Adam's moments) to ``device``, after its parameters moved there (a resumed run
    loads the state on the CPU first). Adam's ``step`` counters stay on the CPU, where torch keeps them."""
    import torch

    for state in optimizer.state.values():
        for key, value in state.items():
            if torch.is_tensor(value) and key != "step":
                state[key] = value.to(device)


@contextlib.contextmanager
def sigterm_interrupts():
    """In a launcher's main process (a study, ``curriculum_runs.py``): while the runs go, SIGTERM (``kill``,
    ``timeout``, a job scheduler) raises ``KeyboardInterrupt``, as Ctrl-C does, so that ``process_pool`` stops its
    workers instead of leaving them to finish their runs unwatched (``kill`` reaches the launcher alone, where
    Ctrl-C reaches its whole process group). Only the main thread may set a handler;
    elsewhere a no-op."""

    def interrupt(signum, frame):
        raise KeyboardInterrupt(f"signal {signum}")

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _exit_on_sigterm() -> None:
    """In a worker process (the pool's initializer): SIGTERM terminates the worker's own children (the
    pool of a viewpoint evaluation), then ends the worker at once, without a traceback."""
    import multiprocessing

    def stop(signum, frame):
        for child in multiprocessing.active_children():
            child.terminate()
        os._exit(128 + signum)

    signal.signal(signal.SIGTERM, stop)


@contextlib.contextmanager
def process_pool(workers: int):
    """A ``ProcessPoolExecutor`` of ``workers`` spawned processes that, when the body raises (an error,
    Ctrl-C, SIGTERM), drops the queued calls and terminates the running ones: a stopped launcher leaves no
    process behind. A terminated worker terminates its own children first (``_exit_on_sigterm``). A launcher
    wraps it in ``sigterm_interrupts`` for ``kill`` to count; the pool does not, because it also runs inside workers
    (a viewpoint evaluation), where SIGTERM must end the process, not raise."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"), initializer=_exit_on_sigterm)
    try:
        yield pool
    except BaseException:
        processes = list((pool._processes or {}).values())  # private; Python 3.14 has pool.terminate_workers()
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()
        for process in processes:
            process.join(timeout=30)
        raise
    pool.shutdown()
