"""Where dexart_lite's files live. This is the only module that knows.

* ``urdf_dir()``: the committed robot and object assets (``urdf/`` in the repository). A
  non-editable install ships them inside the package as ``dexart_lite/urdf`` (see ``setup.cfg``);
  in a source checkout or an editable install they sit next to the package.
* ``cache_dir()``: files generated at run time (the composed arm + hand URDF). Override with the
  environment variable ``DEXART_LITE_CACHE``; the default is ``~/.cache/dexart_lite``.

Set ``DEXART_LITE_URDF`` to point at another asset folder (for example a regenerated object set).
"""

from __future__ import annotations

import os
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def urdf_dir() -> Path:
    """The folder holding ``allegro_hand_right.urdf`` and ``objects/``."""
    override = os.environ.get("DEXART_LITE_URDF")
    candidates = [Path(override)] if override else [_PACKAGE / "urdf", _PACKAGE.parent / "urdf"]
    for path in candidates:
        if (path / "allegro_hand_right.urdf").is_file():
            return path
    raise FileNotFoundError(
        "dexart_lite assets not found; looked in " + ", ".join(str(p) for p in candidates)
        + ". Reinstall the package or set DEXART_LITE_URDF."
    )


def objects_dir() -> Path:
    """The committed articulated objects: ``objects/<category>/<split>/<name>/``."""
    return urdf_dir() / "objects"


def hand_urdf() -> Path:
    """The primitive-geometry right Allegro hand."""
    return urdf_dir() / "allegro_hand_right.urdf"


def cache_dir() -> Path:
    """A writable folder for generated files, created on first use."""
    path = Path(os.environ.get("DEXART_LITE_CACHE", Path.home() / ".cache" / "dexart_lite"))
    path.mkdir(parents=True, exist_ok=True)
    return path
