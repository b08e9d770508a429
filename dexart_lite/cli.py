"""The ``dexart-lite`` command line: one console script, one subcommand per job.

Each subcommand lives next to the code it runs, in a module that defines
``add_arguments(parser)`` and ``run(args) -> int``. Only the chosen module is imported, so
``dexart-lite objects list`` does not pay for importing torch.

Errors that come from bad input (``ValueError``, ``FileNotFoundError``, ...) are printed as one
readable line and exit with status 2; ``--traceback`` shows the full stack instead.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import sys
import types
import typing

# subcommand -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("dexart_lite.quickstart", "run the main job on defaults (what `make demo` runs)"),
    "objects": ("dexart_lite.objects.cli", "list, show, generate and compare the articulated objects"),
    "render": ("dexart_lite.render", "save a GIF of one episode"),
    "solve": ("dexart_lite.experts.solve", "run the scripted (privileged-state) solver on a task"),
    "train": ("dexart_lite.rl.train", "train a policy: point-cloud PPO, or SAC from demonstrations (--algo sac)"),
    "eval": ("dexart_lite.rl.evaluate", "evaluate a checkpoint on seen or unseen objects"),
    "data": ("dexart_lite.pretrain.data", "generate datasets: pretraining clouds (dam, objects) and expert demos"),
    "pretrain": ("dexart_lite.pretrain.train", "pretrain the PointNet encoder"),
    "distill": ("dexart_lite.imitation.distill",
                "distill a point-cloud student from the scripted expert (BC or DAgger)"),
    "study": ("dexart_lite.study", "re-measure a DexArt finding: arms x seeds of distilled students, resumable"),
}

# The exceptions that mean "the user asked for something that cannot be done".
USER_ERRORS = (ValueError, FileNotFoundError, KeyError, RuntimeError, OSError)


def add_config_arguments(parser, config_cls, *, names: list[str] | None = None, given_only: bool = False,
                         default_label: str = "default", overrides: bool = True, defaults: dict | None = None,
                         helps: dict | None = None, required: tuple[str, ...] = ()) -> None:
    """One ``--flag-name`` per field of the dataclass ``config_cls`` (or of its fields in ``names``), typed from
    its annotation (``int | None`` -> int; ``list[int]`` -> one or more ints), with the field's
    ``metadata["help"]`` (or ``helps[name]``), its ``metadata["choices"]`` and "(default_label: value)"; a
    ``metadata["min"]`` makes argparse refuse a smaller value, naming the flag; ``metadata["parse"]`` converts each
    value instead of the annotation's type (e.g. ``SEED=CHECKPOINT`` -> a pair); ``metadata["positional"]`` makes
    the field a positional argument (a list: one or more values);
    booleans get ``--flag`` / ``--no-flag``. ``defaults``: other defaults than the dataclass's, by field name.
    ``given_only``: every flag defaults to None, so that the caller can tell the flags given from the rest (a
    preset, or another config's defaults, then fills those in). ``required``: fields whose flag must be given.
    ``overrides``: also ``--set FIELD=VALUE ...``, the spelling the benchmark scripts and ``study`` take (a
    benchmark's ``--set`` can be pasted into a command), applied after the flags by ``config_from_args``."""
    if overrides:
        parser.add_argument("--set", dest="overrides", nargs="+", default=[], metavar="FIELD=VALUE",
                            help=f"more {config_cls.__name__} fields, typed like their defaults (after the flags)")
    hints, defaults, helps = typing.get_type_hints(config_cls), defaults or {}, helps or {}
    unknown = set(defaults) - {f.name for f in dataclasses.fields(config_cls)}
    if unknown:
        raise ValueError(f"{config_cls.__name__} has no field {sorted(unknown)} to give a default; its fields: "
                         f"{', '.join(f.name for f in dataclasses.fields(config_cls))}")
    for f in dataclasses.fields(config_cls):
        if names is not None and f.name not in names:
            continue
        flag = "--" + f.name.replace("_", "-")
        value = defaults.get(f.name, f.default if f.default is not dataclasses.MISSING else
                             f.default_factory() if f.default_factory is not dataclasses.MISSING else None)
        help_text = helps.get(f.name, f.metadata.get("help", "")) + \
            ("" if f.name in required or f.metadata.get("positional") else f" ({default_label}: {_shown(value)})")
        default = None if given_only else value
        choices = f.metadata.get("choices")
        need = {"required": True} if f.name in required else {}
        if hints[f.name] is bool:
            parser.add_argument(flag, action=argparse.BooleanOptionalAction, default=default, help=help_text, **need)
            continue
        hint = hints[f.name]
        kinds = ([k for k in typing.get_args(hint) if k is not type(None)]
                 if typing.get_origin(hint) in (typing.Union, types.UnionType) else [hint])
        many = typing.get_origin(kinds[0]) in (list, tuple)  # list[int], tuple[str, ...]: one or more values
        kind = f.metadata.get("parse") or (typing.get_args(kinds[0])[0] if many else kinds[0])
        if "min" in f.metadata:
            kind = _at_least(kind, f.metadata["min"])
        if f.metadata.get("positional"):  # always given on the command line (a list: one or more values)
            parser.add_argument(f.name, type=kind, help=help_text, choices=choices,
                                **({"nargs": "+"} if many else {}))
            continue
        parser.add_argument(flag, type=kind, default=default, help=help_text, choices=choices, **need,
                            **({"nargs": "+"} if many else {}))


def _at_least(kind, low):
    """An argparse ``type`` that converts with ``kind`` and refuses a value below ``low``: argparse then prints
    "argument --flag: must be >= low, got value" and exits with status 2."""
    def convert(text: str):
        value = kind(text)
        if value < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {value}")
        return value
    convert.__name__ = kind.__name__  # argparse names the type in "invalid int value: 'x'"
    return convert


def _shown(value) -> str:
    """A default as a command line would spell it: ``[0, 1]`` -> ``0 1``."""
    return " ".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)


def given_fields(config_cls, args: argparse.Namespace) -> dict:
    """The fields of ``config_cls`` that the command line sets: every flag not None, then ``--set`` pairs."""
    from dexart_lite.utils import parse_overrides

    fields = {f.name: getattr(args, f.name) for f in dataclasses.fields(config_cls)
              if getattr(args, f.name, None) is not None}
    return {**fields, **parse_overrides(getattr(args, "overrides", None) or [], config_cls)}


def config_from_args(config_cls, args: argparse.Namespace, preset=None):
    """The ``config_cls`` instance of the flags that ``add_config_arguments`` added and ``--set``; with ``preset``
    (a function of the given fields, e.g. a named preset), the fields not given come from it, else from the
    dataclass defaults."""
    given = given_fields(config_cls, args)
    return preset(**given) if preset is not None else config_cls(**given)


def _top_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dexart-lite", description=__doc__.splitlines()[0])
    parser.add_argument("--traceback", action="store_true", help="show the full traceback on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (_, help_text) in COMMANDS.items():
        sub.add_parser(name, help=help_text, add_help=False)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    show_traceback = "--traceback" in argv
    argv = [a for a in argv if a != "--traceback"]
    top = _top_parser()
    if not argv or argv[0] not in COMMANDS:
        top.parse_args(argv or ["--help"])  # prints help or "invalid choice" and exits
        return 2
    name, rest = argv[0], argv[1:]
    module = importlib.import_module(COMMANDS[name][0])
    parser = argparse.ArgumentParser(prog=f"dexart-lite {name}", description=COMMANDS[name][1])
    module.add_arguments(parser)
    args = parser.parse_args(rest)
    try:
        return int(module.run(args) or 0)
    except USER_ERRORS as err:
        if show_traceback:
            raise
        print(f"dexart-lite {name}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"dexart-lite {name}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
