"""Collision geometry and distances (issue 38, phase 1): the capsule distances of
armgen.symbolic.collision_geometry against coal (the maintained successor of hpp-fcl, an
independent implementation: GJK/EPA and its own closed forms) on seeded random pairs of every
kind, near-parallel, touching and zero-length cases included; the robot's collision_distances
against coal at random configurations with every obstacle slot filled; the barrier H_C against
its documented formula and ∇H_C against central finite differences; the robot-file and URDF
readers of the capsules (schema errors naming file, field and fix; URDF shapes enclosed, a mesh
refused with the link and the fix, a URDF link's capsule placed as Pinocchio places the link);
the generated C (double to the bit in practice, float within the verifier's bounds)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from armgen.cli.main import cli
from armgen.description.collision import (INACTIVE_DISTANCE, BoxObstacle, CapsuleObstacle, PlaneObstacle,
                                          SphereObstacle)
from armgen.description.frames import rpy_matrix
from armgen.errors import RobotFileError
from armgen.robot import Robot, load_robot, parse_robot
from armgen.symbolic import collision_geometry as geometry
from armgen.symbolic.collision import BARRIER_FLOOR, COLLISION_FUNCTIONS
from armgen.symbolic.model import SymbolicModel

from test_urdf import OBLIQUE_URDF

coal = pytest.importorskip("coal", reason="coal missing: pip install coal")

SEED = 20261128
PAIRS = 10_000
# The bar: both sides in double, closed forms of a few dozen operations (coal's GJK run
# to 1e-14), so 1e-9 m leaves six orders of magnitude above the ~1e-15 m of rounding.
COAL_TOL = 1e-9
# Central differences of H_C with a step of 2.5e-7 rad: rounding ~ε H / h ≈ 1e-9 H and truncation
# ~h² |H'''| (largest by the barrier's pole: 4e-8 of the gradient's size at H = 3e6), together
# below 1e-6 of the larger of the gradient's size and H.
FD_STEP = 2.5e-7
FD_TOL = 1e-6
# A sample is near the non-smooth set (a clamp or a least-of switching within the step) when
# the differences at 4h and h disagree by more than this fraction of that size; at most
# SKIPPED_SHARE of the samples may be such.
KINK_TOL = 1e-5
SKIPPED_SHARE = 0.1


def _coal_request() -> coal.DistanceRequest:
    request = coal.DistanceRequest()
    request.gjk_tolerance = 1e-15
    request.epa_tolerance = 1e-15
    request.gjk_max_iterations = 1000
    request.epa_max_iterations = 1000
    return request


REQUEST = _coal_request()


def _coal_capsule(a: np.ndarray, b: np.ndarray, radius: float):
    """coal's capsule is centred on its frame's z axis: (shape, transform) of the segment a–b."""
    axis = b - a
    length = float(np.linalg.norm(axis))
    if length == 0.0:
        return coal.Sphere(radius), coal.Transform3s(np.eye(3), a)
    z = axis / length
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(z, helper)
    x /= np.linalg.norm(x)
    return coal.Capsule(radius, length), coal.Transform3s(np.column_stack([x, np.cross(z, x), z]), 0.5 * (a + b))


def _coal_distance(first, second) -> float:
    return coal.distance(*first, *second, REQUEST, coal.DistanceResult())


def _coal_box(centre: np.ndarray, rotation: np.ndarray, half: np.ndarray):
    return coal.Box(*(2 * half)), coal.Transform3s(rotation, centre)


def _coal_halfspace(normal: np.ndarray, offset: float):
    return coal.Halfspace(normal, offset), coal.Transform3s()


def _rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else q @ np.diag([1.0, 1.0, -1.0])


# -- the primitive pairs against coal -----------------------------------------------------

def _pair_function(kind: str) -> ca.Function:
    """The capsule (a, b, r) against a shape of ``kind``, as armgen.symbolic.collision builds it."""
    a, b = ca.SX.sym("a", 3), ca.SX.sym("b", 3)
    r = ca.SX.sym("r")
    if kind == "capsule":
        c, d, s = ca.SX.sym("c", 3), ca.SX.sym("d", 3), ca.SX.sym("s")
        return ca.Function(kind, [a, b, r, c, d, s], [geometry.segment_segment(a, b, c, d) - r - s])
    if kind == "sphere":
        c, s = ca.SX.sym("c", 3), ca.SX.sym("s")
        return ca.Function(kind, [a, b, r, c, s], [geometry.point_segment(c, a, b) - r - s])
    if kind == "box":
        c, rotation, half = ca.SX.sym("c", 3), ca.SX.sym("R", 9), ca.SX.sym("h", 3)  # R column-major
        return ca.Function(kind, [a, b, r, c, rotation, half],
                           [geometry.segment_box(a, b, c, ca.reshape(rotation, 3, 3), half) - r])
    normal, offset = ca.SX.sym("n", 3), ca.SX.sym("o")
    return ca.Function(kind, [a, b, r, normal, offset], [geometry.segment_halfspace(a, b, normal, offset) - r])


def _ours(kind: str, arguments: list[list]) -> np.ndarray:
    """The pair function over every sample at once (Function.map: the same graph per sample)."""
    f = _pair_function(kind)
    columns = [np.column_stack([np.ravel(np.asarray(x, dtype=float).T) for x in argument]) for argument in
               zip(*arguments)]
    return np.array(f.map(len(arguments))(*columns)).ravel()


def _random_segment(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Uniform ends in the unit cube; one in ten of zero length (a sphere as a capsule)."""
    a = rng.uniform(-1, 1, 3)
    return (a, a.copy()) if rng.random() < 0.1 else (a, rng.uniform(-1, 1, 3))


def _capsule_pairs(rng: np.random.Generator, count: int) -> list[list]:
    """General pairs, and a quarter of near-parallel, exactly parallel and collinear ones."""
    pairs = []
    for k in range(count):
        a, b = _random_segment(rng)
        r, s = rng.uniform(0.01, 0.3, 2)
        style = k % 8
        if style == 0:  # near-parallel: b − a turned by 1e-12 … 1e-3 rad, shifted sideways
            turn = rng.normal(size=3)
            angle = 10 ** rng.uniform(-12, -3)
            axis = np.cross(b - a, turn)
            axis /= np.linalg.norm(axis) or 1.0
            rotated = (b - a) * math.cos(angle) + np.cross(axis, b - a) * math.sin(angle)
            c = a + rng.uniform(-0.5, 0.5) * (b - a) + rng.normal(scale=0.3, size=3)
            pairs.append([a, b, r, c, c + rotated * rng.uniform(0.2, 1.5), s])
        elif style == 1:  # exactly parallel (also collinear when the shift is along the axis)
            shift = rng.normal(scale=0.3, size=3) if rng.random() < 0.5 else rng.uniform(-2, 2) * (b - a)
            pairs.append([a, b, r, a + shift, b + shift, s])
        else:
            c, d = _random_segment(rng)
            pairs.append([a, b, r, c, d, s])
    return pairs


