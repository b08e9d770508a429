"""What a generator produces (an :class:`ObjectModel`), its parameter space and its URDF text.

A category module (``faucet.py``, ``bucket.py``, ``laptop.py``, ``toilet.py``) defines a
:class:`CategorySpec`: the parameters with their per-template ranges and held-out bands, and a
``build(template, params)`` function returning an :class:`ObjectModel`: two links (the fixed or free
**body**, and the **functional part**) joined by one revolute joint.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import trimesh

from dexart_lite.objects import geometry
from dexart_lite.objects.geometry import fmt

GRAVITY = 9.81  # m/s^2
# Laptop and toilet lids hold any opening: joint friction = HOLD_FACTOR * max gravity torque.
HOLD_FACTOR = 1.3
# Nominal URDF <limit> effort and velocity. PyBullet does not enforce them; the task drives the joint.
URDF_EFFORT = 10.0  # N*m
URDF_VELOCITY = 3.14  # rad/s

BODY_RGBA = (0.78, 0.78, 0.76, 1.0)  # light grey
PART_RGBA = (0.85, 0.12, 0.10, 1.0)  # red: the functional part


@dataclass(frozen=True)
class Param:
    """One continuous generator parameter.

    ``ranges`` maps a template letter to its (lo, hi) range (lo == hi: a fixed value for that
    template). ``heldout`` lists bands, as fractions of the A/B range, that seen objects never draw
    from and that some unseen objects draw from (``urdf/objects/README.md``, Templates and parameters).
    """

    name: str
    unit: str  # "m", "rad", "kg", "N*m", "-" (ratio) or "int"
    doc: str
    ranges: dict[str, tuple[float, float]]
    heldout: tuple[tuple[float, float], ...] = ()
    decimals: int = 4  # stored rounded, so the canonical JSON (and the name hash) is stable

    def span(self) -> tuple[float, float]:
        """The union of the template ranges (used to normalise parameter distances)."""
        return min(r[0] for r in self.ranges.values()), max(r[1] for r in self.ranges.values())


@dataclass
class LinkModel:
    """A rigid link made of convex pieces, in its own frame."""

    name: str
    pieces: list[trimesh.Trimesh]
    density: float  # kg/m^3
    rgba: tuple[float, float, float, float]

    def mass_properties(self) -> geometry.MassProperties:
        return geometry.mass_properties(self.pieces, self.density)

    def triangles(self) -> int:
        return sum(len(p.faces) for p in self.pieces)


@dataclass
class JointModel:
    """The task's revolute joint: body -> functional part."""

    name: str
    xyz: np.ndarray  # (3,) m, joint origin (= part frame origin) in the body frame
    rpy: tuple[float, float, float]  # rad, URDF origin rotation of the part frame in the body frame
    axis: tuple[float, float, float]  # unit axis, in the joint (part) frame
    lower: float  # rad
    upper: float  # rad
    init: float  # rad, the state at reset
    target: float  # rad, DexArt's "middle"
    friction: float  # N*m, applied by the task as a VELOCITY_CONTROL motor with force = friction

    def part_to_body(self, q: float) -> np.ndarray:
        """4x4 transform of the part frame in the body frame at joint angle ``q``."""
        matrix = np.eye(4)
        matrix[:3, :3] = geometry.rpy_matrix(self.rpy) @ geometry.axis_rotation(self.axis, q)
        matrix[:3, 3] = self.xyz
        return matrix


@dataclass
class ObjectModel:
    """A generated articulated object, before it is written to disk."""

    category: str
    template: str
    body: LinkModel
    part: LinkModel
    joint: JointModel
    grasp_point: np.ndarray  # (3,) m, in the part frame
    fixed_base: bool
    notes: dict = field(default_factory=dict)  # derived dimensions worth recording (m, rad, kg)

    def center_footprint(self) -> None:
        """Move the body frame to the centre of the footprint, z = 0 at the bottom (in place).

        The footprint is the x-y bounding box of the body vertices that touch the lowest level.
        """
        verts = np.vstack([p.vertices for p in self.body.pieces])
        z_min = verts[:, 2].min()
        ground = verts[verts[:, 2] < z_min + 1e-4]
        center = 0.5 * (ground[:, :2].min(axis=0) + ground[:, :2].max(axis=0))
        offset = np.array([-center[0], -center[1], -z_min])
        self.body.pieces = geometry.translate(self.body.pieces, offset)
        self.joint.xyz = np.asarray(self.joint.xyz, dtype=float) + offset

    def max_gravity_torque(self, samples: int = 181) -> float:
        """Largest gravity torque (N*m) of the part about its joint axis over the joint range."""
        props = self.part.mass_properties()
        weight = np.array([0.0, 0.0, -props.mass * GRAVITY])
        axis_body = geometry.rpy_matrix(self.joint.rpy) @ np.asarray(self.joint.axis, dtype=float)
        worst = 0.0
        for q in np.linspace(self.joint.lower, self.joint.upper, samples):
            com = self.joint.part_to_body(q)[:3, :3] @ props.com  # relative to the joint origin
            worst = max(worst, abs(float(np.cross(com, weight) @ axis_body)))
        return worst


