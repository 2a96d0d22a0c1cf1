#!/usr/bin/env python3
"""Collision-free inverse kinematics (issue 38): measurements, not tests.

    python benchmarks/bench_ik_collision.py [--quick] [--poses N] [--robot iiwa14] [--out FILE]

The bundled iiwa14 (7 DOF; its capsules are Drake's collision model, robots/iiwa14.toml) and
one sphere in front of its shoulder (OBSTACLE), where the plain solver's answers put the elbow
or the forearm for some poses. N poses (default 2000; --quick: 40), each the FK of a seeded
random configuration inside the limits that keeps CLEARANCE + GENERATOR_MARGIN from the sphere
and from the arm itself: every pose has a collision-free solution. Solved from the middle of
the limits, as one batch, by:

- the plain solver (``Robot.ik(..., collision_free=False)``: no collision check);
- ``Robot.ik(...)`` on the robot alone (its own capsules checked, clearance 0);
- ``Robot.ik(..., obstacles=[sphere], clearance=CLEARANCE)``.

Each answer is judged here with coal (hpp-fcl's successor, the ``test`` extra): it collides when
any checked pair (the arm's self pairs, its moving capsules against the sphere) is closer than
CLEARANCE. Reported per solver: the share of poses solved (within 1e-6 m / 1e-6 rad), the share
of the solved answers that collide (the goal: 0 for the collision-free solver), how many of those
overlap the arm with itself (a self pair below 0), and the mean
wall time per pose of the batch call (a shared machine: noisy); for the obstacle run also one
pose per call on the first ONE_BY_ONE poses. Exit 4 when coal is missing (``pip install
'.[test]'``), 1 on any error.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from armgen.description.collision import SphereObstacle  # noqa: E402
from armgen.robot import load_robot  # noqa: E402

SEED = 2038
POSES = 2000
QUICK_POSES = 40
ONE_BY_ONE = 200  # poses solved one per call (the Python call's own cost included)
QUICK_ONE_BY_ONE = 10
OBSTACLE = SphereObstacle((0.3, 0.0, 0.6), 0.15)  # m, base frame
CLEARANCE = 0.02  # m
GENERATOR_MARGIN = 0.01  # m beyond the clearance, so that every pose has a clear solution
EXIT_TOOL_MISSING = 4
WARM_UP = 64  # poses solved before the timed call: enough for the batch path (NumPy replay) to be built


def coal_least(robot, q: np.ndarray, obstacles) -> np.ndarray:
    """coal's least distance (m) per row of ``q`` over the checked pairs (self, and each moving
    capsule against each obstacle)."""
    import coal

    request = coal.DistanceRequest()
    request.gjk_tolerance = request.epa_tolerance = 1e-15

    def capsule(a: np.ndarray, b: np.ndarray, radius: float):
        axis = b - a
        length = float(np.linalg.norm(axis))
        if length == 0.0:
            return coal.Sphere(radius), coal.Transform3s(np.eye(3), a)
        z = axis / length
        x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
        x /= np.linalg.norm(x)
        return coal.Capsule(radius, length), coal.Transform3s(np.column_stack([x, np.cross(z, x), z]), 0.5 * (a + b))

    spheres = [(coal.Sphere(o.radius), coal.Transform3s(np.eye(3), np.array(o.centre))) for o in obstacles]
    capsules = robot.collision.capsules
    least = np.empty(len(q))
    for k, frames in enumerate(robot.frames(q)):
        shapes = [capsule((frames[c.frame] @ [*c.a, 1.0])[:3], (frames[c.frame] @ [*c.b, 1.0])[:3], c.radius)
                  for c in capsules]
        distances = [coal.distance(*shapes[i], *shapes[j], request, coal.DistanceResult())
                     for i, j in robot.collision.self_pairs()]
        distances += [coal.distance(*shapes[i], *sphere, request, coal.DistanceResult())
                      for i in robot.collision.moving() for sphere in spheres]
        least[k] = min(distances)
    return least


def measure(robot, poses: np.ndarray, label: str, one_by_one: int, **arguments) -> dict:
    robot.ik(poses[:WARM_UP], **arguments)  # first use: the kernel, the collision functions and their replay built
    started = time.perf_counter()
    result = robot.ik(poses, **arguments)
    batch_s = time.perf_counter() - started
    least = coal_least(robot, result.q, [OBSTACLE])
    solved = np.asarray(result.success)
    colliding = solved & (least < CLEARANCE)
    folded = solved & (coal_least(robot, result.q, []) < 0)  # the arm into itself
    row = {"solver": label, "poses": len(poses), "solved_pct": 100 * float(solved.mean()),
           "solved_colliding_pct": 100 * float(colliding.sum() / max(solved.sum(), 1)),
           "solved_colliding": int(colliding.sum()), "solved_self_overlapping": int(folded.sum()),
           "mean_batch_us_per_pose": 1e6 * batch_s / len(poses),
           "min_clearance_mm_solved": 1e3 * float(least[solved].min()) if solved.any() else None,
           "mean_iterations": float(np.mean(result.iterations))}
    if result.colliding is not None:
        row["no_clear_solution_found"] = int(np.sum(result.colliding))
    if one_by_one:
        started = time.perf_counter()
        for pose in poses[:one_by_one]:
            robot.ik(pose, **arguments)
        row["mean_single_call_us"] = 1e6 * (time.perf_counter() - started) / one_by_one
    return row


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_POSES} poses (a smoke run)")
    parser.add_argument("--poses", type=int, default=None)
    parser.add_argument("--robot", default="iiwa14", help="a 7-DOF robot with capsules (default: the bundled iiwa14)")
    parser.add_argument("--out", type=Path, default=None,
                        help="results JSON (default benchmarks/results/ik_collision.json; none for --quick)")
    args = parser.parse_args()
    try:
        import coal  # noqa: F401
    except ImportError:
        print("NOT MEASURED: coal is missing (the judge of every answer): pip install '.[test]'")
        return EXIT_TOOL_MISSING
    count = args.poses or (QUICK_POSES if args.quick else POSES)
    one_by_one = QUICK_ONE_BY_ONE if args.quick else ONE_BY_ONE
    robot = load_robot(args.robot)
    if not robot.has_collision:
        raise SystemExit(f"robot '{robot.name}' has no collision capsules: give a robot file with [[collision]]")

    rng = np.random.default_rng(SEED)
    q = np.empty((0, robot.n))
    while len(q) < count:  # configurations clear of the sphere and of the arm: each pose has a clear solution
        draw = rng.uniform(robot.qmin, robot.qmax, (2 * count, robot.n))
        keep = robot.collision_distances(draw, [OBSTACLE]).min(axis=-1) >= CLEARANCE + GENERATOR_MARGIN
        q = np.vstack([q, draw[keep]])
    poses = robot.fk(q[:count])

    rows = [measure(robot, poses, "plain (collision_free=False)", 0, collision_free=False),
            measure(robot, poses, "robot alone (self pairs, clearance 0)", 0),
            measure(robot, poses, f"with the sphere, clearance {CLEARANCE * 1e3:g} mm", one_by_one,
                    obstacles=[OBSTACLE], clearance=CLEARANCE)]
    print(f"robot {robot.name}: {len(robot.collision.capsules)} capsules, {len(robot.collision.self_pairs())} self "
          f"pairs; sphere centre {list(OBSTACLE.centre)} m radius {OBSTACLE.radius} m; {count} poses (seed {SEED}); "
          f"an answer collides when coal measures a pair below {CLEARANCE * 1e3:g} mm")
    print("| solver | poses | solved | solved but colliding | of them the arm into itself | mean per pose (batch) "
          "| one pose per call |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for row in rows:
        single = f"{row['mean_single_call_us'] / 1e3:.2f} ms" if "mean_single_call_us" in row else "—"
        print(f"| {row['solver']} | {row['poses']} | {row['solved_pct']:.2f} % | {row['solved_colliding_pct']:.2f} % "
              f"({row['solved_colliding']}) | {row['solved_self_overlapping']} | {row['mean_batch_us_per_pose'] / 1e3:.3f} ms "
              f"| {single} |")
    clear = rows[-1]
    print(f"success with the obstacle against the plain solver: {clear['solved_pct']:.2f} % vs {rows[0]['solved_pct']:.2f} %"
          f"; no clear solution found for {clear['no_clear_solution_found']} poses")
    out = args.out or (None if args.quick else REPO / "benchmarks" / "results" / "ik_collision.json")
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps({"robot": robot.name, "seed": SEED, "obstacle": {"centre": list(OBSTACLE.centre),
                                   "radius": OBSTACLE.radius}, "clearance_m": CLEARANCE, "rows": rows,
                                   "machine": platform.platform(), "python": platform.python_version()},
                                  indent=2) + "\n", encoding="utf-8")
        print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