# coal takes two segments within ~1e-5 rad of parallel as parallel (its own threshold) and is then
# off by up to 1.1e-7 m (seen on this seed, against the minimisation below); those pairs, sin of
# the angle below COAL_PARALLEL, are compared with an independent minimisation instead.
COAL_PARALLEL = 1e-4
GOLDEN_ITERATIONS = 200


def _golden_section(distance, count: int) -> np.ndarray:
    """min over s ∈ [0, 1] of the convex ``distance(s)`` (one value per pair) by golden-section
    search in extended precision (200 steps shrink the interval by 0.618^200 ≈ 1e-42): another
    algorithm than the closed forms, not their rounding."""
    ratio = (np.sqrt(np.longdouble(5)) - 1) / 2
    lo, hi = np.zeros(count, dtype=np.longdouble), np.ones(count, dtype=np.longdouble)
    for _ in range(GOLDEN_ITERATIONS):
        left, right = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
        lower = distance(left) < distance(right)
        hi, lo = np.where(lower, right, hi), np.where(lower, lo, left)
    return np.minimum(distance(0.5 * (lo + hi)), np.minimum(distance(0 * lo), distance(0 * lo + 1)))


def _golden_section_capsules(pairs: list[list]) -> np.ndarray:
    """The capsule–capsule distances by :func:`_golden_section` over the first axis."""
    a, b, r, c, d, s = (np.array([p[k] for p in pairs], dtype=np.longdouble) for k in range(6))
    u, v = b - a, d - c
    vv = np.maximum(np.einsum("ij,ij->i", v, v), np.longdouble(1e-300))

    def distance(t: np.ndarray) -> np.ndarray:
        point = a + t[:, None] * u
        along = np.clip(np.einsum("ij,ij->i", point - c, v) / vv, 0, 1)
        return np.linalg.norm(c + along[:, None] * v - point, axis=1)

    return (_golden_section(distance, len(pairs)) - r - s).astype(float)


def _golden_section_box(pairs: list[list]) -> np.ndarray:
    """The capsule–box value by :func:`_golden_section` of the box's signed distance (convex)
    along the axis, minus the radius."""
    a, b, r, c, rotation, half = (np.array([p[k] for p in pairs], dtype=np.longdouble) for k in range(6))
    local_a = np.einsum("kji,kj->ki", rotation, a - c)
    local_u = np.einsum("kji,kj->ki", rotation, b - a)

    def distance(t: np.ndarray) -> np.ndarray:
        q = np.abs(local_a + t[:, None] * local_u) - half
        return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)

    return (_golden_section(distance, len(pairs)) - r).astype(float)


def test_capsule_capsule_distances_equal_coals():
    rng = np.random.default_rng(SEED)
    pairs = _capsule_pairs(rng, PAIRS)
    ours = _ours("capsule", pairs)
    theirs = np.array([_coal_distance(_coal_capsule(a, b, r), _coal_capsule(c, d, s)) for a, b, r, c, d, s in pairs])
    sines = np.array([np.linalg.norm(np.cross(b - a, d - c)) / max(np.linalg.norm(b - a) * np.linalg.norm(d - c), 1e-300)
                      for a, b, _, c, d, _ in pairs])
    near_parallel = (sines < COAL_PARALLEL) & np.array([not np.array_equal(p[0], p[1]) for p in pairs])
    error = np.abs(ours - theirs)
    print(f"capsule/capsule: {PAIRS} pairs, {np.sum(theirs < 0)} overlapping, max error {error[~near_parallel].max():.2e}"
          f" m; {near_parallel.sum()} near-parallel, coal off by up to {error[near_parallel].max():.2e} m")
    assert error[~near_parallel].max() <= COAL_TOL  # overlapping ones too: the axes' distance minus the radii is exact
    slow = _golden_section_capsules([p for p, near in zip(pairs, near_parallel) if near])
    assert near_parallel.sum() > PAIRS // 8 and np.abs(ours[near_parallel] - slow).max() <= COAL_TOL


def test_capsule_sphere_and_plane_distances_equal_coals():
    rng = np.random.default_rng(SEED + 1)
    spheres = [[*_random_segment(rng), rng.uniform(0.01, 0.3), rng.uniform(-1, 1, 3), rng.uniform(0.01, 0.3)]
               for _ in range(PAIRS)]
    ours = _ours("sphere", spheres)
    theirs = np.array([_coal_distance(_coal_capsule(a, b, r), (coal.Sphere(s), coal.Transform3s(np.eye(3), c)))
                       for a, b, r, c, s in spheres])
    assert np.abs(ours - theirs).max() <= COAL_TOL
    planes = []
    for k in range(PAIRS):
        a, b = _random_segment(rng)
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        if k % 10 == 0:  # the segment parallel to the plane
            b = a + np.cross(normal, rng.normal(size=3))
        planes.append([a, b, rng.uniform(0.01, 0.3), normal, float(rng.uniform(-1, 1))])
    ours = _ours("plane", planes)
    theirs = np.array([_coal_distance(_coal_capsule(a, b, r), _coal_halfspace(n, o)) for a, b, r, n, o in planes])
    print(f"capsule/plane: {np.sum(theirs < 0)} of {PAIRS} overlapping")
    assert np.abs(ours - theirs).max() <= COAL_TOL


def _box_pairs(rng: np.random.Generator, count: int) -> list[list]:
    """Random boxes and capsules, and one in eight parallel to a face or ending on an edge."""
    pairs = []
    for k in range(count):
        rotation, centre, half = _rotation(rng), rng.uniform(-0.5, 0.5, 3), rng.uniform(0.05, 0.5, 3)
        a, b = _random_segment(rng)
        if k % 8 == 0:  # parallel to a face, above it
            axis = rng.integers(3)
            local = rng.uniform(-1, 1, 3) * half * 1.5
            local[axis] = half[axis] + rng.uniform(0.01, 0.3)
            step = rng.normal(size=3)
            step[axis] = 0.0
            a, b = centre + rotation @ local, centre + rotation @ (local + step)
        elif k % 8 == 1:  # an end on an edge's line, just outside
            local = half * rng.choice([-1.0, 1.0], 3) * np.array([1.0, 1.0, rng.uniform(-1, 1)])
            local += np.sign(local) * np.array([1.0, 1.0, 0.0]) * rng.uniform(1e-6, 0.1)
            a = centre + rotation @ local
        pairs.append([a, b, rng.uniform(0.01, 0.3), centre, rotation, half])
    return pairs


