"""The bundled arms' collision capsules (issue 38): the panda's are Franka's published capsule
model as example-robot-data ships it (panda_collision.urdf) and enclose the same package's
collision meshes; the iiwa14's are Drake's primitives moved into the DH frames (checked at the
URDF link frames Pinocchio computes from Drake's kinematics); every named configuration of a
bundled arm is free of self collision by coal's distances; the arms without published geometry
have no capsules."""

from __future__ import annotations

import struct
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from armgen.robot import load_robot

from test_collision import REQUEST, _coal_capsule

coal = pytest.importorskip("coal", reason="coal missing: pip install coal")
pin = pytest.importorskip("pinocchio", reason="Pinocchio missing: pip install pin example-robot-data")

SEED = 20261128
CONFIGURATIONS = 200
# The robot file gives the published numbers (m -> mm) to 1e-6 mm; a transform between frames
# (the iiwa's) is exact to rounding.
PLACEMENT_TOL = 1e-9  # m
# The panda's base capsule is Franka's segment with the radius raised from 90 mm to 130 mm so that
# it encloses link0's mesh; every other capsule is Franka's.
PANDA_BASE_RADIUS = 0.130


def _erd() -> Path:
    from test_urdf import _example_robot_data_dir

    return _example_robot_data_dir() / "panda_description"


def _franka_capsules() -> list[tuple[int, np.ndarray, np.ndarray, float]]:
    """(link, a, b, radius) of panda_collision.urdf: each cylinder with its two end spheres (the
    spheres of the cylinder's radius are the ends of a capsule), in the URDF's order."""
    root = ET.parse(_erd() / "urdf" / "panda_collision.urdf").getroot()
    capsules = []
    for link in root.findall("link"):
        name = link.get("name")
        if not name.startswith("panda_link"):
            continue
        spheres = [c for c in link.findall("collision") if c.find("geometry/sphere") is not None]
        for first, second in zip(spheres[::2], spheres[1::2]):
            ends = [np.array(s.find("origin").get("xyz").split(), dtype=float) for s in (first, second)]
            radius = float(first.find("geometry/sphere").get("radius"))
            capsules.append((int(name.removeprefix("panda_link")), ends[1], ends[0], radius))
    return capsules


def test_panda_capsules_are_frankas_published_model():
    robot = load_robot("panda")
    ours = robot.collision.capsules
    theirs = _franka_capsules()
    assert len(ours) == len(theirs)
    for capsule, (link, a, b, radius) in zip(ours, theirs):
        assert capsule.frame == link
        ends = sorted([tuple(capsule.a), tuple(capsule.b)])
        assert np.allclose(ends, sorted([tuple(a), tuple(b)]), atol=PLACEMENT_TOL)
        assert capsule.radius == pytest.approx(PANDA_BASE_RADIUS if link == 0 else radius, abs=PLACEMENT_TOL)


def _stl_vertices(path: Path) -> np.ndarray:
    data = path.read_bytes()
    count = struct.unpack("<I", data[80:84])[0]
    facets = np.frombuffer(data[84:84 + 50 * count], dtype=np.dtype([("n", "<3f4"), ("v", "<9f4"), ("a", "<u2")]))
    return np.unique(facets["v"].reshape(-1, 3).astype(float), axis=0)


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip((points - a) @ ab / max(ab @ ab, 1e-300), 0.0, 1.0)
    return np.linalg.norm(a + t[:, None] * ab - points, axis=1)


