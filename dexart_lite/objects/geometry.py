"""Convex building blocks, mass properties and a deterministic OBJ writer for the object generators.

Every link of a generated object is a list of **convex pieces** (``trimesh.Trimesh``, watertight,
outward normals). Each link is written as one OBJ with one ``o`` block per piece, so PyBullet builds a
compound of convex hulls without any decomposition. (Measured in pybullet 3.2.7: a U-shaped cup written as
one merged mesh collides as a single convex hull, so a dropped sphere rests on its rim; written with one ``o``
block per convex piece, the sphere falls inside.)
The same OBJ is used for the visual and the collision geometry.

All lengths are metres, all angles radians, densities kg/m^3.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

# Decimal places written for vertex coordinates (1 micrometre) and significant digits for every
# other number in the URDF (and in params.json, which repeats the URDF's joint and mass values).
# Fixed formats keep regeneration byte-for-byte identical.
VERTEX_DECIMALS = 6
SIG_DIGITS = 7


def fmt(x: float) -> str:
    """A float as a short, stable string (``SIG_DIGITS`` significant digits, never ``-0``)."""
    x = float(x)
    if abs(x) < 1e-12:
        return "0"
    return format(x, f".{SIG_DIGITS}g")


def hull(points) -> trimesh.Trimesh:
    """Convex hull of a point set ``(N, 3)``."""
    return trimesh.convex.convex_hull(np.asarray(points, dtype=float))


def box(extents, center=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    """Axis-aligned box with ``extents`` (dx, dy, dz) centred at ``center`` (12 triangles)."""
    mesh = trimesh.creation.box(extents=np.asarray(extents, dtype=float))
    mesh.apply_translation(np.asarray(center, dtype=float))
    return mesh


def rod(p0, p1, radius: float, sections: int = 8) -> trimesh.Trimesh:
    """Cylinder of ``radius`` from point ``p0`` to point ``p1`` (4 * sections triangles)."""
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    return trimesh.creation.cylinder(radius=radius, segment=np.stack([p0, p1]), sections=sections)


def disk(radius: float, z0: float, z1: float, sections: int = 16, center=(0.0, 0.0)) -> trimesh.Trimesh:
    """Vertical cylinder of ``radius`` spanning z0..z1, axis through ``center`` (x, y)."""
    cx, cy = center
    return rod((cx, cy, z0), (cx, cy, z1), radius, sections)


def ball(radius: float, center) -> trimesh.Trimesh:
    """Low-poly sphere (icosphere, 80 triangles)."""
    mesh = trimesh.creation.icosphere(subdivisions=1, radius=radius)
    mesh.apply_translation(np.asarray(center, dtype=float))
    return mesh


def superellipse(a: float, b: float, power: float, count: int, center=(0.0, 0.0)) -> np.ndarray:
    """Closed outline ``|x/a|^power + |y/b|^power = 1`` as ``(count, 2)`` points, counter-clockwise.

    power 2 is an ellipse; larger powers give squarer shapes. The first point is at +x.
    """
    t = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    c, s = np.cos(t), np.sin(t)
    x = a * np.sign(c) * np.abs(c) ** (2.0 / power)
    y = b * np.sign(s) * np.abs(s) ** (2.0 / power)
    return np.stack([x + center[0], y + center[1]], axis=1)


def rounded_rectangle(half_x: float, half_y: float, radius: float, per_corner: int = 5) -> np.ndarray:
    """Rectangle outline ``(4 * per_corner, 2)`` with corner radius ``radius`` (0 gives 4 corners)."""
    if radius <= 0.0:
        return np.array([[half_x, half_y], [-half_x, half_y], [-half_x, -half_y], [half_x, -half_y]])
    points = []
    corners = [(half_x - radius, half_y - radius, 0.0), (-half_x + radius, half_y - radius, 0.5 * np.pi),
               (-half_x + radius, -half_y + radius, np.pi), (half_x - radius, -half_y + radius, 1.5 * np.pi)]
    for cx, cy, a0 in corners:
        for a in np.linspace(a0, a0 + 0.5 * np.pi, per_corner):
            points.append([cx + radius * np.cos(a), cy + radius * np.sin(a)])
    return np.array(points)


def prism(outline, z0: float, z1: float) -> trimesh.Trimesh:
    """Convex hull of a 2-D ``outline`` extruded from z0 to z1."""
    outline = np.asarray(outline, dtype=float)
    lo = np.column_stack([outline, np.full(len(outline), z0)])
    hi = np.column_stack([outline, np.full(len(outline), z1)])
    return hull(np.vstack([lo, hi]))


def _inward_normals(outline: np.ndarray) -> np.ndarray:
    """Unit inward normals ``(N, 2)`` at the vertices of a counter-clockwise closed outline."""
    prev_pt, next_pt = np.roll(outline, 1, axis=0), np.roll(outline, -1, axis=0)
    tangent = next_pt - prev_pt
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    return np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)  # CCW outline: left normal points inward


def wall_sectors(bottom, top, z0: float, z1: float, thickness: float) -> list[trimesh.Trimesh]:
    """An open-ended wall between two outlines, as one convex piece per outline edge.

    ``bottom`` and ``top`` are counter-clockwise outlines ``(N, 2)`` with corresponding vertices,
    placed at heights z0 and z1; the wall is ``thickness`` thick, measured inward. Each piece is the
    hull of its 8 corner points (chord-faced sectors).
    """
    bottom, top = np.asarray(bottom, dtype=float), np.asarray(top, dtype=float)
    bottom_in = bottom + thickness * _inward_normals(bottom)
    top_in = top + thickness * _inward_normals(top)
    pieces = []
    for i in range(len(bottom)):
        j = (i + 1) % len(bottom)
        pts = [(*bottom[k], z0) for k in (i, j)] + [(*bottom_in[k], z0) for k in (i, j)]
        pts += [(*top[k], z1) for k in (i, j)] + [(*top_in[k], z1) for k in (i, j)]
        pieces.append(hull(pts))
    return pieces


def ring_sectors(outline, width: float, z0: float, z1: float) -> list[trimesh.Trimesh]:
    """A flat band of ``width`` (inward from ``outline``) between z0 and z1, one piece per edge."""
    return wall_sectors(outline, outline, z0, z1, width)


def polyline_rods(points, radius: float, sections: int = 8) -> list[trimesh.Trimesh]:
    """Consecutive rods through ``points`` ``(N, 3)``: N - 1 convex pieces."""
    points = np.asarray(points, dtype=float)
    return [rod(p, q, radius, sections) for p, q in zip(points[:-1], points[1:])]


def transform(pieces: list[trimesh.Trimesh], matrix: np.ndarray) -> list[trimesh.Trimesh]:
    """Copies of ``pieces`` moved by a 4x4 homogeneous ``matrix``."""
    out = []
    for piece in pieces:
        moved = piece.copy()
        moved.apply_transform(matrix)
        out.append(moved)
    return out


def translate(pieces: list[trimesh.Trimesh], offset) -> list[trimesh.Trimesh]:
    matrix = np.eye(4)
    matrix[:3, 3] = offset
    return transform(pieces, matrix)


def rot_x(angle: float) -> np.ndarray:
    """3x3 rotation about +x."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> np.ndarray:
    """3x3 rotation about +y."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> np.ndarray:
    """3x3 rotation about +z."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy_matrix(rpy) -> np.ndarray:
    """URDF fixed-axis roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    return rot_z(rpy[2]) @ rot_y(rpy[1]) @ rot_x(rpy[0])


def axis_rotation(axis, angle: float) -> np.ndarray:
    """3x3 rotation by ``angle`` about the unit vector ``axis`` (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    k = k / np.linalg.norm(k)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * kx + (1.0 - np.cos(angle)) * (kx @ kx)


@dataclass(frozen=True)
class MassProperties:
    """Rigid-body properties of a link in its own frame."""

    mass: float  # kg
    volume: float  # m^3, sum of the convex pieces' volumes
    com: np.ndarray  # (3,) m, centre of mass in the link frame
    inertia: np.ndarray  # (3, 3) kg*m^2, about the centre of mass, link-frame axes


def mass_properties(pieces: list[trimesh.Trimesh], density: float) -> MassProperties:
    """Mass, centre of mass and inertia of a union of convex pieces at a uniform ``density``.

    Pieces are summed as if disjoint (as SAPIEN and DexArt do with convex decompositions), so a small
    overlap between two pieces is counted twice.
    """
    masses, coms, inertias = [], [], []
    for piece in pieces:
        props = trimesh.triangles.mass_properties(piece.triangles, density=density)
        masses.append(props["mass"])
        coms.append(props["center_mass"])
        inertias.append(props["inertia"])  # about the piece's own centre of mass
    masses = np.array(masses)
    coms = np.array(coms)
    total = float(masses.sum())
    com = (masses[:, None] * coms).sum(axis=0) / total
    inertia = np.zeros((3, 3))
    for m, c, inert in zip(masses, coms, inertias):
        d = c - com
        inertia += inert + m * (d @ d * np.eye(3) - np.outer(d, d))  # parallel-axis theorem
    return MassProperties(mass=total, volume=total / density, com=com, inertia=inertia)


def obj_text(pieces: list[trimesh.Trimesh], header: str) -> str:
    """A multi-object OBJ: one ``o piece_<i>`` block per convex piece (PyBullet: compound of hulls).

    Written by hand (not ``trimesh.exchange``) so that the bytes depend only on the vertex values.
    """
    lines = [f"# {header}", f"# {len(pieces)} convex pieces, {sum(len(p.faces) for p in pieces)} triangles"]
    offset = 1  # OBJ indices are 1-based and global across objects
    for i, piece in enumerate(pieces):
        lines.append(f"o piece_{i}")
        verts = np.round(np.asarray(piece.vertices, dtype=float), VERTEX_DECIMALS) + 0.0  # + 0.0: no "-0"
        lines += [f"v {x:.{VERTEX_DECIMALS}f} {y:.{VERTEX_DECIMALS}f} {z:.{VERTEX_DECIMALS}f}" for x, y, z in verts]
        lines += [f"f {a + offset} {b + offset} {c + offset}" for a, b, c in np.asarray(piece.faces)]
        offset += len(piece.vertices)
    return "\n".join(lines) + "\n"


def read_obj_pieces(path) -> list[trimesh.Trimesh]:
    """The convex pieces of an OBJ written by :func:`obj_text` (one ``o`` block each)."""
    vertices: list[list[float]] = []
    pieces: list[list[list[int]]] = []
    for line in open(path, encoding="utf-8"):
        tag, *rest = line.split() or [""]
        if tag == "o":
            pieces.append([])
        elif tag == "v":
            vertices.append([float(v) for v in rest])
        elif tag == "f":
            pieces[-1].append([int(i.split("/")[0]) - 1 for i in rest])
    all_vertices = np.array(vertices)
    out = []
    for faces in pieces:
        faces = np.array(faces)
        used = np.unique(faces)
        remap = np.zeros(len(all_vertices), dtype=int)
        remap[used] = np.arange(len(used))
        out.append(trimesh.Trimesh(all_vertices[used], remap[faces], process=False))
    return out


def surface_samples(pieces: list[trimesh.Trimesh], count: int, seed: int) -> np.ndarray:
    """``(count, 3)`` points sampled uniformly (by area) on the pieces' surfaces, reproducibly."""
    merged = trimesh.util.concatenate(pieces)
    points, _ = trimesh.sample.sample_surface(merged, count, seed=seed)
    return np.asarray(points)