def test_capsule_box_distances_equal_coals():
    """Equal wherever the capsule's axis is outside the box (apart, touching, or only the
    rounded part overlapping); once the axis enters, ours is −r minus its deepest point's depth,
    at least coal's (the translation that separates the whole axis), and equal for a sphere."""
    rng = np.random.default_rng(SEED + 2)
    pairs = _box_pairs(rng, PAIRS)
    ours = _ours("box", pairs)
    theirs = np.array([_coal_distance(_coal_capsule(a, b, r), _coal_box(c, rotation, h))
                       for a, b, r, c, rotation, h in pairs])
    radius = np.array([p[2] for p in pairs])
    axis_inside = ours + radius < 0
    sphere = np.array([np.array_equal(p[0], p[1]) for p in pairs])
    exact = ~axis_inside | sphere
    print(f"capsule/box: {np.sum(theirs < 0)} overlapping, {np.sum(axis_inside)} with the axis inside")
    assert np.sum(exact & (theirs < 0)) > PAIRS // 20  # the overlapping cases are exercised
    # coal's GJK stops early on a few pairs whose end lies by an edge (one in 10 000 on this seed,
    # its nearest point off the box by 2e-4 m): those are judged by the golden-section search
    disagree = exact & (np.abs(ours - theirs) > COAL_TOL)
    print(f"capsule/box: coal disagrees on {disagree.sum()} pairs")
    assert disagree.sum() <= PAIRS // 1000
    assert np.allclose(ours[disagree], _golden_section_box([p for p, bad in zip(pairs, disagree) if bad]),
                       rtol=0.0, atol=COAL_TOL)
    assert np.all(ours[~exact] >= theirs[~exact] - COAL_TOL)
    assert np.allclose(ours, _golden_section_box(pairs), rtol=0.0, atol=COAL_TOL)  # also where the axis is inside


def test_touching_pairs_are_zero_within_rounding():
    """Capsules placed at exactly the sum of their radii (perpendicular axes) and a capsule
    lying on a plane and on a box face: ours and coal's both 0 to 1e-9."""
    rng = np.random.default_rng(SEED + 3)
    for _ in range(200):
        r, s = rng.uniform(0.01, 0.3, 2)
        a = rng.uniform(-1, 1, 3)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        side = np.cross(d, rng.normal(size=3))
        side /= np.linalg.norm(side)
        other = np.cross(d, side)
        c = a + 0.3 * d + (r + s) * side  # the second axis crosses the first's normal plane at r + s
        pair = [a, a + 0.6 * d, r, c - 0.4 * other, c + 0.4 * other, s]
        assert abs(_ours("capsule", [pair])[0]) <= COAL_TOL
        assert abs(_coal_distance(_coal_capsule(*pair[:3]), _coal_capsule(*pair[3:]))) <= COAL_TOL
        half = rng.uniform(0.05, 0.5, 3)
        on_face = [np.array([-0.01, 0.0, half[2] + r]), np.array([0.01, 0.02, half[2] + r]), r, np.zeros(3),
                   np.eye(3), half]
        assert abs(_ours("box", [on_face])[0]) <= COAL_TOL
        assert abs(_ours("plane", [[a, a + side, r, other, float(other @ a) - r]])[0]) <= COAL_TOL


# -- the robot's functions -----------------------------------------------------------------

CAPSULES = """
[[collision]]
link = 0
a = [0, 0, 0]
b = [0, 0, 360]
radius = 70

[[collision]]
link = 2
a = [0, 0, 0]
b = [0, 0, 420]
radius = 65

[[collision]]
link = 4
a = [0, 0, 0]
b = [0, 0, 400]
radius = 60

[[collision]]
link = 6
a = [0, 0, 0]
b = [0, 0, 126]
radius = 50

[[collision]]
link = 7
a = [0, 0, 60]
radius = 45

[collision_check]
ignore = [[0, 1], [1, 2], [2, 3]]
"""


# The bundled robot files end with their own capsules, from this line on.
BUNDLED_CAPSULES = "\n# -- Collision capsules"


def bare_robot_text(name: str) -> str:
    """A bundled robot file's text without its collision capsules."""
    return Path(load_robot(name).path).read_text(encoding="utf-8").split(BUNDLED_CAPSULES)[0]


def iiwa_with_capsules(extra: str = "") -> Robot:
    """The bundled iiwa14 with simpler capsules than its own around its links (DH frames 0, 2, 4, 6
    hold the segments from their origin along z to the next origin; a sphere beyond the flange)."""
    text = bare_robot_text("iiwa14").replace('name = "iiwa14"', 'name = "iiwa14c"') + CAPSULES + extra
    return parse_robot(text, "iiwa14c.toml")


@pytest.fixture(scope="module")
def iiwa() -> Robot:
    return iiwa_with_capsules()


def _random_obstacles(rng: np.random.Generator) -> list:
    """Two of each kind (within the default slots) where the arm reaches."""
    def point():
        return tuple(rng.uniform([-0.8, -0.8, 0.0], [0.8, 0.8, 1.3]))
    obstacles = []
    for _ in range(2):
        obstacles.append(SphereObstacle(point(), float(rng.uniform(0.02, 0.2))))
        obstacles.append(CapsuleObstacle(point(), point(), float(rng.uniform(0.02, 0.2))))
        obstacles.append(BoxObstacle(point(), tuple(rng.uniform(0.05, 0.6, 3)), tuple(rng.uniform(-math.pi, math.pi, 3))))
        normal = rng.normal(size=3)
        obstacles.append(PlaneObstacle(point(), tuple(normal)))
    return obstacles


def _coal_obstacle(obstacle):
    if isinstance(obstacle, SphereObstacle):
        return coal.Sphere(obstacle.radius), coal.Transform3s(np.eye(3), np.array(obstacle.centre))
    if isinstance(obstacle, CapsuleObstacle):
        return _coal_capsule(np.array(obstacle.a), np.array(obstacle.b), obstacle.radius)
    if isinstance(obstacle, BoxObstacle):
        return _coal_box(np.array(obstacle.centre), rpy_matrix(*obstacle.rpy), 0.5 * np.array(obstacle.size))
    normal = np.array(obstacle.normal) / np.linalg.norm(obstacle.normal)
    return _coal_halfspace(normal, float(normal @ np.array(obstacle.point)))


def test_robot_distances_equal_coals_at_random_configurations(iiwa):
    """Every entry of collision_distances (pair_labels' order) against coal on the capsules
    placed by the robot's frames: self pairs and all four obstacle kinds, 300 configurations."""
    rng = np.random.default_rng(SEED + 4)
    configurations = 300
    q = rng.uniform(iiwa.qmin, iiwa.qmax, size=(configurations, iiwa.n))
    frames = iiwa.frames(q)
    labels = iiwa.collision_pairs()
    capsules = iiwa.collision.capsules
    checked = 0
    for k in range(configurations):
        obstacles = _random_obstacles(rng)
        ours = iiwa.collision_distances(q[k], obstacles)
        world = [(frames[k, c.frame] @ [*c.a, 1.0])[:3] for c in capsules]
        world_b = [(frames[k, c.frame] @ [*c.b, 1.0])[:3] for c in capsules]
        by_kind = {kind: [o for o in obstacles if type(o).__name__.lower().startswith(kind)]
                   for kind in ("sphere", "capsule", "box", "plane")}
        self_pairs = len(iiwa.collision.self_pairs())
        for entry, (value, (first, second)) in enumerate(zip(ours, labels)):
            i = int(first.split()[1])
            arm = _coal_capsule(world[i], world_b[i], capsules[i].radius)
            kind, index = second.split()
            if entry < self_pairs:
                j = int(index)
                reference = _coal_distance(arm, _coal_capsule(world[j], world_b[j], capsules[j].radius))
            elif int(index) < len(by_kind[kind]):
                reference = _coal_distance(arm, _coal_obstacle(by_kind[kind][int(index)]))
            else:  # an empty slot
                assert value == INACTIVE_DISTANCE
                continue
            if kind == "box" and value + capsules[i].radius < 0:  # the axis inside the box
                assert value >= reference - COAL_TOL
            else:
                assert abs(value - reference) <= COAL_TOL, (k, first, second, value, reference)
                checked += 1
    assert checked > configurations * 30  # of 38 pairs per configuration (6 self, 4 capsules × 8 obstacles)