@dataclass(frozen=True)
class CategorySpec:
    """Everything the generator needs to know about one category."""

    name: str
    templates: dict[str, str]  # letter -> one-line description; "C" is held out (unseen only)
    params: tuple[Param, ...]
    primary: tuple[str, ...]  # parameters with held-out bands (seen draws avoid them)
    build: Callable[[str, dict], ObjectModel]
    summary_keys: tuple[str, ...]  # parameters shown by ``objects list``
    # The optional "wide" training split: ``wide`` extra objects of templates A / B whose draws ``widen`` changes
    # (params, rng) -> params beyond the A / B ranges. Training-only shapes for a category whose seen objects
    # are too alike; the seen and unseen splits (DexArt's) are untouched. 0: no wide split.
    wide: int = 0
    widen: Callable[[dict, np.random.Generator], dict] | None = None

    def param(self, name: str) -> Param:
        return next(p for p in self.params if p.name == name)


def ceil_to(x: float, step: float) -> float:
    """``x`` rounded up to a multiple of ``step`` (for derived physical constants)."""
    return round(math.ceil(x / step - 1e-9) * step, 6)


def _inertial_xml(props: geometry.MassProperties) -> str:
    c, inertia = props.com, props.inertia
    return (
        "    <inertial>\n"
        f'      <origin xyz="{fmt(c[0])} {fmt(c[1])} {fmt(c[2])}" rpy="0 0 0"/>\n'
        f'      <mass value="{fmt(props.mass)}"/>\n'
        f'      <inertia ixx="{fmt(inertia[0, 0])}" ixy="{fmt(inertia[0, 1])}" ixz="{fmt(inertia[0, 2])}" '
        f'iyy="{fmt(inertia[1, 1])}" iyz="{fmt(inertia[1, 2])}" izz="{fmt(inertia[2, 2])}"/>\n'
        "    </inertial>\n"
    )


def _link_xml(link: LinkModel, mesh_file: str) -> str:
    rgba = " ".join(fmt(v) for v in link.rgba)
    geom = f'<geometry><mesh filename="{mesh_file}"/></geometry>'
    return (
        f'  <link name="{link.name}">\n'
        + _inertial_xml(link.mass_properties())
        + f"    <visual>\n      {geom}\n"
        f'      <material name="{link.name}_color"><color rgba="{rgba}"/></material>\n'
        "    </visual>\n"
        f"    <collision>\n      {geom}\n    </collision>\n"
        "  </link>\n"
    )


def urdf_text(model: ObjectModel, name: str) -> str:
    """The URDF of ``model``; meshes are ``<link>.obj`` next to the URDF."""
    j = model.joint
    return (
        '<?xml version="1.0"?>\n'
        f"<!-- generated by dexart_lite.objects ({model.category}, template {model.template}); do not edit -->\n"
        f'<robot name="{name}">\n'
        + _link_xml(model.body, f"{model.body.name}.obj")
        + _link_xml(model.part, f"{model.part.name}.obj")
        + f'  <joint name="{j.name}" type="revolute">\n'
        f'    <parent link="{model.body.name}"/>\n'
        f'    <child link="{model.part.name}"/>\n'
        f'    <origin xyz="{fmt(j.xyz[0])} {fmt(j.xyz[1])} {fmt(j.xyz[2])}" '
        f'rpy="{fmt(j.rpy[0])} {fmt(j.rpy[1])} {fmt(j.rpy[2])}"/>\n'
        f'    <axis xyz="{fmt(j.axis[0])} {fmt(j.axis[1])} {fmt(j.axis[2])}"/>\n'
        f'    <limit lower="{fmt(j.lower)}" upper="{fmt(j.upper)}" effort="{fmt(URDF_EFFORT)}" '
        f'velocity="{fmt(URDF_VELOCITY)}"/>\n'
        "  </joint>\n"
        "</robot>\n"
    )