def test_panda_capsules_enclose_its_collision_meshes():
    """Every vertex of link0..link7's collision STL lies inside the union of the capsules, at
    random configurations (a capsule of another link may cover part of a link: Franka's model
    puts the upper arm's tube on link3's capsule, around joint 3's axis)."""
    robot = load_robot("panda")
    meshes = [_stl_vertices(_erd() / "meshes" / "collision" / f"link{i}.stl") for i in range(8)]
    rng = np.random.default_rng(SEED)
    for q in rng.uniform(robot.qmin, robot.qmax, size=(CONFIGURATIONS // 4, robot.n)):
        frames = robot.frames(q)
        placed = [(frames[c.frame][:3, :3] @ np.array(c.a) + frames[c.frame][:3, 3],
                   frames[c.frame][:3, :3] @ np.array(c.b) + frames[c.frame][:3, 3], c.radius)
                  for c in robot.collision.capsules]
        for link, vertices in enumerate(meshes):
            world = vertices @ frames[link][:3, :3].T + frames[link][:3, 3]
            outside = np.min([_segment_distance(world, a, b) - r for a, b, r in placed], axis=0)
            assert outside.max() <= 0.0, f"link{link}: a vertex {outside.max() * 1e3:.1f} mm outside"


# Drake's iiwa14_primitive_collision.urdf (links 0-5: cylinder origin xyz, rpy, length, radius)
# and iiwa14_spheres_collision.urdf (links 6, 7: sphere centre, radius), m
DRAKE_IIWA14 = {0: ((-0.015, 0, 0.07), (0, 0, 0), 0.17, 0.139), 1: ((0, -0.014, 0.14), (0, 0, 0), 0.29, 0.101),
                2: ((0, 0.056, 0.035), (np.pi / 2, 0, 0), 0.29, 0.101), 3: ((0, 0.025, 0.137), (0, 0, 0), 0.29, 0.092),
                4: ((0, 0.056, 0.025), (np.pi / 2, 0, 0), 0.25, 0.092), 5: ((0, 0.03, 0.13), (-0.3, 0, 0), 0.29, 0.07),
                6: ((0, -0.01623589495, 0.00748218906), None, 0.0, 0.06341754633),
                7: ((0, -0.001260393754, -0.001625199191), None, 0.0, 0.05285650291)}
# The robot file rounds the spheres' radii up to 0.1 mm.
RADIUS_ROUNDING = 1e-4  # m


def test_iiwa14_capsules_are_drakes_primitives_at_their_links():
    """Each capsule, placed by armgen's DH frames, sits where Drake's shape sits on the URDF link
    frame Pinocchio computes (tests/data/iiwa14_drake_inertials.urdf: Drake's kinematics)."""
    from test_bundled_inertials import IIWA14_URDF

    robot = load_robot("iiwa14")
    model = pin.buildModelFromUrdf(str(IIWA14_URDF))
    data = model.createData()
    for q in np.random.default_rng(SEED).uniform(robot.qmin, robot.qmax, size=(10, robot.n)):
        pin.framesForwardKinematics(model, data, q)
        frames = robot.frames(q)
        for capsule in robot.collision.capsules:
            link = data.oMf[model.getFrameId(f"iiwa_link_{capsule.frame}")]
            centre, rpy, length, radius = DRAKE_IIWA14[capsule.frame]
            axis = pin.rpy.rpyToMatrix(*rpy)[:, 2] if rpy is not None else np.zeros(3)
            theirs = [link.act(np.array(centre) + side * length / 2 * axis) for side in (-1, 1)]
            pose = frames[capsule.frame]
            ours = [pose[:3, :3] @ np.array(end) + pose[:3, 3] for end in (capsule.a, capsule.b)]
            assert np.allclose(sorted(map(tuple, ours)), sorted(map(tuple, theirs)), atol=PLACEMENT_TOL)
            assert radius <= capsule.radius <= radius + RADIUS_ROUNDING


@pytest.mark.parametrize("name", ["iiwa14", "panda"])
def test_named_configurations_are_free_of_self_collision(name):
    """coal's distance of every checked pair (the ignore pairs of the file left out) at each of
    the robot file's configurations is positive, and equals armgen's to 1e-9 m."""
    robot = load_robot(name)
    assert robot.has_collision and robot.configurations
    pairs = robot.collision.self_pairs()
    for label, q in robot.configurations.items():
        frames = robot.frames(np.asarray(q))
        shapes = [_coal_capsule(frames[c.frame][:3, :3] @ np.array(c.a) + frames[c.frame][:3, 3],
                                frames[c.frame][:3, :3] @ np.array(c.b) + frames[c.frame][:3, 3], c.radius)
                  for c in robot.collision.capsules]
        theirs = np.array([coal.distance(*shapes[i], *shapes[j], REQUEST, coal.DistanceResult()) for i, j in pairs])
        assert theirs.min() > 0, f"{name} {label}: pair {pairs[int(np.argmin(theirs))]} at {theirs.min():.4f} m"
        assert np.abs(robot.collision_distances(np.asarray(q))[:len(pairs)] - theirs).max() <= PLACEMENT_TOL


@pytest.mark.parametrize("name", ["modular8", "planar3", "snake12"])
def test_arms_without_published_geometry_have_no_capsules(name):
    assert not load_robot(name).has_collision