def test_batched_distances_equal_single_calls(iiwa):
    rng = np.random.default_rng(SEED + 5)
    q = rng.uniform(iiwa.qmin, iiwa.qmax, size=(4, 3, iiwa.n))
    obstacles = _random_obstacles(rng)
    batch = iiwa.collision_distances(q, obstacles)
    assert batch.shape == (4, 3, len(iiwa.collision_pairs()))
    assert np.array_equal(batch[2, 1], iiwa.collision_distances(q[2, 1], obstacles))
    criterion = iiwa.collision_criterion(q, obstacles, clearance=0.01, activation=0.2)
    assert criterion["H_C"].shape == (4, 3) and criterion["grad_H_C"].shape == (4, 3, iiwa.n)


def _barrier(d: np.ndarray, clearance: float, activation: float) -> np.ndarray:
    """docs/collision.md's formula, written again in NumPy by cases."""
    span, floor = activation - clearance, BARRIER_FLOOR * (activation - clearance)
    room = d - clearance

    def g(u):
        return 0.5 * np.maximum(span / u - 1, 0) ** 2

    slope = -(span / floor - 1) * span / floor ** 2
    value = np.where(room >= floor, g(np.maximum(room, floor)), g(floor) + slope * (room - floor))
    return np.sum(value, axis=-1)


def test_criterion_is_the_documented_barrier(iiwa):
    rng = np.random.default_rng(SEED + 6)
    q = rng.uniform(iiwa.qmin, iiwa.qmax, size=(500, iiwa.n))
    obstacles = _random_obstacles(rng)
    d = iiwa.collision_distances(q, obstacles)
    h = iiwa.collision_criterion(q, obstacles, clearance=0.02, activation=0.25)["H_C"]
    expected = _barrier(d, 0.02, 0.25)
    assert np.sum(expected > 0) > 100 and np.sum(d < 0.02) > 0  # in the band and beyond the clearance
    assert np.allclose(h, expected, rtol=1e-12, atol=0.0)
    # C1 at the activation distance (g and g' vanish there) and at the floor (the tangent)
    for at in (0.25 - 1e-7, 0.25, 0.25 + 1e-7):
        assert _barrier(np.array([at]), 0.02, 0.25) <= 1e-12
    floor = 0.02 + BARRIER_FLOOR * 0.23
    slopes = [(_barrier(np.array([x + 1e-12]), 0.02, 0.25) - _barrier(np.array([x - 1e-12]), 0.02, 0.25)) / 2e-12
              for x in (floor - 1e-10, floor + 1e-10)]
    assert slopes[0] == pytest.approx(slopes[1], rel=1e-3) and slopes[0] < 0


def test_criterion_gradient_equals_central_differences(iiwa):
    rng = np.random.default_rng(SEED + 7)
    obstacles = [SphereObstacle((0.45, 0.1, 0.7), 0.12), BoxObstacle((0.3, -0.4, 0.4), (0.2, 0.3, 0.8), (0, 0, 0.4)),
                 PlaneObstacle((0, 0, 0.05), (0, 0, 1)), CapsuleObstacle((0.5, 0.4, 0.0), (0.5, 0.4, 1.2), 0.06)]
    q = rng.uniform(iiwa.qmin, iiwa.qmax, size=(400, iiwa.n))
    criterion = iiwa.collision_criterion(q, obstacles, clearance=0.0, activation=0.3)
    active = criterion["H_C"] > 0
    q, gradient = q[active], criterion["grad_H_C"][active]
    assert len(q) > 100
    eye = np.eye(iiwa.n)

    def differences(step: float) -> np.ndarray:
        plus = iiwa.collision_criterion(q[:, None, :] + step * eye, obstacles, clearance=0.0, activation=0.3)["H_C"]
        minus = iiwa.collision_criterion(q[:, None, :] - step * eye, obstacles, clearance=0.0, activation=0.3)["H_C"]
        return (plus - minus) / (2 * step)

    coarse, fine = differences(4 * FD_STEP), differences(FD_STEP)
    scale = np.maximum(np.abs(gradient).max(axis=1), criterion["H_C"][active])
    smooth = np.abs(coarse - fine).max(axis=1) <= KINK_TOL * scale
    print(f"∇H_C: {smooth.sum()} of {len(q)} samples away from the non-smooth set")
    assert np.mean(~smooth) <= SKIPPED_SHARE
    error = np.abs(gradient - fine).max(axis=1) / scale
    print(f"∇H_C: largest error {error[smooth].max():.2e} of the size")
    assert error[smooth].max() <= FD_TOL


# The envelope-theorem gradient against reverse-mode AD of the same criterion built on
# collision_distances: two derivations of one expression in double, equal to rounding (1e-9 of
# the larger of the gradient's size and H_C leaves six orders above it).
AD_TOL = 1e-9


def test_criterion_gradient_equals_reverse_mode_ad(iiwa):
    """∇H_C by the witness points moving with their links (armgen.symbolic.collision._Arm.gradient)
    equals CasADi's reverse-mode derivative of H_C composed from the distances, with boxes
    entered by the axis (where the deepest point moves along the segment with a kink) included."""
    from armgen.description.collision import obstacle_parameters
    from armgen.symbolic.collision import _barrier_terms

    distances = iiwa.symbolic.function("collision_distances")
    symbols = [ca.SX.sym(distances.name_in(k), distances.sparsity_in(k)) for k in range(distances.n_in())]
    clearance, activation = ca.SX.sym("clearance"), ca.SX.sym("activation")
    h, _ = _barrier_terms(distances(*symbols), clearance, activation)
    reference = ca.Function("ad", [*symbols, clearance, activation], [h, ca.gradient(h, symbols[0])])
    criterion = iiwa.symbolic.function("collision_criterion")
    rng = np.random.default_rng(SEED + 10)
    boxes_entered = 0
    for _ in range(300):
        obstacles = _random_obstacles(rng)
        parameters = obstacle_parameters(obstacles, iiwa.collision.slots)
        q = rng.uniform(iiwa.qmin, iiwa.qmax)
        arguments = [q, *[parameters[distances.name_in(k)] for k in range(1, distances.n_in())], 0.01, 0.3]
        ours, theirs = ([np.array(v).ravel() for v in f(*arguments)] for f in (criterion, reference))
        scale = max(np.abs(theirs[1]).max(), theirs[0][0], 1.0)
        assert abs(ours[0][0] - theirs[0][0]) <= AD_TOL * scale
        assert np.abs(ours[1] - theirs[1]).max() <= AD_TOL * scale
        d = iiwa.collision_distances(q, obstacles)
        boxes_entered += sum(value + iiwa.collision.capsules[int(first.split()[1])].radius < 0
                             for value, (first, second) in zip(d, iiwa.collision_pairs()) if second.startswith("box"))
    assert boxes_entered > 20  # the kinked case is exercised (41 on this seed)


