"""The ``rr`` fields of the planners built on a spec 30/35 path task
(:class:`armgen.planning.taskpath.PathTask`: fault_tolerant, wgpm): path, timing, CLIK."""

from __future__ import annotations

import numpy as np

from ..configuration import geometric_path, program_path
from ..literals import c_ints, c_real


def path_task_fields(path, source: str) -> dict[str, str]:
    """The values of the ``$path``, ``$clik_gain`` and ``$task_rows`` placeholders."""
    values = {"clik_gain": c_real(path.clik_gain if path.clik else 0.0), "task_rows": c_ints(path.robot.task_rows)}
    if path.motion is not None:
        return dict(values, path=program_path(path.duration))
    axis, angle = np.array([0.0, 0.0, 1.0]), 0.0
    if path.path_type == "line" and path.end_rotation is not None:  # the planner's own axis/angle
        from ...planning.backends import make_backend
        from ...planning.taskpath import TaskPath

        pose0, _ = make_backend(path.robot, "symbolic", ("fk_jacobian",)).call("fk_jacobian", path.q_start)
        line = TaskPath(path, np.asarray(pose0)).path
        axis, angle = line.axis_local, float(line.angle)
    return dict(values, path=geometric_path(path.path_type, path.via, path.end, axis, angle, path.duration, path.law,
                                            source, path.relative, path.turns))
