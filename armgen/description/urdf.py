"""URDF import: the serial chain from a base link to a tip link as armgen joints.

What the kinematics and the dynamics need is read: per ``<link>`` its ``name`` and
``<inertial>`` (``<origin xyz rpy>``, ``<mass value>``, ``<inertia ixx ixy ixz iyy iyz
izz>``), and per ``<joint>`` its ``name``, ``type``, ``<parent link>``, ``<child link>``,
``<origin xyz rpy>``, ``<axis xyz>`` and ``<limit lower upper velocity effort>``; per link on the
chain its ``<collision>`` shapes, as capsules (sphere and capsule exactly, cylinder and box
enclosed, a mesh marked: ``docs/collision.md``). Visual data are ignored.

Rules (see ``docs/urdf.md``):

- ``revolute``, ``continuous`` and ``prismatic`` joints on the chain become armgen joints;
  ``fixed`` joints are folded into the next joint's origin (or into the tool transform when
  they follow the last moving joint).
- ``floating`` and ``planar`` joints and ``<mimic>`` on the chain are rejected; joints off
  the chain (e.g. gripper fingers) are only checked for well-formedness.
- A revolute or prismatic joint needs ``<limit lower upper>`` with lower < upper, a
  revolute joint's within ±``MAX_REVOLUTE_LIMIT_RAD`` (URDF angles are radians: limits
  written in degrees are refused, not read as dozens of turns); a continuous joint gets
  ``[-CONTINUOUS_LIMIT, CONTINUOUS_LIMIT]`` unless a robot file bounds it under ``[limits]``.
  ``<limit velocity>`` is the speed limit (absent or 0: none; a robot file may replace it
  and add an acceleration limit, which a URDF cannot hold).
- The base link defaults to the tree's root, the tip link to the end of the chain when the
  tree does not branch below the base. Branches that lead only through fixed joints to leaf
  frames (a camera or sensor frame beside the arm) are ignored where another branch moves;
  any other branching is an error naming the branching link and the leaf links below it.
- Each moving joint's body is its child link with every link fixed to it (through fixed
  joints, on the chain or beside it: a flange, a hand, a camera), lumped into one inertial
  expressed in the joint's link frame (the child link frame times the axis alignment of
  :func:`~armgen.description.frames.axis_alignment`). Links before the first moving joint
  and links beyond a moving joint off the chain carry no dynamics. A moving joint's child
  link without ``<inertial>``, a body of mass 0 or a lumped tensor no body has leaves the
  robot without dynamics (``UrdfChain.no_dynamics`` says why); a fixed link without
  ``<inertial>`` is massless. ``<limit effort>`` is the torque limit (absent or 0: none).
- DOCTYPE and entity declarations are refused before parsing (no entity expansion).

Every failure is one :class:`~armgen.errors.RobotFileError` naming the file and element.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import RobotFileError, excerpt
from ..schemas import IDENTIFIER_PATTERN
from .collision import CollisionCapsule
from .frames import axis_alignment, rpy_matrix, snap_quarter_turn
from .inertia import inertia_matrix, inertia_problem, inertia_six, lump
from .model import (MAX_ABS_ANGLE_RAD, MAX_ABS_LENGTH_M, MAX_INERTIA_KGM2, MAX_MASS_KG, MAX_REVOLUTE_LIMIT_RAD,
                    MAX_TORQUE, MIN_JOINT_RATE, Inertial)
from .schema import MAX_DOF

# Default range of a continuous joint (rad): one full turn about zero. Criteria and planners
# need finite limits; bound the joint in a robot file's [limits] table to change it.
CONTINUOUS_LIMIT = math.pi
DEGREE = math.pi / 180.0  # rad

MOVING_TYPES = ("revolute", "continuous", "prismatic")
UNSUPPORTED_TYPES = ("floating", "planar")
URDF_JOINT_TYPES = MOVING_TYPES + ("fixed",) + UNSUPPORTED_TYPES

_DECLARATION = re.compile(r"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)
# The robot-file bounds hold for URDF robots too: a moving joint's name is an identifier (it
# names the joint in the generated C and the CSV columns), at most MAX_DOF moving joints on
# the chain, origins within MAX_ABS_LENGTH_M / MAX_ABS_ANGLE_RAD, prismatic limits within
# MAX_ABS_LENGTH_M and revolute ones within MAX_REVOLUTE_LIMIT_RAD, speed limits from
# MIN_JOINT_RATE. Link and fixed joint names only appear in messages: any text up to this length.
MAX_URDF_NAME_CHARS = 256
_IDENTIFIER = re.compile(IDENTIFIER_PATTERN)


@dataclass(frozen=True)
class UrdfJoint:
    """One moving joint of the chain, SI units.

    ``origin`` is the fixed transform from the previous moving joint's frame (or the base
    link) to this joint's frame, including any fixed joints in between; ``axis`` is the unit
    joint axis in this joint's frame.
    """

    name: str
    type: str  # "revolute", "continuous" or "prismatic"
    origin: np.ndarray  # 4x4
    axis: tuple[float, float, float]
    qlim: tuple[float, float]
    qdlim: float = math.inf  # <limit velocity> (rad/s, m/s); inf when absent or 0
    taumax: float = math.inf  # <limit effort> (N·m, N); inf when absent or 0
    inertial: Inertial | None = None  # the lumped body it moves, in its link frame; None: not known


@dataclass(frozen=True)
class UrdfCollision:
    """One ``<collision>`` of a link on the chain: its capsule (in the link's frame index and
    that frame's coordinates), or None for a mesh."""

    link: str
    capsule: CollisionCapsule | None


@dataclass(frozen=True)
class UrdfChain:
    """The chain from ``base_link`` to ``tip_link``; ``tip`` is the fixed transform from
    the last moving joint's frame to the tip link. ``link_frames`` maps every link of the
    chain's bodies to (frame index: 0 base, i joint i's link frame; the link's pose in it)."""

    robot_name: str
    base_link: str
    tip_link: str
    joints: tuple[UrdfJoint, ...]
    tip: np.ndarray  # 4x4
    no_dynamics: str = ""  # why a joint's body has no inertial ("" when every joint's has one)
    collision: tuple[UrdfCollision, ...] = ()
    link_frames: dict[str, tuple[int, np.ndarray]] = field(default_factory=dict)


@dataclass(frozen=True)
class _RawJoint:
    name: str
    type: str
    parent: str
    child: str
    element: ET.Element


class _Parser:
    def __init__(self, source: str):
        self.source = source

    def fail(self, where: str, message: str) -> RobotFileError:
        return RobotFileError(f"{self.source}: {where}: {message}")

    def name(self, element: ET.Element, where: str) -> str:
        value = element.get("name")
        if not value or not value.strip():
            raise self.fail(where, f"<{element.tag}> has no 'name' attribute; add name=\"…\"")
        if len(value) > MAX_URDF_NAME_CHARS:
            raise self.fail(where, f"<{element.tag} name=\"{excerpt(value)}\"> is longer than {MAX_URDF_NAME_CHARS} "
                                   "characters; give a shorter name")
        return value

    def numbers(self, element: ET.Element | None, attribute: str, where: str, count: int,
                default: tuple[float, ...] | None) -> tuple[float, ...]:
        text = None if element is None else element.get(attribute)
        if text is None:
            if default is None:
                tag = "element" if element is None else f"<{element.tag}>"
                raise self.fail(where, f"{tag} needs attribute '{attribute}'")
            return default
        parts = text.split()
        try:
            values = tuple(float(p) for p in parts)
        except ValueError:
            raise self.fail(where, f"<{element.tag} {attribute}=\"{excerpt(text)}\"> must be {count} numbers") from None
        if len(values) != count:
            raise self.fail(where, f"<{element.tag} {attribute}=\"{excerpt(text)}\"> must be {count} numbers, "
                                   f"got {len(values)}")
        if not all(math.isfinite(v) for v in values):
            raise self.fail(where, f"<{element.tag} {attribute}=\"{excerpt(text)}\"> must be finite numbers")
        return values

    def link_of(self, joint: ET.Element, tag: str, where: str) -> str:
        found = joint.findall(tag)
        if len(found) != 1:
            raise self.fail(where, f"needs exactly one <{tag} link=\"…\"/>, found {len(found)}")
        link = found[0].get("link")
        if not link:
            raise self.fail(where, f"<{tag}> has no 'link' attribute")
        return link


def parse_urdf(text: str, source: str, base_link: str | None = None, tip_link: str | None = None) -> UrdfChain:
    """Parse URDF text and extract the serial chain from ``base_link`` to ``tip_link``.

    Parameters
    ----------
    text
        The URDF document.
    source
        The file name used in error messages.
    base_link, tip_link
        The chain's ends; None infers them (the tree's root; the end of an unbranched chain).

    Raises
    ------
    RobotFileError
        On malformed XML, a DOCTYPE or entity declaration, a missing or unknown element or
        attribute, a non-finite number, a loop, an unsupported joint on the chain or an
        ambiguous tip.
    """
    p = _Parser(source)
    root = _robot_element(p, text)
    robot_name = p.name(root, "<robot>")
    tree = _read_tree(p, root)
    base_link = _base_link(p, tree, base_link)
    tip_link = _tip_link(p, tree, base_link, tip_link)
    path = _chain_path(p, tree, base_link, tip_link)
    joints, tip = _moving_joints(p, path)
    if not joints:
        raise p.fail("tip_link", f"no revolute, continuous or prismatic joint between '{base_link}' and '{tip_link}'")
    moving = [r for r in path if r.type != "fixed"]
    bodies = [_body(p, tree, raw, joint) for raw, joint in zip(moving, joints)]
    link_frames = _link_frames(p, tree, base_link, moving, joints)
    collision = tuple(shape for link, (frame, pose) in link_frames.items()
                      for shape in _link_collisions(p, tree, link, frame, pose))
    missing = next((reason for _, reason in bodies if reason), "")
    if missing:  # the dynamics need every body: none at all rather than some
        return UrdfChain(robot_name, base_link, tip_link, joints, tip, no_dynamics=missing, collision=collision,
                         link_frames=link_frames)
    return UrdfChain(robot_name, base_link, tip_link,
                     tuple(replace(joint, inertial=inertial) for joint, (inertial, _) in zip(joints, bodies)), tip,
                     collision=collision, link_frames=link_frames)


@dataclass(frozen=True)
class _Tree:
    links: dict[str, ET.Element]
    joints: dict[str, _RawJoint]
    parent_joint: dict[str, _RawJoint]  # child link -> the joint that moves it
    children: dict[str, list[_RawJoint]]


def _robot_element(p: _Parser, text: str) -> ET.Element:
    if _DECLARATION.search(text):
        raise p.fail("file", "DOCTYPE/ENTITY declarations are not accepted in URDF; remove them")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise p.fail("file", f"not well-formed XML ({exc})") from None
    if root.tag != "robot":
        raise p.fail("file", f"root element is <{root.tag}>, expected <robot>")
    return root


def _read_links(p: _Parser, root: ET.Element) -> dict[str, ET.Element]:
    links: dict[str, ET.Element] = {}
    for element in root.findall("link"):
        name = p.name(element, "<link>")
        if name in links:
            raise p.fail(f"link '{excerpt(name)}'", "defined twice; link names must be unique")
        links[name] = element
    if not links:
        raise p.fail("<robot>", "no <link> elements")
    return links


def _read_tree(p: _Parser, root: ET.Element) -> _Tree:
    tree = _Tree(_read_links(p, root), {}, {}, {})
    for element in root.findall("joint"):
        raw = _read_joint(p, element, tree)
        tree.joints[raw.name] = raw
        tree.parent_joint[raw.child] = raw
        tree.children.setdefault(raw.parent, []).append(raw)
    return tree


def _read_joint(p: _Parser, element: ET.Element, tree: _Tree) -> _RawJoint:
    name = p.name(element, "<joint>")
    where = f"joint '{excerpt(name)}'"
    if name in tree.joints:
        raise p.fail(where, "defined twice; joint names must be unique")
    jtype = element.get("type")
    if jtype not in URDF_JOINT_TYPES:
        raise p.fail(where, f"type {excerpt(repr(jtype))} is not a URDF joint type ({', '.join(URDF_JOINT_TYPES)})")
    parent, child = p.link_of(element, "parent", where), p.link_of(element, "child", where)
    for role, link in (("parent", parent), ("child", child)):
        if link not in tree.links:
            raise p.fail(where, f"{role} link '{link}' is not defined; add <link name=\"{link}\"/> or fix the name")
    if parent == child:
        raise p.fail(where, f"parent and child are both '{parent}' (a loop)")
    if child in tree.parent_joint:
        raise p.fail(where, f"link '{child}' already has parent joint '{tree.parent_joint[child].name}'; "
                            "a URDF must be a tree (no loops, one parent per link)")
    return _RawJoint(name, jtype, parent, child, element)


def _base_link(p: _Parser, tree: _Tree, base_link: str | None) -> str:
    """``base_link`` checked, or the tree's one root link when it is None."""
    roots = sorted(set(tree.links) - set(tree.parent_joint))
    if not roots:
        raise p.fail("<robot>", "every link has a parent joint: the joints form a loop")
    if base_link is None:
        if len(roots) > 1:
            raise p.fail("<robot>", f"several root links ({', '.join(roots)}); choose one with base_link")
        return roots[0]
    if base_link not in tree.links:
        raise p.fail("base_link", f"link '{base_link}' is not defined in the file")
    return base_link


def _tip_link(p: _Parser, tree: _Tree, base_link: str, tip_link: str | None) -> str:
    """``tip_link`` checked, or the end of the chain below ``base_link`` when it is None."""
    if tip_link is None:
        return _infer_tip(p, base_link, tree.children)
    if tip_link not in tree.links:
        raise p.fail("tip_link", f"link '{tip_link}' is not defined in the file")
    return tip_link


def _chain_path(p: _Parser, tree: _Tree, base_link: str, tip_link: str) -> list[_RawJoint]:
    """The joints from ``base_link`` down to ``tip_link``, fixed ones included."""
    path: list[_RawJoint] = []
    link = tip_link
    while link != base_link:
        if link not in tree.parent_joint:
            raise p.fail("tip_link", f"link '{tip_link}' is not below base link '{base_link}'")
        path.append(tree.parent_joint[link])
        link = tree.parent_joint[link].parent
        if len(path) > len(tree.joints):  # unreachable for a tree; guards against a cycle above the tip
            raise p.fail(f"link '{link}'", "the joints form a loop")
    path.reverse()
    moving = [raw for raw in path if raw.type != "fixed"]
    if len(moving) > MAX_DOF:
        raise p.fail("tip_link", f"the chain from '{excerpt(base_link)}' to '{excerpt(tip_link)}' has {len(moving)} "
                                 f"moving joints, more than {MAX_DOF}; choose a shorter chain with base_link/tip_link")
    return path


def _moving_joints(p: _Parser, path: list[_RawJoint]) -> tuple[tuple[UrdfJoint, ...], np.ndarray]:
    """(the moving joints of ``path``, each origin holding the fixed joints before it; the
    transform of the fixed joints after the last one)."""
    chain: list[UrdfJoint] = []
    pending = np.eye(4)
    for raw in path:
        where = f"joint '{excerpt(raw.name)}'"
        if raw.type in UNSUPPORTED_TYPES:
            raise p.fail(where, f"type '{raw.type}' is not supported on the chain (only revolute, continuous, "
                                "prismatic and fixed); choose base_link/tip_link to exclude it")
        if raw.element.find("mimic") is not None:
            raise p.fail(where, "<mimic> joints are not supported on the chain; choose base_link/tip_link to exclude it")
        pending = pending @ _origin(p, raw.element, where)
        if raw.type == "fixed":
            continue
        if not _IDENTIFIER.fullmatch(raw.name):
            raise p.fail(where, "a moving joint's name must be a letter then letters, digits or _ (at most 48): it "
                                "names the joint in the generated C and the CSV columns; rename the joint")
        chain.append(UrdfJoint(raw.name, raw.type, pending, _axis(p, raw, where), _limits(p, raw, where),
                               _rate_limit(p, raw, where, "velocity"), _rate_limit(p, raw, where, "effort")))
        pending = np.eye(4)
    return tuple(chain), pending


def _axis(p: _Parser, raw: _RawJoint, where: str) -> tuple[float, float, float]:
    axis = np.array(p.numbers(raw.element.find("axis"), "xyz", f"{where} <axis>", 3, (1.0, 0.0, 0.0)))
    with np.errstate(over="ignore"):
        norm = float(np.linalg.norm(axis))
    if norm == 0.0:
        raise p.fail(f"{where} <axis>", "xyz is the zero vector; give the joint's axis direction")
    if not math.isfinite(norm):
        raise p.fail(f"{where} <axis>", "xyz is so long its length overflows; give the axis as a unit vector")
    return tuple(float(v) for v in axis / norm)


def _subtree(link: str, children: dict[str, list[_RawJoint]]) -> tuple[list[str], bool]:
    """(the leaf links below ``link``, whether a moving joint is below it)."""
    leaves, moving, stack, seen = [], False, [link], {link}
    while stack:
        current = stack.pop()
        below = children.get(current, [])
        if not below:
            leaves.append(current)
        for joint in below:
            moving = moving or joint.type != "fixed"
            if joint.child not in seen:  # a tree, but never loop on a malformed one
                seen.add(joint.child)
                stack.append(joint.child)
    return sorted(leaves), moving


def _infer_tip(p: _Parser, base_link: str, children: dict[str, list[_RawJoint]]) -> str:
    """The end of the chain below ``base_link``: follow the one branch at each link. A branch
    that leads only through fixed joints to leaf frames (a sensor or camera frame beside the
    arm) is ignored where another branch moves; a real choice is an error listing the leaves."""
    tip, visited = base_link, {base_link}
    while children.get(tip):
        below = children[tip]
        if len(below) > 1:
            moving = [j for j in below if j.type != "fixed" or _subtree(j.child, children)[1]]
            if len(moving) != 1:
                leaves = _subtree(tip, children)[0]
                raise p.fail(f"link '{tip}'", f"branches into joints {', '.join(j.name for j in below)}, leading to "
                                              f"the leaf links {', '.join(leaves)}; choose the chain's end with "
                                              f"tip_link (e.g. tip_link = \"{leaves[0]}\")")
            below = moving
        tip = below[0].child
        if tip in visited:
            raise p.fail(f"link '{tip}'", "the joints form a loop")
        visited.add(tip)
    return tip


def _origin(p: _Parser, element: ET.Element, where: str) -> np.ndarray:
    origins = element.findall("origin")
    if len(origins) > 1:
        raise p.fail(where, f"has {len(origins)} <origin> elements; give one")
    origin = origins[0] if origins else None
    xyz = p.numbers(origin, "xyz", f"{where} <origin>", 3, (0.0, 0.0, 0.0))
    rpy = p.numbers(origin, "rpy", f"{where} <origin>", 3, (0.0, 0.0, 0.0))
    for attribute, values, bound, unit in (("xyz", xyz, MAX_ABS_LENGTH_M, "m"), ("rpy", rpy, MAX_ABS_ANGLE_RAD, "rad")):
        if max(abs(v) for v in values) > bound:
            raise p.fail(f"{where} <origin>", f"{attribute} = {' '.join(f'{v:g}' for v in values)} is beyond "
                                              f"±{bound:g} {unit} (URDF is in m and rad); check the value")
    out = np.eye(4)
    out[:3, :3] = rpy_matrix(*[snap_quarter_turn(v) for v in rpy])
    out[:3, 3] = xyz
    return out


def _limits(p: _Parser, raw: _RawJoint, where: str) -> tuple[float, float]:
    if raw.type == "continuous":
        return (-CONTINUOUS_LIMIT, CONTINUOUS_LIMIT)
    limit = raw.element.find("limit")
    if limit is None:
        raise p.fail(where, f"a {raw.type} joint needs <limit lower=\"…\" upper=\"…\"/>")
    (lower,) = p.numbers(limit, "lower", f"{where} <limit>", 1, None)
    (upper,) = p.numbers(limit, "upper", f"{where} <limit>", 1, None)
    if not lower < upper:
        raise p.fail(f"{where} <limit>", f"lower = {lower} is not below upper = {upper}")
    if raw.type == "prismatic" and max(abs(lower), abs(upper)) > MAX_ABS_LENGTH_M:
        raise p.fail(f"{where} <limit>", f"lower = {lower:g}, upper = {upper:g} reach beyond ±{MAX_ABS_LENGTH_M:g} m; "
                                         "check the values (URDF is in m and rad)")
    if raw.type == "revolute" and max(abs(lower), abs(upper)) > MAX_REVOLUTE_LIMIT_RAD:
        raise p.fail(f"{where} <limit>", _revolute_limit_message(lower, upper))
    return (lower, upper)


def _revolute_limit_message(lower: float, upper: float) -> str:
    """Why revolute limits beyond ``MAX_REVOLUTE_LIMIT_RAD`` are refused, and the fix: URDF
    angles are radians, and limits written in degrees read as radians protect nothing."""
    message = (f"lower = {lower:g}, upper = {upper:g} reach beyond ±{MAX_REVOLUTE_LIMIT_RAD:.4g} rad (two turns "
               "either side of zero, more than any arm's joint turns): URDF angles are radians")
    if max(abs(lower), abs(upper)) * DEGREE <= MAX_REVOLUTE_LIMIT_RAD:
        message += (f"; if these are degrees, write lower=\"{lower * DEGREE:.6g}\" upper=\"{upper * DEGREE:.6g}\" "
                    "(rad)")
    return message


# What each <limit> rate attribute limits, its unit, and the smallest value that is no unit slip.
_RATE_ATTRIBUTES = {"velocity": ("speed limit", "rad/s or m/s", MIN_JOINT_RATE, math.inf),
                    "effort": ("torque limit", "N·m or N", 0.0, MAX_TORQUE)}


def _rate_limit(p: _Parser, raw: _RawJoint, where: str, attribute: str) -> float:
    """``<limit velocity>`` (the joint's speed limit) or ``<limit effort>`` (its torque or
    force limit). Absent or 0 (a common exporter placeholder) means unlimited."""
    what, unit, smallest, largest = _RATE_ATTRIBUTES[attribute]
    limit = raw.element.find("limit")
    if limit is None or limit.get(attribute) is None:
        return math.inf
    (value,) = p.numbers(limit, attribute, f"{where} <limit>", 1, None)
    if value < 0:
        raise p.fail(f"{where} <limit>", f"{attribute} = {value} is negative; give the {what} (≥ 0, 0 = none)")
    if 0 < value < smallest:
        raise p.fail(f"{where} <limit>", f"{attribute} = {value:g} is below {smallest:g} (URDF {what}s are {unit}): a "
                                         "unit slip; check the value (0 = none)")
    if value > largest:
        raise p.fail(f"{where} <limit>", f"{attribute} = {value:g} is beyond {largest:g} {unit}, more than any drive "
                                         "gives; check the value (0 = none)")
    return value if value > 0 else math.inf


def _link_inertial(p: _Parser, tree: _Tree, link: str) -> tuple[float, np.ndarray, np.ndarray] | None:
    """A link's ``<inertial>`` as (mass, centre of mass, 3×3 tensor about it) in the link
    frame (SI, the ``<origin>`` rotation applied); None when it has none."""
    where = f"link '{excerpt(link)}' <inertial>"
    found = tree.links[link].findall("inertial")
    if not found:
        return None
    if len(found) > 1:
        raise p.fail(where, f"{len(found)} <inertial> elements; give one")
    element = found[0]
    origin = _origin(p, element, where)
    for tag, example in (("mass", 'value="…" (kg)'), ("inertia", 'ixx="…" iyy="…" izz="…" ixy="…" ixz="…" iyz="…" (kg·m²)')):
        if element.find(tag) is None:
            raise p.fail(where, f"needs <{tag} {example}/>; add it, or remove the <inertial> of a massless link")
    (mass,) = p.numbers(element.find("mass"), "value", f"{where} <mass>", 1, None)
    if not 0 <= mass <= MAX_MASS_KG:
        raise p.fail(f"{where} <mass>", f"value = {mass:g} is outside [0, {MAX_MASS_KG:g}] kg (URDF masses are kg); "
                                        "check the value")
    inertia = element.find("inertia")
    six = [p.numbers(inertia, key, f"{where} <inertia>", 1, None)[0] for key in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")]
    if max(abs(v) for v in six) > MAX_INERTIA_KGM2:
        raise p.fail(f"{where} <inertia>", f"a value is beyond {MAX_INERTIA_KGM2:g} kg·m² (URDF inertias are kg·m²); "
                                           "check the values")
    rotation = origin[:3, :3]
    return mass, origin[:3, 3], rotation @ inertia_matrix(six) @ rotation.T


def _body(p: _Parser, tree: _Tree, raw: _RawJoint, joint: UrdfJoint) -> tuple[Inertial | None, str]:
    """(the inertial of the body ``raw`` moves, in its link frame; "") or (None, why not).

    The body is the child link and every link fixed to it, lumped in the child link frame,
    then turned into the link frame ``child · A`` (A: the axis alignment)."""
    where = f"joint '{excerpt(raw.name)}'"
    parts, stack = [], [(raw.child, np.eye(4))]
    while stack:
        link, pose = stack.pop()  # pose: the link's frame in the child link frame
        inertial = _link_inertial(p, tree, link)
        if inertial is None and link == raw.child:
            return None, f"link '{link}' (moved by {where}) has no <inertial>"
        if inertial is not None:
            mass, com, tensor = inertial
            parts.append((mass, pose[:3, :3] @ com + pose[:3, 3], pose[:3, :3] @ tensor @ pose[:3, :3].T))
        stack.extend((fixed.child, pose @ _origin(p, fixed.element, f"joint '{excerpt(fixed.name)}'"))
                     for fixed in tree.children.get(link, []) if fixed.type == "fixed")
    if sum(mass for mass, _, _ in parts) <= 0:
        return None, f"the links {where} moves ('{raw.child}' and those fixed to it) have mass 0"
    mass, com, tensor = lump(parts)
    problem = inertia_problem(inertia_six(tensor), definite=False)
    if problem:
        return None, f"the inertia of the links {where} moves ('{raw.child}' and those fixed to it) {problem}"
    turn = axis_alignment(joint.axis)[:3, :3]  # the link frame's axes in the child link frame
    return Inertial(mass=float(mass), com=tuple(float(v) for v in turn.T @ com),
                    inertia=inertia_six(turn.T @ tensor @ turn)), ""


def _fixed_subtree(p: _Parser, tree: _Tree, link: str) -> list[tuple[str, np.ndarray]]:
    """``link`` and every link fixed to it (through fixed joints), with its pose in ``link``'s frame."""
    out, stack = [], [(link, np.eye(4))]
    while stack:
        current, pose = stack.pop()
        out.append((current, pose))
        stack.extend((fixed.child, pose @ _origin(p, fixed.element, f"joint '{excerpt(fixed.name)}'"))
                     for fixed in tree.children.get(current, []) if fixed.type == "fixed")
    return sorted(out, key=lambda item: item[0] != link)  # the link itself first, then in tree order


def _link_frames(p: _Parser, tree: _Tree, base_link: str, moving: list[_RawJoint],
                 joints: tuple[UrdfJoint, ...]) -> dict[str, tuple[int, np.ndarray]]:
    """Every link of the chain's rigid bodies: the base link and the links fixed to it (frame 0,
    the base link's frame), each moving joint's child and the links fixed to it (frame i, the
    child's frame turned by the axis alignment A: poses ``Aᵀ · pose in the child``)."""
    frames = {link: (0, pose) for link, pose in _fixed_subtree(p, tree, base_link)}
    for i, (raw, joint) in enumerate(zip(moving, joints), start=1):
        turn = axis_alignment(joint.axis).T
        frames.update({link: (i, turn @ pose) for link, pose in _fixed_subtree(p, tree, raw.child)})
    return frames


def _link_collisions(p: _Parser, tree: _Tree, link: str, frame: int, pose: np.ndarray) -> list[UrdfCollision]:
    """The link's ``<collision>`` shapes as capsules in frame ``frame`` (``pose``: the link's
    pose in it): a sphere and a capsule exactly, a cylinder enclosed by the capsule of its axis
    and radius (the caps reach r beyond its ends), a box by the capsule along its longest axis
    with the radius of its cross-section's half-diagonal; a mesh gives None."""
    shapes = []
    for k, element in enumerate(tree.links[link].findall("collision")):
        where = f"link '{excerpt(link)}' <collision> {k + 1}"
        geometry = element.find("geometry")
        shape = next(iter(geometry), None) if geometry is not None else None
        if shape is None:
            raise p.fail(where, "needs <geometry> with one of <sphere>, <cylinder>, <box>, <capsule>, <mesh>")
        if shape.tag == "mesh":
            shapes.append(UrdfCollision(link, None))
            continue
        origin = pose @ _origin(p, element, where)
        ends, radius, kind = _shape_axis(p, shape, f"{where} <{shape.tag}>")
        a, b = (origin[:3, :3] @ np.asarray(end) + origin[:3, 3] for end in ends)
        capsule = CollisionCapsule(frame=frame, a=tuple(float(v) for v in a), b=tuple(float(v) for v in b),
                                   radius=radius, link=link, origin=f"urdf {kind}")
        shapes.append(UrdfCollision(link, capsule))
    return shapes


def _shape_axis(p: _Parser, shape: ET.Element, where: str) -> tuple[tuple[tuple[float, ...], ...], float, str]:
    """(the capsule's segment ends in the shape's frame, its radius, what it is) of a URDF shape."""
    def positive(attribute: str, count: int = 1) -> tuple[float, ...]:
        values = p.numbers(shape, attribute, where, count, None)
        if min(values) < 0 or max(values) > MAX_ABS_LENGTH_M:
            raise p.fail(where, f"{attribute} must be ≥ 0 and at most {MAX_ABS_LENGTH_M:g} m (URDF is in m)")
        return values

    if shape.tag == "sphere":
        return ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)), positive("radius")[0], "sphere"
    if shape.tag in ("cylinder", "capsule"):
        radius, half = positive("radius")[0], positive("length")[0] / 2
        kind = "capsule" if shape.tag == "capsule" else "cylinder (enclosed)"
        return ((0.0, 0.0, -half), (0.0, 0.0, half)), radius, kind
    if shape.tag == "box":
        half = np.asarray(positive("size", 3)) / 2
        axis = int(np.argmax(half))
        end = np.zeros(3)
        end[axis] = half[axis]
        others = [half[k] for k in range(3) if k != axis]
        return (tuple(-end), tuple(end)), float(math.hypot(*others)), "box (enclosed)"
    raise p.fail(where, "is not a URDF collision shape; give <sphere>, <cylinder>, <box>, <capsule> or <mesh>")