def test_inactive_slots_and_too_many_obstacles(iiwa):
    d = iiwa.collision_distances(iiwa.q0, [])
    self_pairs = len(iiwa.collision.self_pairs())
    assert np.all(d[self_pairs:] == INACTIVE_DISTANCE) and np.all(d[:self_pairs] < INACTIVE_DISTANCE)
    with pytest.raises(ValueError, match=r"3 box obstacles, but the robot's collision functions take 2; raise "
                                         r"\[collision_check\] max_obstacles.box"):
        iiwa.collision_distances(iiwa.q0, [BoxObstacle((1, 0, 0), (0.1, 0.1, 0.1))] * 3)
    with pytest.raises(ValueError, match="clearance = 0.3 must be below activation = 0.2"):
        iiwa.collision_criterion(iiwa.q0, clearance=0.3, activation=0.2)


def test_robots_without_capsules_have_no_collision_functions():
    robot = load_robot("planar3")
    assert not robot.has_collision
    assert not set(SymbolicModel(robot).available()) & set(COLLISION_FUNCTIONS)
    with pytest.raises(RobotFileError, match="robot 'planar3' has no collision model .it has no capsules."):
        robot.collision_distances(robot.q0)
    assert "no collision capsules: no collision functions" in robot.show_text()


def test_capsules_that_give_no_pair_leave_no_collision_functions():
    text = (Path(load_robot("planar3").path).read_text(encoding="utf-8") + "\n[[collision]]\nlink = 1\na = [0, 0, 0]\n"
            "radius = 0.1\n[collision_check.max_obstacles]\nsphere = 0\ncapsule = 0\nbox = 0\nplane = 0\n")
    robot = parse_robot(text, "lonely.toml")
    assert not robot.has_collision and not set(SymbolicModel(robot).available()) & set(COLLISION_FUNCTIONS)
    assert "no collision model: its capsules give no pair to check" in robot.show_text()


# -- robot files ---------------------------------------------------------------------------

def test_capsules_are_read_in_the_files_units(iiwa):
    capsules = iiwa.collision.capsules
    assert capsules[1].frame == 2 and capsules[1].b == (0.0, 0.0, 0.42) and capsules[1].radius == pytest.approx(0.065)
    assert capsules[4].a == capsules[4].b == (0.0, 0.0, 0.06)  # b omitted: a sphere
    # frames at least two apart, minus the ignored pairs [0, 1], [1, 2], [2, 3]
    assert iiwa.collision.self_pairs() == ((0, 2), (0, 3), (0, 4), (1, 3), (1, 4), (2, 4))
    assert iiwa.collision.moving() == (1, 2, 3, 4)
    text = iiwa.show_text()
    assert "collision: 5 capsules (mm, in their frames), 6 self pairs checked" in text
    assert "capsule  4 frame 7: sphere at [0.0, 0.0, 60.0] r=45.000  [robot file]" in text


@pytest.mark.parametrize("extra, message", [
    ('[[collision]]\nlink = "l3"\na = [0, 0, 0]\nradius = 1\n',
     "[[collision]] capsule 5.link: link = 'l3' names a URDF link, but this robot file is DH: give the frame index"),
    ("[[collision]]\nlink = 8\na = [0, 0, 0]\nradius = 1\n",
     "link = 8 is beyond the flange: the robot has 7 joints, so the frames are 0 (base) … 7"),
    ("[[collision]]\nlink = 2\na = [0, 0, 0]\nradius = -1\n", "radius"),
    ("[[collision]]\nlink = 2\na = [0, 0]\nradius = 1\n", "a"),
    ("[[collision]]\nlink = 2\na = [0, 0, 0]\nradius = 1\nlength = 3\n",
     "[[collision]] capsule 5: unknown field(s) length; allowed: a, b, link, radius"),
])
def test_bad_capsules_are_one_error_naming_file_and_field(extra, message):
    with pytest.raises(RobotFileError, match=r"iiwa14c\.toml") as error:
        iiwa_with_capsules(extra)
    assert message in str(error.value)


def test_bad_ignore_pairs_are_errors():
    for ignore, message in (("[[0, 9]]", "pair [0, 9] names capsule 9, but the file has 5 [[collision]] capsules"),
                            ("[[3, 3]]", "pair [3, 3] names one capsule twice")):
        text = CAPSULES.replace("ignore = [[0, 1], [1, 2], [2, 3]]", f"ignore = {ignore}")
        source = bare_robot_text("iiwa14") + text
        with pytest.raises(RobotFileError) as error:
            parse_robot(source, "arm.toml")
        assert message in str(error.value) and "arm.toml" in str(error.value)


_LENGTH = st.one_of(st.floats(-2e6, 2e6, allow_nan=False), st.integers(-5, 5), st.just(float("nan")),
                    st.just("1"), st.just(True))


