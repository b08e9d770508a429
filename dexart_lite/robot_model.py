"""The robot's URDF: a primitive-geometry Allegro right hand bolted onto pybullet_data's XArm6.

* ``hand_urdf_text()`` writes the right Allegro hand from the public kinematic table (Allegro v3/v4
  xacro; see ``urdf/README.md``) with boxes and tip spheres, DexArt's link names and an
  ``<inertial>`` on every link (PyBullet would give a missing one 1 kg). The result is committed as
  ``urdf/allegro_hand_right.urdf``; ``python -m dexart_lite.robot_model`` regenerates it.
* ``composed_urdf()`` joins the arm and the hand with DexArt's mount (``link6`` -> ``base_link``,
  xyz 0 0.045 0.045, rpy 0 -1.57 -1.57) into one URDF in the cache folder. The arm's meshes stay in
  ``pybullet_data`` (referenced by absolute path, never copied). Its visuals are replaced by
  simplified collision hulls (the renderer's cost follows the triangle count) and its
  ``<dynamics damping>`` is stripped (PyBullet's explicit joint damping is unstable at these gains).

Units: metres, radians, kilograms.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import numpy as np

from dexart_lite import paths

DEG = np.pi / 180

# Mount of the hand on the arm flange, as in DexArt's xarm6_allegro_wrist_mounted_rotate.urdf.
MOUNT_XYZ = (0.0, 0.045, 0.045)
MOUNT_RPY = (0.0, -1.57, -1.57)

# Finger chains (index, middle, ring): name offset k, base joint origin in base_link, roll of the
# abduction frame.
FINGERS = ((0, (0.0, 0.0435, -0.001542), -5 * DEG), (4, (0.0, 0.0, 0.0007), 0.0), (8, (0.0, -0.0435, -0.001542), 5 * DEG))
FINGER_LENGTHS = (0.0164, 0.0540, 0.0384, 0.0267)  # base, proximal, medial, distal-to-tip-centre
FINGER_MASSES = (0.0119, 0.065, 0.0355, 0.0096)
FINGER_LIMITS = ((-0.47, 0.47), (-0.196, 1.61), (-0.174, 1.709), (-0.227, 1.618))
THUMB_ORIGIN, THUMB_RPY = (-0.0182, 0.019333, -0.045987), (0.0, -95 * DEG, -90 * DEG)
THUMB_J13_ORIGIN = (-0.027, 0.005, 0.0399)
THUMB_LENGTHS = (0.0177, 0.0514, 0.0423)  # link_13, link_14, link_15 (to the tip centre)
THUMB_MASSES = (0.0176, 0.0119, 0.038, 0.0388)  # link_12 .. link_15
THUMB_LIMITS = ((0.263, 1.396), (-0.105, 1.163), (-0.189, 1.644), (-0.162, 1.719))
LINK_SECTION = (0.0196, 0.0275)  # finger link cross-section x, y
PALM_SIZE, PALM_CENTRE, PALM_MASS = (0.0408, 0.1130, 0.095), (-0.0093, 0.0, -0.0475), 0.4154
TIP_RADIUS, TIP_MASS = 0.012, 0.0168
HAND_EFFORT, HAND_VELOCITY = 10.0, 3.14  # N*m, rad/s (the SAPIEN drive limit DexArt uses)

DARK, LIGHT = "0.2 0.2 0.2 1", "0.9 0.9 0.9 1"


def _f(x: float) -> str:
    """Fixed float formatting, so that regenerating the URDF is byte-for-byte reproducible."""
    return f"{float(x):.6g}"


def _vec(v) -> str:
    return " ".join(_f(x) for x in v)


def _inertial(mass: float, size, centre=(0.0, 0.0, 0.0)) -> str:
    """Solid-box inertia about the centre of mass (kg*m^2)."""
    sx, sy, sz = size
    ixx, iyy, izz = mass * (sy**2 + sz**2) / 12, mass * (sx**2 + sz**2) / 12, mass * (sx**2 + sy**2) / 12
    return (
        f'<inertial><origin xyz="{_vec(centre)}"/><mass value="{_f(mass)}"/>'
        f'<inertia ixx="{ixx:.4e}" iyy="{iyy:.4e}" izz="{izz:.4e}" ixy="0" ixz="0" iyz="0"/></inertial>'
    )


def _box_link(name: str, size, centre, mass: float, rgba: str = DARK) -> str:
    geom = f'<origin xyz="{_vec(centre)}"/><geometry><box size="{_vec(size)}"/></geometry>'
    return (
        f'<link name="{name}">{_inertial(mass, size, centre)}'
        f'<visual>{geom}<material name="m_{name}"><color rgba="{rgba}"/></material></visual>'
        f"<collision>{geom}</collision></link>"
    )


def _tip_link(name: str) -> str:
    geom = f'<geometry><sphere radius="{_f(TIP_RADIUS)}"/></geometry>'
    size = (2 * TIP_RADIUS,) * 3
    return (
        f'<link name="{name}">{_inertial(TIP_MASS, size)}'
        f'<visual>{geom}<material name="m_{name}"><color rgba="{LIGHT}"/></material></visual>'
        f"<collision>{geom}</collision></link>"
    )


def _joint(name, parent, child, xyz, rpy=(0, 0, 0), axis=None, limit=None) -> str:
    kind = "fixed" if axis is None else "revolute"
    text = (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{_vec(xyz)}" rpy="{_vec(rpy)}"/>'
    )
    if axis is not None:
        text += (
            f'<axis xyz="{_vec(axis)}"/><limit lower="{_f(limit[0])}" upper="{_f(limit[1])}" '
            f'effort="{_f(HAND_EFFORT)}" velocity="{_f(HAND_VELOCITY)}"/>'
        )
    return text + "</joint>"


def hand_body_xml() -> str:
    """Links and joints of the right hand, rooted at ``base_link`` (no ``<robot>`` wrapper)."""
    wx, wy = LINK_SECTION
    out = [_box_link("base_link", PALM_SIZE, PALM_CENTRE, PALM_MASS)]
    for k, base_xyz, roll in FINGERS:
        names = [f"link_{k + i}.0" for i in range(4)]
        parents = ["base_link"] + names[:3]
        for i, (name, parent) in enumerate(zip(names, parents)):
            length = FINGER_LENGTHS[i]
            out.append(_box_link(name, (wx, wy, length), (0, 0, length / 2), FINGER_MASSES[i]))
            origin = base_xyz if i == 0 else (0, 0, FINGER_LENGTHS[i - 1])
            axis = (0, 0, 1) if i == 0 else (0, 1, 0)  # abduction about z, flexion about y
            out.append(_joint(f"joint_{k + i}.0", parent, name, origin, (roll if i == 0 else 0, 0, 0), axis, FINGER_LIMITS[i]))
        out.append(_tip_link(f"link_{k + 3}.0_tip"))
        out.append(_joint(f"joint_{k + 3}.0_tip", names[3], f"link_{k + 3}.0_tip", (0, 0, FINGER_LENGTHS[3])))
    # Thumb: rotation (axis -x) on the palm, then abduction (z), then two flexions (y).
    out.append(_box_link("link_12.0", (0.0358, 0.034, 0.0455), (-0.0179, 0.009, 0.0145), THUMB_MASSES[0]))
    out.append(_joint("joint_12.0", "base_link", "link_12.0", THUMB_ORIGIN, THUMB_RPY, (-1, 0, 0), THUMB_LIMITS[0]))
    chain = (("link_13.0", "link_12.0", THUMB_J13_ORIGIN, (0, 0, 1)),
             ("link_14.0", "link_13.0", (0, 0, THUMB_LENGTHS[0]), (0, 1, 0)),
             ("link_15.0", "link_14.0", (0, 0, THUMB_LENGTHS[1]), (0, 1, 0)))
    for i, (name, parent, origin, axis) in enumerate(chain):
        length = THUMB_LENGTHS[i]
        out.append(_box_link(name, (wx, wy, length), (0, 0, length / 2), THUMB_MASSES[i + 1]))
        out.append(_joint(f"joint_{13 + i}.0", parent, name, origin, axis=axis, limit=THUMB_LIMITS[i + 1]))
    out.append(_tip_link("link_15.0_tip"))
    out.append(_joint("joint_15.0_tip", "link_15.0", "link_15.0_tip", (0, 0, THUMB_LENGTHS[2])))
    # palm_center: a frame-only link 3 cm down the palm (DexArt's `palm_name`), with a tiny inertial.
    out.append(
        '<link name="palm_center"><inertial><mass value="0.001"/>'
        '<inertia ixx="1e-08" iyy="1e-08" izz="1e-08" ixy="0" ixz="0" iyz="0"/></inertial></link>'
    )
    out.append(_joint("palm_center_joint", "base_link", "palm_center", (0, 0, -0.03)))
    return "\n".join(out)


def hand_urdf_text() -> str:
    """The standalone hand URDF, as committed in ``urdf/allegro_hand_right.urdf``."""
    return (
        '<?xml version="1.0"?>\n<!-- Generated by `python -m dexart_lite.robot_model`; do not edit. -->\n'
        f'<robot name="allegro_hand_right">\n{hand_body_xml()}\n</robot>\n'
    )


def _obj_pieces(path: Path) -> list[np.ndarray]:
    """Vertex arrays of the ``o`` blocks of a multi-object OBJ (trimesh would merge them)."""
    vertices, blocks = [], [[]]
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            vertices.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("o ") and blocks[-1]:
            blocks.append([])
        elif line.startswith("f "):
            blocks[-1] += [int(token.split("/")[0]) - 1 for token in line.split()[1:]]
    vertices = np.asarray(vertices)
    return [vertices[np.unique(block)] for block in blocks if block]


def _farthest_points(points: np.ndarray, k: int) -> np.ndarray:
    """``k`` of ``points`` spread out by greedy farthest-point selection (deterministic)."""
    chosen, dist = [0], np.linalg.norm(points - points[0], axis=1)
    for _ in range(min(k, len(points)) - 1):
        chosen.append(int(np.argmax(dist)))
        dist = np.minimum(dist, np.linalg.norm(points - points[chosen[-1]], axis=1))
    return points[chosen]


ARM_VISUAL_VERTICES = 32  # per convex piece of the arm's simplified visual hulls


def simplified_arm_visual(collision_obj: Path) -> Path:
    """A low-poly visual mesh for one arm link, written to the cache folder.

    Each convex piece of the link's V-HACD collision OBJ is replaced by the hull of 32 of its
    vertices (farthest-point selection): 1,226 triangles for the arm instead of 2,396, at a median
    deviation of 4.5 mm (10.6 mm at worst). TinyRenderer's time follows the triangle count (the
    full hulls cost about 0.8 ms of a 1.1 ms frame), while collisions keep the full hulls.
    """
    import trimesh  # local import: only asset generation needs it

    hulls = [trimesh.convex.convex_hull(_farthest_points(v, ARM_VISUAL_VERTICES)) for v in _obj_pieces(collision_obj)]
    mesh = trimesh.util.concatenate(hulls)
    text = trimesh.exchange.obj.export_obj(mesh, include_normals=False, include_texture=False)
    digest = hashlib.sha1((collision_obj.read_text() + str(ARM_VISUAL_VERTICES)).encode()).hexdigest()[:10]
    path = paths.cache_dir() / f"{collision_obj.stem}_visual_{digest}.obj"
    _write_atomic(path, text)
    return path


def _write_atomic(path: Path, text: str) -> None:
    """Write once; parallel workers may race to create the same cached file."""
    if not path.exists():
        tmp = path.with_suffix(f".tmp{np.random.default_rng().integers(1 << 30)}")
        tmp.write_text(text)
        tmp.replace(path)


def _arm_body_xml() -> str:
    """pybullet_data's xarm6 URDF without its closing tag, with absolute mesh paths.

    Visuals: the 52k-triangle STLs would cost ~9 ms per rendered frame; they are replaced by
    simplified collision hulls (``simplified_arm_visual``).
    """
    import pybullet_data  # local import: only this function needs the data path

    data = Path(pybullet_data.getDataPath()) / "xarm"
    text = (data / "xarm6_robot.urdf").read_text()
    text = text.replace("package://xarm_description", str(data / "xarm_description"))
    text = re.sub(r"<gazebo.*?</gazebo>", "", text, flags=re.S)
    text = re.sub(r"<transmission.*?</transmission>", "", text, flags=re.S)
    text = re.sub(r"<dynamics[^>]*/>", "", text)
    collision = data / "xarm_description" / "meshes" / "xarm6" / "collision"
    text = re.sub(r"[^\"]*meshes/xarm6/visual/(\w+)\.stl",
                  lambda m: str(simplified_arm_visual(collision / f"{m.group(1)}_vhacd.obj")), text)
    return text.replace("</robot>", "")


def composed_urdf_text() -> str:
    """Arm + hand in one URDF string."""
    mount = (
        '<joint name="hand_mount" type="fixed"><parent link="link6"/><child link="base_link"/>'
        f'<origin xyz="{_vec(MOUNT_XYZ)}" rpy="{_vec(MOUNT_RPY)}"/></joint>'
    )
    hand = paths.hand_urdf().read_text()
    hand_body = hand[hand.index("<link") : hand.rindex("</robot>")]
    return _arm_body_xml() + mount + "\n" + hand_body + "</robot>\n"


def composed_urdf() -> Path:
    """Write the arm + hand URDF into the cache folder (named by a hash of its text) and return it.

    The hash in the file name matters: PyBullet caches URDFs by path for the life of a connection.
    """
    text = composed_urdf_text()
    digest = hashlib.sha1(text.encode()).hexdigest()[:10]
    path = paths.cache_dir() / f"xarm6_allegro_{digest}.urdf"
    _write_atomic(path, text)
    return path


if __name__ == "__main__":
    target = Path(__file__).resolve().parent.parent / "urdf" / "allegro_hand_right.urdf"
    target.write_text(hand_urdf_text())
    print(f"wrote {target}")
