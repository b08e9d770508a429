"""A non-editable install finds its assets: build the wheel, import from it, load a URDF."""

import subprocess
import sys
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

CHECK = """
import dexart_lite, dexart_lite.paths as paths
from dexart_lite.objects import list_objects
import pybullet
root = paths.urdf_dir()
assert str(root).startswith(SITE), (root, SITE)
assert dexart_lite.__file__.startswith(SITE), dexart_lite.__file__
client = pybullet.connect(pybullet.DIRECT)
for task in dexart_lite.TASKS:
    info = list_objects(task, "unseen")[0]
    assert str(info.urdf_path).startswith(SITE)
    pybullet.loadURDF(str(info.urdf_path), physicsClientId=client)
pybullet.loadURDF(str(paths.hand_urdf()), physicsClientId=client)
print("ok", root)
"""


def test_wheel_ships_the_urdf_assets(tmp_path):
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", str(REPO),
                    "-w", str(tmp_path / "dist")], check=True, cwd=tmp_path)
    wheel = next((tmp_path / "dist").glob("dexart_lite-*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    assert "dexart_lite/urdf/allegro_hand_right.urdf" in names
    assert sum(n.endswith("params.json") for n in names) == 82 + 17  # DexArt's splits + the toilets' wide split
    packages = {str(p.parent.relative_to(REPO)) for p in (REPO / "dexart_lite").rglob("__init__.py")}
    assert packages <= {str(Path(n).parent) for n in names}, "a subpackage is missing from setup.cfg"
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    out = subprocess.run([sys.executable, "-c", f"SITE = {str(site)!r}\n" + CHECK], cwd=tmp_path, check=True,
                         capture_output=True, text=True, env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"})
    assert out.stdout.strip().startswith("ok")


def test_no_pybullet_banner_in_the_output():
    """PyBullet's C module prints "pybullet build time: ..." at import, into every command's output.
    dexart_lite imports pybullet in one place (``sim``), quietly."""
    code = "import dexart_lite.envs, dexart_lite.objects.feasibility\nenv = dexart_lite.envs.make('laptop', num_points=16)\nprint('done')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO)
    assert out.stdout == "done\n", out.stdout
    assert "build time" not in out.stderr
    importers = [p.relative_to(REPO).as_posix() for p in (REPO / "dexart_lite").rglob("*.py")
                 if any(line.startswith(("import pybullet", "from pybullet")) for line in p.read_text().splitlines())]
    assert importers == ["dexart_lite/sim.py"], importers