@settings(max_examples=200, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(link=st.one_of(st.integers(-2, 10), st.text(max_size=4)), a=st.lists(_LENGTH, min_size=0, max_size=4),
       radius=_LENGTH, ignore=st.lists(st.lists(st.integers(-1, 7), min_size=0, max_size=3), max_size=3))
def test_fuzzed_capsules_load_or_fail_cleanly(link, a, radius, ignore):
    def toml(value):
        if isinstance(value, bool):
            return "true" if value else "false"
        if isinstance(value, float) and math.isnan(value):
            return "nan"
        return json.dumps(value)
    extra = (f"[[collision]]\nlink = {toml(link)}\na = [{', '.join(toml(v) for v in a)}]\nradius = {toml(radius)}\n"
             f"[collision_check]\nignore = {json.dumps(ignore)}\n")
    base = Path(load_robot("planar3").path).read_text(encoding="utf-8")
    try:
        robot = parse_robot(base + extra, "fuzz.toml")
    except RobotFileError as error:
        assert str(error).startswith("fuzz.toml"), str(error)
        return
    (capsule,) = robot.collision.capsules
    assert 0 <= capsule.frame <= robot.n and capsule.radius >= 0 and all(map(math.isfinite, capsule.a))


# -- URDF ----------------------------------------------------------------------------------

def _oblique_with_collisions() -> str:
    shapes = {
        "base": '<collision><origin xyz="0 0 0.1"/><geometry><cylinder radius="0.08" length="0.2"/></geometry></collision>',
        "l2": '<collision><origin xyz="0.1 0.02 0" rpy="0 1.5707963267948966 0.3"/><geometry><cylinder radius="0.05" '
              'length="0.3"/></geometry></collision>',
        "mid": '<collision><origin xyz="0.01 0 0.1" rpy="0.4 0.2 0.1"/><geometry><box size="0.1 0.3 0.05"/></geometry>'
               '</collision>',
        "l5": '<collision><geometry><sphere radius="0.04"/></geometry></collision>',
        "tcp": '<collision><origin xyz="0 0 -0.05"/><geometry><capsule radius="0.03" length="0.1"/></geometry>'
               '</collision>',
    }
    text = OBLIQUE_URDF
    for link, shape in shapes.items():
        text = text.replace(f'<link name="{link}"/>', f'<link name="{link}">{shape}</link>')
    return text


def test_urdf_shapes_become_capsules_enclosing_them(tmp_path):
    path = tmp_path / "oblique.urdf"
    path.write_text(_oblique_with_collisions(), encoding="utf-8")
    robot = Robot.from_urdf(path)
    assert robot.has_collision
    origins = [(c.link, c.frame, c.origin) for c in robot.collision.capsules]
    assert origins == [("base", 0, "urdf cylinder (enclosed)"), ("l2", 2, "urdf cylinder (enclosed)"),
                       ("mid", 4, "urdf box (enclosed)"), ("l5", 5, "urdf sphere"), ("tcp", 6, "urdf capsule")]
    assert "[urdf box (enclosed)]" in robot.show_text()
    assert "collision: 5 capsules (mm, in their frames; 3 enclose a URDF cylinder or box)" in robot.show_text()
    box = robot.collision.capsules[2]
    assert box.radius == pytest.approx(math.hypot(0.05, 0.025))  # the cross-section's half-diagonal
    assert np.linalg.norm(np.subtract(box.b, box.a)) == pytest.approx(0.3)  # along the longest side


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    t = np.clip((points - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-300), 0, 1)
    return np.linalg.norm(a + t[:, None] * (b - a) - points, axis=1)


@settings(max_examples=100, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(size=st.lists(st.floats(0.01, 1.0), min_size=3, max_size=3), xyz=st.lists(st.floats(-1, 1), min_size=3, max_size=3),
       rpy=st.lists(st.floats(-3.1, 3.1), min_size=3, max_size=3), cylinder=st.booleans())
def test_urdf_cylinders_and_boxes_are_enclosed_tightly(tmp_path_factory, size, xyz, rpy, cylinder):
    """Every corner of a box and every rim point of a cylinder lies in its capsule, and one of them
    on its surface (the capsule is no larger than its construction says)."""
    shape = (f'<cylinder radius="{size[0]!r}" length="{size[1]!r}"/>' if cylinder
             else f'<box size="{size[0]!r} {size[1]!r} {size[2]!r}"/>')
    origin = f'<origin xyz="{" ".join(map(repr, xyz))}" rpy="{" ".join(map(repr, rpy))}"/>'
    path = tmp_path_factory.mktemp("shape") / "shape.urdf"
    path.write_text(f"""<robot name="shape"><link name="base"><collision>{origin}<geometry>{shape}</geometry></collision>
      </link><link name="l1"/><joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
      <limit lower="-1" upper="1"/></joint></robot>""", encoding="utf-8")
    (capsule,) = Robot.from_urdf(path).collision.capsules
    if cylinder:
        angles = np.linspace(0, 2 * np.pi, 64, endpoint=False)
        local = np.array([[size[0] * math.cos(t), size[0] * math.sin(t), z * size[1] / 2]
                          for t in angles for z in (-1.0, 1.0)])
    else:
        local = np.array([[sx * size[0], sy * size[1], sz * size[2]] for sx in (-0.5, 0.5) for sy in (-0.5, 0.5)
                          for sz in (-0.5, 0.5)])
    points = local @ rpy_matrix(*rpy).T + np.array(xyz)
    distance = _segment_distance(points, np.array(capsule.a), np.array(capsule.b))
    assert distance.max() <= capsule.radius * (1 + 1e-12)
    assert distance.max() >= capsule.radius * (1 - 1e-12)


def test_urdf_capsules_sit_where_pinocchio_places_their_links(tmp_path):
    """The capsules' ends in the base frame through robot.frames against the link placements
    of Pinocchio's model of the same URDF (the shapes' origins composed by hand)."""
    pin = pytest.importorskip("pinocchio", reason="Pinocchio missing: pip install pin")
    path = tmp_path / "oblique.urdf"
    path.write_text(_oblique_with_collisions(), encoding="utf-8")
    robot = Robot.from_urdf(path)
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    geometry_model = pin.buildGeomFromUrdf(model, str(path), pin.GeometryType.COLLISION)
    rng = np.random.default_rng(SEED + 8)
    for q in rng.uniform(robot.qmin, robot.qmax, size=(50, robot.n)):
        qp = pin.neutral(model)
        for joint, value in zip(robot.joints, q):
            idx, nq = model.joints[model.getJointId(joint.name)].idx_q, model.joints[model.getJointId(joint.name)].nq
            qp[idx:idx + nq] = [math.cos(value), math.sin(value)] if nq == 2 else [value]
        pin.framesForwardKinematics(model, data, qp)
        geometry_data = pin.GeometryData(geometry_model)
        pin.updateGeometryPlacements(model, data, geometry_model, geometry_data)
        frames = robot.frames(q)
        for capsule, placement in zip(robot.collision.capsules, geometry_data.oMg):
            ours = [(frames[capsule.frame] @ [*end, 1.0])[:3] for end in (capsule.a, capsule.b)]
            # every shape's axis is its frame's z (cylinder, capsule) or a point (sphere) or, for
            # the box, its longest side: the local y axis of 0.1 x 0.3 x 0.05
            axis = 1 if capsule.origin == "urdf box (enclosed)" else 2
            half = 0.5 * np.linalg.norm(np.subtract(capsule.b, capsule.a))
            theirs = [placement.translation + sign * half * placement.rotation[:, axis] for sign in (-1.0, 1.0)]
            assert np.allclose(ours, theirs, atol=1e-12) or np.allclose(ours, theirs[::-1], atol=1e-12)


def test_urdf_mesh_is_refused_naming_the_link_and_a_robot_file_replaces_it(tmp_path):
    text = _oblique_with_collisions().replace(
        '<link name="l3"/>', '<link name="l3"><collision><geometry><mesh filename="l3.stl"/></geometry></collision></link>')
    (tmp_path / "oblique.urdf").write_text(text, encoding="utf-8")
    robot = Robot.from_urdf(tmp_path / "oblique.urdf")
    assert not robot.has_collision
    assert "link 'l3' has a <mesh> collision shape" in robot.show_text()
    with pytest.raises(RobotFileError, match=r"link 'l3' has a <mesh> collision shape, which armgen does not take; give "
                                             r"its capsules in a robot file that references the URDF \(\[\[collision\]\] "
                                             r'link = "l3"'):
        robot.collision_distances(robot.qmid)
    (tmp_path / "arm.toml").write_text('urdf = "oblique.urdf"\n[units]\nlength = "mm"\n'
                                       '[[collision]]\nlink = "l3"\na = [0, 0, 0]\nb = [0, 0, 100]\nradius = 30\n',
                                       encoding="utf-8")
    wrapped = load_robot(tmp_path / "arm.toml")
    assert wrapped.has_collision
    first = wrapped.collision.capsules[0]
    assert first.link == "l3" and first.frame == 3 and first.radius == pytest.approx(0.03)
    assert len(wrapped.collision.capsules) == 6  # the file's, then the URDF's other five
    (tmp_path / "bad.toml").write_text('urdf = "oblique.urdf"\n[[collision]]\nlink = "nope"\na = [0, 0, 0]\n'
                                       'radius = 1\n', encoding="utf-8")
    with pytest.raises(RobotFileError, match=r"bad.toml: \[\[collision\]\] capsule 0: link = 'nope' is not a link of "
                                             r"the chain \(links: world, base"):
        load_robot(tmp_path / "bad.toml")


def test_a_urdf_with_more_shapes_than_capsules_loads_without_a_collision_model(tmp_path):
    spheres = "".join(f'<collision><origin xyz="0 0 {0.01 * k}"/><geometry><sphere radius="0.01"/></geometry></collision>'
                      for k in range(40))
    (tmp_path / "many.urdf").write_text(OBLIQUE_URDF.replace('<link name="l3"/>', f'<link name="l3">{spheres}</link>'),
                                        encoding="utf-8")
    robot = Robot.from_urdf(tmp_path / "many.urdf")
    assert not robot.has_collision and robot.n == 6
    assert "the URDF's and the robot file's shapes make 40 capsules, more than 32" in robot.show_text()


@pytest.mark.parametrize("collision, message", [
    ("<collision/>",
     "link 'l3' <collision> 1: needs <geometry> with one of <sphere>, <cylinder>, <box>, <capsule>, <mesh>"),
    ("<collision><geometry><cone radius=\"1\"/></geometry></collision>", "<cone>: is not a URDF collision shape"),
    ("<collision><geometry><sphere/></geometry></collision>", "<collision> 1 <sphere>: <sphere> needs attribute 'radius'"),
    ("<collision><geometry><box size=\"1 2\"/></geometry></collision>", "must be 3 numbers, got 2"),
    ("<collision><geometry><cylinder radius=\"-1\" length=\"1\"/></geometry></collision>",
     "radius must be ≥ 0 and at most 1000 m (URDF is in m)"),
])
def test_malformed_urdf_collision_is_one_error_naming_the_link(tmp_path, collision, message):
    (tmp_path / "bad.urdf").write_text(OBLIQUE_URDF.replace('<link name="l3"/>', f'<link name="l3">{collision}</link>'),
                                       encoding="utf-8")
    with pytest.raises(RobotFileError) as error:
        Robot.from_urdf(tmp_path / "bad.urdf")
    assert str(error.value).startswith(str(tmp_path / "bad.urdf")) and message in str(error.value), str(error.value)


# -- generated C ---------------------------------------------------------------------------

# A small arm for the C: the planar 3R with a capsule per link, the links stacked 0.12 m apart in
# z as a real planar arm's are (coplanar axes would cross on a whole region, where the distance
# has no gradient: double gives 0 there, float a direction of rounding), one slot of each kind.
PLANAR_CAPSULES = """
[[collision]]
link = 1
a = [-0.5, 0, 0]
b = [0, 0, 0]
radius = 0.05

[[collision]]
link = 2
a = [-0.4, 0, 0.12]
b = [0, 0, 0.12]
radius = 0.04

[[collision]]
link = 3
a = [-0.3, 0, 0.24]
b = [0, 0, 0.24]
radius = 0.03

[[collision]]
link = 0
a = [0, 0, -0.2]
b = [0, 0, 0]
radius = 0.1

[collision_check.max_obstacles]
sphere = 1
capsule = 1
box = 1
plane = 1
"""


def _planar_with_capsules(folder: Path) -> Path:
    text = Path(load_robot("planar3").path).read_text(encoding="utf-8").replace('name = "planar3"', 'name = "planarc"')
    path = folder / "planarc.toml"
    path.write_text(text + PLANAR_CAPSULES, encoding="utf-8")
    return path


def test_gen_emits_the_collision_functions_and_verify_compares_them(tmp_path, monkeypatch):
    """armgen gen lists them last with fixed-size obstacle arrays; armgen verify compares them
    in double and float (the callbacks stage: bounds DOUBLE_REL_BOUND and FLOAT_BOUNDS); a bundled
    robot has them when its file gives capsules (iiwa14, panda), none otherwise."""
    monkeypatch.chdir(tmp_path)
    _planar_with_capsules(tmp_path)
    out = CliRunner().invoke(cli, ["gen", "planarc.toml", "-o", "gen"])
    assert out.exit_code == 0, out.output
    manifest = json.loads((tmp_path / "gen" / "manifest.json").read_text())
    assert manifest["options"]["functions"][-2:] == list(COLLISION_FUNCTIONS)
    header = (tmp_path / "gen" / "planarc.h").read_text()
    # 3 self pairs (frames 1-3, 2-0, 3-0), then 3 moving capsules against 4 slots
    r = "planarc_real"
    assert (f"void planarc_collision_distances(const {r} q[PLANARC_NDOF], const {r} spheres[5], const {r} capsules[8], "
            f"const {r} boxes[16], const {r} planes[5], {r} d[15]);") in header
    assert (f"void planarc_collision_criterion(const {r} q[PLANARC_NDOF], const {r} spheres[5], const {r} capsules[8], "
            f"const {r} boxes[16], const {r} planes[5], {r} clearance, {r} activation, {r} *H_C, "
            f"{r} grad_H_C[PLANARC_NDOF]);") in header
    report = tmp_path / "verify.json"
    out = CliRunner().invoke(cli, ["verify", "planarc.toml", "-o", "gen", "--samples", "2000", "--report", str(report)])
    assert out.exit_code == 0, out.output
    (callbacks,) = [stage for stage in json.loads(report.read_text())["stages"] if stage["name"] == "callbacks"]
    compared = {(row[0], row[1]) for row in callbacks["rows"] if row[5]}
    assert {(name, precision) for name in COLLISION_FUNCTIONS for precision in ("double", "float")} <= compared
    for name in ("planar3", "modular8", "iiwa14", "panda"):
        bundled = json.loads((Path(__file__).parent.parent / "generated" / name / "manifest.json").read_text())
        emitted = set(bundled["functions"]) & set(COLLISION_FUNCTIONS)
        assert emitted == (set(COLLISION_FUNCTIONS) if load_robot(name).has_collision else set())


@pytest.fixture(scope="module")
def planar_collision_c(tmp_path_factory) -> tuple[Path, Robot]:
    """The planar arm's two collision functions generated alone."""
    from armgen.codegen.generate import CodegenConfig, generate, write

    folder = tmp_path_factory.mktemp("planarc")
    robot = load_robot(_planar_with_capsules(folder))
    write(generate(CodegenConfig(robot, functions=COLLISION_FUNCTIONS)), folder / "gen")
    return folder / "gen", robot


def test_collision_c_is_strict_heap_free_and_true_float(planar_collision_c, tmp_path):
    """The strict flags in both precisions, no heap or stdio, no double libm call in the float
    build, and no software double on a Cortex-M4F."""
    import subprocess

    from armgen.codegen.toolchain import ARM_CPU_FLAGS, STRICT_FLAGS
    from conftest import require_tool
    from test_codegen import DOUBLE_LIBM, FORBIDDEN_SYMBOLS
    from test_dynamics_codegen import _undefined_symbols

    gen_dir, _ = planar_collision_c
    source = gen_dir / "planarc.c"
    undefined = {}
    for precision, flag in (("double", 0), ("float", 1)):
        obj = tmp_path / f"{precision}.o"
        subprocess.run(["gcc", *STRICT_FLAGS, "-O2", f"-DPLANARC_USE_FLOAT={flag}", "-c", str(source), "-o", str(obj)],
                       check=True, capture_output=True, text=True)
        undefined[precision] = _undefined_symbols(obj)
        assert not undefined[precision] & FORBIDDEN_SYMBOLS
    assert not undefined["float"] & DOUBLE_LIBM
    arm_gcc = require_tool("arm-none-eabi-gcc")
    m4 = tmp_path / "m4.o"
    subprocess.run([arm_gcc, *STRICT_FLAGS, "-Os", *ARM_CPU_FLAGS, "-DPLANARC_USE_FLOAT=1", "-c", str(source), "-o",
                    str(m4)], check=True, capture_output=True, text=True)
    symbols = _undefined_symbols(m4, require_tool("arm-none-eabi-nm"))
    assert not [s for s in symbols if s.startswith("__aeabi_d")], symbols


@pytest.mark.parametrize("precision", ["double", "float"])
def test_collision_c_is_sanitizer_clean(planar_collision_c, precision):
    from armgen.verification.harness import run_sanitized

    gen_dir, robot = planar_collision_c
    functions = {name: robot.symbolic.function(name) for name in COLLISION_FUNCTIONS}
    assert run_sanitized(gen_dir, "planarc", functions, precision).startswith("ok")


# -- the task vocabulary ---------------------------------------------------------------------

def test_task_obstacles_convert_to_si_and_feed_the_distances(iiwa):
    """[[obstacles]] and [collision] in a task's millimetres and degrees give the same distances
    as the obstacles written in SI by hand; bad entries are one error naming the field."""
    import pydantic
    import tomllib

    from armgen.planning.common.collision import CollisionSettings, Obstacles, collision_si, obstacles_si
    from armgen.planning.common.schema import Units

    document = tomllib.loads("""
        [[obstacles]]
        type = "capsule"
        a = [600, -200, 0]
        b = [600, -200, 1200]
        radius = 80
        [[obstacles]]
        type = "box"
        centre = [500, 300, 400]
        size = [200, 300, 800]
        rpy = [0, 0, 30]
        [[obstacles]]
        type = "sphere"
        centre = [400, 0, 900]
        radius = 100
        [[obstacles]]
        type = "plane"
        point = [0, 0, 0]
        normal = [0, 0, 2]
        [collision]
        clearance = 20
        activation = 100
        """)
    units = Units(length="mm", angle="deg")
    entries = pydantic.TypeAdapter(Obstacles).validate_python(document["obstacles"], strict=True)
    obstacles = obstacles_si(entries, units)
    by_hand = [CapsuleObstacle((0.6, -0.2, 0.0), (0.6, -0.2, 1.2), 0.08),
               BoxObstacle((0.5, 0.3, 0.4), (0.2, 0.3, 0.8), (0.0, 0.0, math.radians(30))),
               SphereObstacle((0.4, 0.0, 0.9), 0.1), PlaneObstacle((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))]
    q = np.random.default_rng(SEED + 9).uniform(iiwa.qmin, iiwa.qmax, size=(50, iiwa.n))
    assert np.allclose(iiwa.collision_distances(q, obstacles), iiwa.collision_distances(q, by_hand), rtol=0, atol=1e-15)
    settings = collision_si(CollisionSettings.model_validate(document["collision"]), units)
    assert (settings.clearance, settings.activation, settings.gain) == pytest.approx((0.02, 0.1, 0.01))
    for bad, message in (({"type": "cone", "radius": 1}, "cone"), ({"type": "plane", "point": [0, 0, 0],
                                                                     "normal": [0, 0, 0]}, "has no direction"),
                         ({"type": "box", "centre": [0, 0, 0], "size": [1, 0, 1]}, "greater than 0")):
        with pytest.raises(pydantic.ValidationError, match=message):
            pydantic.TypeAdapter(Obstacles).validate_python([bad], strict=True)
    with pytest.raises(pydantic.ValidationError, match="activation = 10.0 must be beyond clearance = 20.0"):
        CollisionSettings.model_validate({"clearance": 20.0, "activation": 10.0})


_URDF_VALUE = st.one_of(st.floats(-10, 10, allow_nan=False).map(repr), st.sampled_from(["nan", "inf", "1e400", "", "x",
                                                                                        "0", "-1", "0 0", "1 2 3"]))


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(shape=st.sampled_from(["sphere", "cylinder", "box", "capsule", "mesh", "cone"]),
       values=st.fixed_dictionaries({key: _URDF_VALUE for key in ("radius", "length", "size")}),
       present=st.sets(st.sampled_from(["radius", "length", "size"])))
def test_fuzzed_urdf_collision_shapes_load_or_fail_cleanly(tmp_path_factory, shape, values, present):
    """Every result is a robot whose capsules are finite and within the bounds, or one
    RobotFileError naming the file and the link's <collision>."""
    attributes = " ".join(f'{key}="{values[key]}"' for key in sorted(present))
    text = _oblique_with_collisions().replace(
        '<link name="l3"/>', f'<link name="l3"><collision><geometry><{shape} {attributes} filename="x.stl"/></geometry>'
                             '</collision></link>')
    path = tmp_path_factory.mktemp("urdf") / "fuzz.urdf"
    path.write_text(text, encoding="utf-8")
    try:
        robot = Robot.from_urdf(path)
    except RobotFileError as error:
        assert str(error).startswith(str(path)) and "link 'l3' <collision> 1" in str(error), str(error)
        return
    for capsule in robot.collision.capsules:
        assert 0 <= capsule.radius <= 1e3 and np.all(np.isfinite([*capsule.a, *capsule.b]))
    assert robot.has_collision == (shape != "mesh")


_COORDINATE = st.floats(-2, 2, allow_nan=False).map(lambda v: round(v, 1))  # ties, zeros and repeats are common


@settings(max_examples=500, deadline=None, derandomize=True)
@given(points=st.lists(st.tuples(_COORDINATE, _COORDINATE, _COORDINATE), min_size=4, max_size=4))
def test_degenerate_segments_give_finite_distances_and_gradients(points):
    """Zero-length, coincident, parallel and crossing segments (coordinates on a 0.1 grid): the
    distance is the brute-force one and its gradient is finite (the guarded divisions)."""
    a1, b1, a2, b2 = (np.array(p) for p in points)
    x = ca.SX.sym("x", 12)
    distance = geometry.segment_segment(x[0:3], x[3:6], x[6:9], x[9:12])
    f = ca.Function("f", [x], [distance, ca.gradient(distance, x)])
    value, gradient = (np.array(v).ravel() for v in f(np.concatenate([a1, b1, a2, b2])))
    s = np.linspace(0, 1, 201)
    first, second = a1 + s[:, None] * (b1 - a1), a2 + s[:, None] * (b2 - a2)
    brute = np.min(np.linalg.norm(first[:, None, :] - second[None, :, :], axis=2))
    assert np.all(np.isfinite(gradient)) and value[0] >= 0
    assert brute - 0.02 <= value[0] <= brute + 1e-12  # the grid of 201 points is within 0.02 of the segments' points
