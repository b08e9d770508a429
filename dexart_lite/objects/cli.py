"""``dexart-lite objects ...``: list, show, generate and compare the articulated objects.

Subcommands:

* ``list [--category C] [--split S] [--json]``: every object with its template and key dimensions.
* ``show NAME --out PNG``: one object rendered at a few joint angles.
* ``generate [--out DIR] [--category C]``: rebuild the object set (default: ``urdf/objects`` in place;
  existing objects are kept, new ones written, stale ones removed), plus checks.json and README.md.
* ``split-report``: distance from each unseen object to its nearest seen object.
* ``montage --out-dir DIR``: one PNG per category with every object.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from dexart_lite import objects
from dexart_lite.utils import check_choice


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)

    p = sub.add_parser("list", help="print every object with its template and key dimensions")
    p.add_argument("--category", help=f"one of {', '.join(objects.CATEGORIES)}")
    p.add_argument("--split", help=f"one of {', '.join(objects.SPLITS)}")
    p.add_argument("--json", action="store_true", help="print a JSON list instead of a table")

    p = sub.add_parser("show", help="render one object at a few joint angles")
    p.add_argument("name", help="object name, e.g. laptop_0123456789 (see `objects list`)")
    p.add_argument("--out", required=True, type=Path, help="PNG file to write")

    p = sub.add_parser("generate", help="rebuild the object set (keeps existing objects, removes stale ones)")
    p.add_argument("--out", type=Path, help="object root to write (default: the package's urdf/objects)")
    p.add_argument("--category", action="append", help="only this category (repeatable; default: all)")

    sub.add_parser("split-report", help="distance from each unseen object to its nearest seen object")

    p = sub.add_parser("montage", help="write montage_<category>.png with every object of each category")
    p.add_argument("--out-dir", required=True, type=Path, help="folder for the PNGs")


def _selected(category: str | None, split: str | None) -> list[objects.ObjectInfo]:
    if category is not None:
        check_choice("category", category, objects.CATEGORIES)
    if split is not None:
        check_choice("split", split, objects.SPLITS)
    out = []
    for c in objects.CATEGORIES if category is None else (category,):
        for s in objects.FOLDERS if split is None else (split,):
            out += objects.list_objects(c, s)
    return out


def _summary(info: objects.ObjectInfo) -> dict:
    from dexart_lite.objects.generate import CATEGORY_SPECS

    keys = CATEGORY_SPECS[info.category].summary_keys
    return {"category": info.category, "split": info.split, "index": info.index, "name": info.name,
            "template": info.template, "dimensions": {k: info.params[k] for k in keys},
            "joint": {"name": info.joint_name, "lower": info.joint_lower, "upper": info.joint_upper,
                      "init": info.joint_init, "target": info.joint_target, "friction": info.joint_friction},
            "fixed_base": info.fixed_base, "position": list(info.position), "urdf": str(info.urdf_path)}


def _list(args) -> int:
    infos = _selected(args.category, args.split)
    if args.json:
        print(json.dumps([_summary(i) for i in infos], indent=1))
        return 0
    print(f"{'category':8s} {'split':6s} {'#':>2s} {'tmpl':4s} {'name':18s} {'key dimensions'}")
    for info in infos:
        dims = "  ".join(f"{k}={v:g}" for k, v in _summary(info)["dimensions"].items())
        print(f"{info.category:8s} {info.split:6s} {info.index:2d} {info.template:4s} {info.name:18s} {dims}")
    print(f"{len(infos)} objects")
    return 0


def _generate(args) -> int:
    from dexart_lite import paths
    from dexart_lite.objects import generate, readme

    categories = tuple(args.category or objects.CATEGORIES)
    for c in categories:
        check_choice("category", c, objects.CATEGORIES)
    root = args.out if args.out is not None else paths.objects_dir()
    if root.exists() and not root.is_dir():
        raise ValueError(f"{root} is not a folder")
    unexpected = [p.name for p in root.iterdir() if p.name not in
                  set(objects.CATEGORIES) | {"README.md", generate.CHECKS_FILE} and not p.name.startswith("montage_")
                  ] if root.is_dir() else []
    if unexpected:
        raise ValueError(f"{root} holds files that are not part of an object set ({', '.join(sorted(unexpected))}); "
                         "pick an empty folder or an existing object root")
    root.mkdir(parents=True, exist_ok=True)
    generate.generate(root, categories)
    objects._catalog.cache_clear()
    if set(categories) == set(objects.CATEGORIES) or (root / "README.md").exists():
        try:
            (root / "README.md").write_text(readme.readme_text(root))
            print(f"wrote {root / 'README.md'}")
        except RuntimeError as err:  # partial set (e.g. --category into an empty folder): no README
            print(f"README not written: {err}")
    return 0


def _split_report(args) -> int:
    from dexart_lite.objects import report

    for c in objects.CATEGORIES:
        print(report.category_report(c, objects.list_objects(c, "seen"), objects.list_objects(c, "unseen")).text())
        print()
    return 0


def _montage(args) -> int:
    from dexart_lite.objects import pictures

    for c in objects.CATEGORIES:
        out = args.out_dir / f"montage_{c}.png"
        infos = [info for split in objects.FOLDERS for info in objects.list_objects(c, split)]
        pictures.montage(c, infos, out)
        print(f"wrote {out}")
    return 0


def _show(args) -> int:
    from dexart_lite.objects import pictures

    angles = pictures.show(objects.get_object(args.name), args.out)
    print(f"wrote {args.out} (q = {', '.join(f'{q:.2f}' for q in angles)} rad)")
    return 0


def run(args) -> int:
    return {"list": _list, "show": _show, "generate": _generate, "split-report": _split_report,
            "montage": _montage}[args.action](args)
