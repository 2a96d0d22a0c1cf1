"""The robot: the description (:mod:`armgen.description`), its models and NumPy kinematics on them.

:class:`Robot` is a :class:`~armgen.description.RobotDescription` (joints, limits, base, tool,
configurations) plus the models derived from it and the methods that evaluate them: forward
kinematics, Jacobians, the redundancy criteria, the inverse kinematics and, for a robot with
inertials, the rigid-body dynamics (docs/dynamics.md) and, for a robot with capsules, the
collision distances and criterion (docs/collision.md). The models (the
symbolic model of :mod:`armgen.symbolic` with its IK definition, the NumPy evaluators) are
built on first use and held here, never by the description, which stays plain data. This
module sits above the symbolic core, which takes the description and never this module
(Pinocchio's split: a model, and algorithms on it). :func:`load_robot`, :func:`parse_robot`
and :meth:`Robot.from_urdf` read a description and return it as a :class:`Robot`.

The description's public names (``Joint``, ``rpy_matrix``, ``matrix_rpy``, ``BUNDLED_DIR``,
``bundled_robots``, ``resolve_robot_path``, ``describe``) stay importable from here.
"""

from __future__ import annotations

import math
from dataclasses import astuple, dataclass, fields
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
from numpy.typing import ArrayLike

from .description import (BUNDLED_DIR, Joint, RobotDescription, bundled_robots, describe, load_description,
                          matrix_rpy, parse_description, read_urdf, resolve_robot_path, rpy_matrix)
from .description.collision import BoxObstacle, CapsuleObstacle, Obstacle, PlaneObstacle, SphereObstacle
from .description.model import MAX_ABS_LENGTH_M
from .errors import excerpt

if TYPE_CHECKING:
    from .codegen.api_kernel import ApiKernel
    from .symbolic.model import SymbolicModel
    from .symbolic.numeric import NumericModel
    from .symbolic.replay import BatchFunction

__all__ = ["BUNDLED_DIR", "Joint", "Robot", "bundled_robots", "describe", "load_robot", "load_robot_any",
           "matrix_rpy", "parse_robot", "resolve_robot_path", "rpy_matrix"]


class Robot(RobotDescription):
    """A serial robot, SI units: joints, base and tool transforms, named configurations, and
    NumPy kinematics on them.

    Load one with :func:`armgen.load_robot` (bundled name, robot TOML or URDF) or
    :meth:`Robot.from_urdf`. The NumPy methods (:meth:`fk`, :meth:`jacobian`, …) take ``q``
    of shape ``(n,)`` or ``(..., n)`` and evaluate a batch in one vectorised pass; named
    configurations are attributes (``robot.q0``). The fields are those of
    :class:`~armgen.description.RobotDescription`; the models derived from them
    (:attr:`symbolic`, the NumPy evaluators) are built on first use and kept by the robot, not
    pickled (a copy sent to a worker process rebuilds them).
    """

    @classmethod
    def from_description(cls, description: RobotDescription) -> Robot:
        """The same description with the NumPy methods (itself when it already is a Robot)."""
        if isinstance(description, cls):
            return description
        return cls(**{f.name: getattr(description, f.name) for f in fields(description) if f.init})

    @classmethod
    def from_urdf(cls, path: str | Path, base_link: str | None = None, tip_link: str | None = None) -> Robot:
        """Read the serial chain from ``base_link`` to ``tip_link`` of a URDF file
        (:func:`armgen.description.read_urdf`: parameters, result and errors)."""
        return cls.from_description(read_urdf(path, base_link, tip_link))

    def __getstate__(self) -> dict[str, Any]:
        # The description's fields only: the models hold CasADi SX functions, which do not
        # pickle, and are rebuilt on first use.
        return {f.name: self.__dict__[f.name] for f in fields(self)}

    # -- the models, built on first use (the symbolic layer is imported then, so that loading
    # a robot needs no CasADi) -----------------------------------------------------------
    @cached_property
    def symbolic(self) -> SymbolicModel:
        """The symbolic model (:class:`armgen.symbolic.model.SymbolicModel`): every function as
        a ``casadi.Function`` (``symbolic.function("fk")``) and the IK definition
        (``symbolic.ik_definition``), the ones the NumPy methods evaluate."""
        from .symbolic.model import SymbolicModel

        return SymbolicModel(self)

    @cached_property
    def _kernel(self) -> ApiKernel | None:
        """The compiled kernel the NumPy methods call (docs/api.md, "The compiled kernel"), or
        None: they run on the CasADi reference (``ARMGEN_KERNEL=reference``, or no C compiler)."""
        from .codegen.api_kernel import load_api_kernel

        return load_api_kernel(self.symbolic)

    @property
    def _evaluator(self) -> ApiKernel | NumericModel:
        """What evaluates the criteria: the compiled kernel, else the CasADi reference."""
        kernel = self._kernel
        return kernel if kernel is not None else self._numeric

    @cached_property
    def _numeric(self) -> NumericModel:
        from .symbolic.numeric import NumericModel

        return NumericModel(self.symbolic)

    @cached_property
    def _frames(self) -> BatchFunction:
        """(q) → the base, joint and tool frames stacked (4 (n + 2) × 4), replayed in NumPy."""
        import casadi as ca

        from .symbolic.kinematics import chain
        from .symbolic.replay import BatchFunction

        symbols = ca.SX.sym("q", self.n)
        _, joint_frames, tool = chain(self, symbols)
        stacked = ca.vertcat(*[ca.densify(frame) for frame in [ca.SX(ca.DM(self.base)), *joint_frames, tool]])
        return BatchFunction(ca.Function("frames", [symbols], [stacked], ["q"], ["T"]))

    # -- NumPy evaluation (vectorised over leading batch axes) -------------------------

    def fk(self, q: ArrayLike) -> np.ndarray:
        """Tool pose in the base frame.

        Parameters
        ----------
        q
            Joint values (rad / m), shape ``(n,)`` or ``(..., n)``.

        Returns
        -------
        numpy.ndarray
            Homogeneous transforms, shape ``(4, 4)`` or ``(..., 4, 4)``.
        """
        kernel = self._kernel
        return kernel.fk(q) if kernel is not None else self._numeric.evaluate("fk", q)["T"]

    def frames(self, q: ArrayLike) -> np.ndarray:
        """The base frame, the frame after each joint and the tool pose, in the base frame: the
        chain :meth:`fk` ends in, for drawing the links (consecutive frame origins).

        After joint i is the DH frame i of a DH robot, and the joint's child frame (turned so
        that z is the joint axis) of a URDF robot; its origin lies on the joint's axis.

        Parameters
        ----------
        q
            Joint values (rad / m), shape ``(n,)`` or ``(..., n)``.

        Returns
        -------
        numpy.ndarray
            Homogeneous transforms, shape ``(n + 2, 4, 4)`` or ``(..., n + 2, 4, 4)``; the last
            is :meth:`fk`'s tool pose.
        """
        q = np.asarray(q, dtype=float)
        if q.ndim == 0 or q.shape[-1] != self.n:
            raise ValueError(f"q must have shape ({self.n},) or (..., {self.n}) for robot '{self.name}', got {q.shape}")
        batch_shape = q.shape[:-1]
        samples = q.reshape(-1, self.n)
        (stacked,) = self._frames([np.ascontiguousarray(samples.T)], samples.shape[0])
        # column-major (4 (n + 2)) × 4 entries per sample → (samples, n + 2, 4, 4)
        count = self.n + 2
        return stacked.reshape(4, count, 4, -1).transpose(3, 1, 2, 0).reshape(batch_shape + (count, 4, 4))

    def jacobian(self, q: ArrayLike) -> np.ndarray:
        """Geometric Jacobian: rows ``[v; ω]`` of the tool origin in the base frame.

        Parameters
        ----------
        q
            Joint values, shape ``(n,)`` or ``(..., n)``.

        Returns
        -------
        numpy.ndarray
            Shape ``(6, n)`` or ``(..., 6, n)`` (all six rows, whatever ``task_rows`` says).
        """
        kernel = self._kernel
        return kernel.jacobian(q) if kernel is not None else self._numeric.evaluate("jacobian", q)["J"]

    def fk_jacobian(self, q: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`fk` and :meth:`jacobian` in one pass (shared trigonometry)."""
        kernel = self._kernel
        if kernel is not None:
            return kernel.fk_jacobian(q)
        out = self._numeric.evaluate("fk_jacobian", q)
        return out["T"], out["J"]

    def manipulability(self, q: ArrayLike, delta: float = 0.0) -> np.ndarray:
        """Manipulability ``w = sqrt(det(J Jᵀ) + δ²)`` on the task rows.

        Parameters
        ----------
        q
            Joint values, shape ``(n,)`` or ``(..., n)``.
        delta
            Regularisation ``δ`` (0: Yoshikawa's measure).

        Returns
        -------
        numpy.ndarray
            Shape ``()`` or ``(...)``.
        """
        return self._evaluator.evaluate("manipulability", q, delta=delta)["w"]

    def manipulability_gradient(self, q: ArrayLike, delta: float = 0.0) -> np.ndarray:
        """Gradient of :meth:`manipulability` with respect to ``q``, shape ``(n,)`` or ``(..., n)``.
        Use ``delta > 0`` near singular poses, where ``w`` is not differentiable."""
        return self._evaluator.evaluate("manipulability", q, delta=delta)["grad_w"]

    def joint_limit_criterion(self, q: ArrayLike) -> np.ndarray:
        """Zghal's joint-limit criterion ``H_L = Σ (q_max − q_min)² / ((q_max − q)(q − q_min))``,
        shape ``()`` or ``(...)``; ``2n`` at mid-range, growing without bound at a limit."""
        return self._evaluator.evaluate("zghal", q)["H_L"]

    def joint_limit_gradient(self, q: ArrayLike) -> np.ndarray:
        """Gradient of :meth:`joint_limit_criterion`, shape ``(n,)`` or ``(..., n)``."""
        return self._evaluator.evaluate("zghal", q)["grad_H_L"]

    def repetitive_criterion(self, q: ArrayLike, q_init: ArrayLike) -> np.ndarray:
        """Repetitive criterion ``H_R = ½‖q − q_init‖²``, shape ``()`` or ``(...)``."""
        return self._evaluator.evaluate("repetitive", q, q_init=q_init)["H_R"]

    def repetitive_gradient(self, q: ArrayLike, q_init: ArrayLike) -> np.ndarray:
        """Gradient of :meth:`repetitive_criterion` (``q − q_init``), shape ``(n,)`` or ``(..., n)``."""
        return self._evaluator.evaluate("repetitive", q, q_init=q_init)["grad_H_R"]

    def joint_manipulability(self, q: ArrayLike, weights: ArrayLike | None = None,
                             delta: float = 0.0) -> dict[str, np.ndarray]:
        """Joint manipulability (spec 30): the manipulability left when joint i locks.

        Parameters
        ----------
        q
            Joint values, shape ``(n,)`` or ``(..., n)``.
        weights
            The ``a_i`` of ``H_M = Σ a_i ω_i`` (default all 1).
        delta
            Regularisation ``δ`` of ``ω_i = sqrt(det(J₋ᵢ J₋ᵢᵀ) + δ²)``.

        Returns
        -------
        dict
            ``omega`` ``(..., n)``, ``H_M`` ``(...)`` and ``grad_H_M`` ``(..., n)``.
        """
        a = np.ones(self.n) if weights is None else weights
        return self._evaluator.evaluate("joint_manipulability", q, a=a, delta=delta)

    # -- dynamics (docs/dynamics.md): a robot with every link's inertial (has_dynamics) ---------

    def gravity_torques(self, q: ArrayLike) -> np.ndarray:
        """Gravity torques ``g(q)``: the joint torques that hold the arm still at ``q``.

        Parameters
        ----------
        q
            Joint values (rad / m), shape ``(n,)`` or ``(..., n)``.

        Returns
        -------
        numpy.ndarray
            N·m (N for a prismatic joint), shape ``(n,)`` or ``(..., n)``.

        Raises
        ------
        armgen.errors.RobotFileError
            The robot has no inertials (:attr:`has_dynamics` is False).
        """
        return self._dynamics("gravity", q)["tau"]

    def rnea(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike) -> np.ndarray:
        """Inverse dynamics ``τ = M(q) q̈ + C(q, q̇) q̇ + g(q)`` (recursive Newton–Euler).

        ``q``, ``dq`` (rad/s, m/s) and ``ddq`` (rad/s², m/s²) have shape ``(n,)`` or ``(..., n)``
        and broadcast against each other; returns τ with the broadcast shape. Raises
        :class:`~armgen.errors.RobotFileError` for a robot without inertials.
        """
        return self._dynamics("rnea", q, dq=dq, ddq=ddq)["tau"]

    def mass_matrix(self, q: ArrayLike) -> np.ndarray:
        """Joint-space mass matrix ``M(q)`` (composite rigid body; motor inertias on the
        diagonal), shape ``(n, n)`` or ``(..., n, n)``, symmetric positive definite. Raises
        :class:`~armgen.errors.RobotFileError` for a robot without inertials."""
        return self._dynamics("mass_matrix", q)["M"]

    def coriolis(self, q: ArrayLike, dq: ArrayLike) -> np.ndarray:
        """Coriolis and centrifugal torques ``c = C(q, q̇) q̇``, shape ``(n,)`` or ``(..., n)``
        (``q`` and ``dq`` broadcast). Raises :class:`~armgen.errors.RobotFileError` for a robot
        without inertials."""
        return self._dynamics("coriolis", q, dq=dq)["c"]

    def _dynamics(self, name: str, q: ArrayLike, **rates: ArrayLike) -> dict[str, np.ndarray]:
        """Evaluate dynamic function ``name``; ``q`` and the rates broadcast to one batch shape."""
        from .symbolic.dynamics import require_dynamics

        require_dynamics(self)
        arrays = {"q": np.asarray(q, dtype=float), **{k: np.asarray(v, dtype=float) for k, v in rates.items()}}
        for label, value in arrays.items():
            if value.ndim == 0 or value.shape[-1] != self.n:
                raise ValueError(f"{label} must have shape ({self.n},) or (..., {self.n}) for robot '{self.name}', "
                                 f"got {value.shape}")
        try:
            shaped = dict(zip(arrays, np.broadcast_arrays(*arrays.values())))
        except ValueError:
            shapes = ", ".join(f"{k} {v.shape}" for k, v in arrays.items())
            raise ValueError(f"{name}: the shapes {shapes} do not broadcast to one batch") from None
        return self._evaluator.evaluate(name, shaped.pop("q"), **shaped)

    # -- collision (docs/collision.md): a robot with capsules (has_collision) -------------------

    def collision_pairs(self) -> list[tuple[str, str]]:
        """What each entry of :meth:`collision_distances` is: ``("capsule 2", "capsule 5")``, then
        ``("capsule 3", "box 0")`` … (self pairs, then each moving capsule against each obstacle slot)."""
        return self.collision.pair_labels()

    def collision_distances(self, q: ArrayLike, obstacles: Sequence[Obstacle] = ()) -> np.ndarray:
        """Signed distances (m; negative when overlapping) of the checked pairs at ``q``.

        Parameters
        ----------
        q
            Joint values, shape ``(n,)`` or ``(..., n)``.
        obstacles
            :class:`~armgen.description.collision.SphereObstacle`, ``CapsuleObstacle``,
            ``BoxObstacle``, ``PlaneObstacle`` (SI, base frame), at most the robot's slots per
            kind; the slots left over report a distance of ``INACTIVE_DISTANCE``.

        Returns
        -------
        numpy.ndarray
            Shape ``(pairs,)`` or ``(..., pairs)``, in the order of :meth:`collision_pairs`.

        Raises
        ------
        armgen.errors.RobotFileError
            The robot has no usable capsules (:attr:`has_collision` is False).
        """
        return self._collision("collision_distances", q, obstacles)["d"]

    def collision_criterion(self, q: ArrayLike, obstacles: Sequence[Obstacle] = (), *, clearance: float = 0.0,
                            activation: float) -> dict[str, np.ndarray]:
        """The collision criterion ``H_C`` (a barrier on the distances below ``activation``,
        docs/collision.md) and its gradient: ``{"H_C": (...), "grad_H_C": (..., n)}``.
        ``clearance`` < ``activation`` (m); other arguments as :meth:`collision_distances`."""
        if not (math.isfinite(clearance) and math.isfinite(activation) and clearance < activation):
            raise ValueError(f"collision_criterion: clearance = {clearance!r} must be below activation = "
                             f"{activation!r} (both finite, m)")
        return self._collision("collision_criterion", q, obstacles, clearance=clearance, activation=activation)

    def _collision(self, name: str, q: ArrayLike, obstacles: Sequence[Obstacle], **scalars: float) -> dict[str, np.ndarray]:
        from .description.collision import obstacle_parameters
        from .symbolic.collision import require_collision

        require_collision(self)
        q = np.asarray(q, dtype=float)
        parameters = obstacle_parameters(obstacles, self.collision.slots)
        kernel = self._kernel
        if kernel is not None or q.ndim != 1:  # the kernel, and a batch, take each matrix as its column-major entries
            parameters = {k: v.reshape(-1, order="F") for k, v in parameters.items()}
        return (kernel or self._numeric).evaluate(name, q, **parameters, **scalars)

    def within_limits(self, q: ArrayLike) -> np.ndarray:
        """True where every joint value is finite and inside ``[qmin, qmax]``.

        Parameters
        ----------
        q
            Joint values, shape ``(n,)`` or ``(..., n)``.

        Returns
        -------
        numpy.ndarray
            Booleans of shape ``()`` or ``(...)``.
        """
        q = np.asarray(q, dtype=float)
        if q.ndim == 0 or q.shape[-1] != self.n:
            raise ValueError(f"q must have shape (n,) or (..., n) with n = {self.n}, got {q.shape}")
        return np.all((q >= self.qmin) & (q <= self.qmax), axis=-1)

    def ik(self, pose: ArrayLike, q0: ArrayLike | None = None, *, seed: str | ArrayLike | None = None,
           tol_position: float | None = None, tol_orientation: float | None = None, max_iterations: int | None = None,
           obstacles: Sequence[Obstacle] = (), clearance: float = 0.0, activation: float | None = None,
           collision_free: bool = True):
        """Joint values that put the tool at ``pose`` (inverse kinematics, ``docs/ik.md``).

        Damped least squares (Levenberg–Marquardt) on the pose error over the robot's task
        rows, clamped to the joint limits, with deterministic restarts; the same operations as
        the generated ``<p>_ik``.

        Parameters
        ----------
        pose
            Target tool pose(s) in the base frame: a 4×4 homogeneous matrix or ``(..., 4, 4)``.
        q0
            A configuration to stay near, ``(n,)`` or ``(..., n)``: the self-motion of a
            redundant arm then minimises ``½‖q − q0‖²`` (default: the Zghal distance from the
            limits), and the first attempt starts from it unless ``seed`` is given.
        seed
            The first attempt's start: a named configuration or joint values (default: ``q0``,
            else the middle of the limits). Without ``q0`` the start is first turned about the
            first joint's axis toward the target when both reach out from that axis
            (docs/ik.md, Method).
        tol_position, tol_orientation
            Success thresholds (m, rad; default 1e-6 each; above 0 and at most
            :data:`MAX_TOL_POSITION` / :data:`MAX_TOL_ORIENTATION`, 0.01).
        max_iterations
            Stop after this many steps (an int, 1 to the default,
            ``armgen.symbolic.ik.MAX_ITERATIONS``): a bound on the time a solve takes, at the
            price of more misses. It bounds the collision search's steps too (whose solves from
            other starts then do not run: each needs a whole ``max_iterations``).
        obstacles
            :class:`~armgen.description.collision.SphereObstacle`, ``CapsuleObstacle``,
            ``BoxObstacle``, ``PlaneObstacle`` (SI, base frame) the solution must keep clear of.
        clearance
            The least distance (m) a solution keeps between the arm's checked capsule pairs and
            from each obstacle. A robot with capsules is checked against itself even without
            obstacles (docs/ik.md, "Collision-free solutions"); a solution closer than this is
            moved along the arm's self-motion, else searched for from other starts, and when none
            is found ``success`` is False and ``colliding`` True.
        activation
            The distance (m, > ``clearance``) below which the collision criterion pushes the
            pairs apart during that search (default ``clearance`` + 0.05 m).
        collision_free
            False: the plain solver, no collision check (no ``obstacles`` then).

        Returns
        -------
        armgen.symbolic.ik.IKResult
            ``q`` (the solution, or the closest configuration reached), ``success``,
            ``position_error``, ``orientation_error``, ``iterations``, and for a checked robot
            ``clearance`` (the least distance at ``q``) and ``colliding``; arrays with the pose's
            batch shape for a batch. ``reason`` says why a pose was not solved.

        Raises
        ------
        TypeError
            A pose, ``q0`` or ``seed`` that does not hold real numbers (text, complex, bool), a
            tolerance that is no number, a ``max_iterations`` that is no int (or a bool).
        ValueError
            A pose that is not a finite homogeneous transform with a rotation part (or has an
            entry beyond ±1000 m), a ``q0``/``seed`` of the wrong size, a tolerance outside
            its range, a ``max_iterations`` outside its range, a ``clearance`` or ``activation``
            that is not a finite length with ``0 ≤ clearance < activation``, more obstacles of a
            kind than the robot's slots.
        armgen.errors.RobotFileError
            ``obstacles`` or a ``clearance`` for a robot without capsules.
        """
        from .symbolic import ik

        targets, batch_shape = _pose_targets(pose)
        checked = self._ik_collision_settings(obstacles, clearance, activation, collision_free)
        cap = _iteration_cap(max_iterations, ik.MAX_ITERATIONS)
        tol_p = _tolerance(tol_position, "tol_position", ik.TOL_POSITION, MAX_TOL_POSITION, "m")
        tol_o = _tolerance(tol_orientation, "tol_orientation", ik.TOL_ORIENTATION, MAX_TOL_ORIENTATION, "rad")
        kernel = self._kernel
        if q0 is not None:
            rest = self._joints_per_pose(q0, "q0", batch_shape)
        else:
            qmid = kernel.qmid if kernel is not None else self.qmid  # (the kernel's copy: computed once)
            rest = qmid[None] if not batch_shape else np.broadcast_to(qmid, (targets.shape[0], self.n))
        if isinstance(seed, str):
            start = self._joints_per_pose(self.configuration(seed), f"seed '{seed}'", batch_shape)
        elif seed is not None:
            start = self._joints_per_pose(seed, "seed", batch_shape)
        else:
            start = rest
        use_rest = 0.0 if q0 is None else 1.0
        q, pos, ori, iterations, success = self._ik_outputs(targets, start, rest, use_rest, tol_p, tol_o, cap)
        if checked is None:  # the plain solver: nothing to check
            return ik.IKResult(q.T.reshape(batch_shape + (self.n,)), success.reshape(batch_shape) != 0,
                               pos.reshape(batch_shape), ori.reshape(batch_shape),
                               iterations.reshape(batch_shape).astype(int))
        search = _CollisionFreeSearch(self, targets, np.broadcast_to(rest, (len(targets), self.n)), use_rest,
                                      (tol_p, tol_o, cap, None if max_iterations is None else cap), *checked)
        found = search.run(q.T.copy(), success.reshape(-1) != 0, pos.reshape(-1), ori.reshape(-1),
                           iterations.reshape(-1).astype(int))
        return ik.IKResult(found.q.reshape(batch_shape + (self.n,)), found.success.reshape(batch_shape),
                           found.position_error.reshape(batch_shape), found.orientation_error.reshape(batch_shape),
                           found.iterations.reshape(batch_shape), found.clearance.reshape(batch_shape),
                           found.colliding.reshape(batch_shape))

    def _ik_outputs(self, targets: np.ndarray, start: np.ndarray, rest: np.ndarray, use_rest: float, tol_p: float,
                    tol_o: float, cap: int) -> list[np.ndarray]:
        """The solver (the compiled kernel's ``<p>_ik``, else the reference) on ``targets`` (B, 4, 4)
        from ``start`` with ``rest`` (B, n): q, position and orientation errors, iterations, success, each (rows, B)."""
        from .symbolic import ik

        kernel = self._kernel
        if kernel is not None:
            outputs = kernel.ik(targets, start, rest, use_rest, tol_p, tol_o, cap)
            if not outputs[3].all():  # an attempt of 0 iterations: <p>_ik found no pose (BAD_TARGET)
                ik.check_targets(targets)  # the reference's check, and its error naming what is wrong
            return outputs
        return ik.solve(self.symbolic.ik_definition, targets, np.ascontiguousarray(start), np.ascontiguousarray(rest),
                        use_rest, tol_p, tol_o, cap)

    def _ik_collision_settings(self, obstacles: Sequence[Obstacle], clearance: object, activation: object,
                               collision_free: bool) -> tuple[tuple[Obstacle, ...], float, float] | None:
        """(obstacles, clearance, activation) the IK's solutions are checked against, or None when
        nothing is checked (``collision_free`` False, or a robot without capsules given neither
        obstacles nor a clearance)."""
        from .description.collision import obstacle_parameters
        from .symbolic.collision import require_collision

        if isinstance(obstacles, (str, bytes)) or not isinstance(obstacles, Sequence):
            raise TypeError(f"obstacles must be a sequence of SphereObstacle, CapsuleObstacle, BoxObstacle or "
                            f"PlaneObstacle, got {excerpt(repr(obstacles))}")
        obstacles = tuple(obstacles)
        for k, obstacle in enumerate(obstacles):
            if type(obstacle) not in _OBSTACLE_TYPES:
                raise TypeError(f"obstacles: {excerpt(repr(obstacle))} is no obstacle; give SphereObstacle, "
                                "CapsuleObstacle, BoxObstacle or PlaneObstacle (armgen.description.collision)")
            values = _real_array(np.concatenate([np.ravel(v) for v in astuple(obstacle)]), f"obstacles[{k}]")
            if not (np.isfinite(values).all() and (np.abs(values) <= MAX_ABS_LENGTH_M).all()):
                raise ValueError(f"obstacles[{k}] ({type(obstacle).__name__}) holds a value that is not finite or is "
                                 f"beyond ±{MAX_ABS_LENGTH_M:g} (m, rad), far out of any arm's reach: give it in metres")
        clearance = _length(clearance, "clearance")
        if not collision_free:
            if obstacles or clearance or activation is not None:
                raise ValueError("ik: obstacles, clearance and activation need collision_free=True (the default)")
            return None
        if not self.has_collision and not obstacles and not clearance and activation is None:
            return None
        require_collision(self)
        activation = clearance + DEFAULT_ACTIVATION_BAND if activation is None else _length(activation, "activation")
        if not activation > clearance:
            raise ValueError(f"activation = {activation!r} m must be beyond clearance = {clearance!r} m: the "
                             "collision criterion acts between them")
        obstacle_parameters(obstacles, self.collision.slots)  # more of a kind than slots: its ValueError
        return obstacles, clearance, activation

    def _joints_per_pose(self, value: ArrayLike, what: str, batch_shape: tuple[int, ...]) -> np.ndarray:
        """``value`` (``(n,)`` or the poses' ``(..., n)``) as one row of joint values per pose."""
        value = _real_array(value, what)
        if value.ndim == 0 or value.shape[-1] != self.n or not np.all(np.isfinite(value)):
            raise ValueError(f"{what} must hold {self.n} finite joint values for robot '{self.name}' "
                             f"(shape ({self.n},) or (..., {self.n})), got shape {value.shape}")
        if not batch_shape and value.ndim == 1:
            return value[None]  # one pose (what broadcast_to gives, without its cost)
        try:
            return np.broadcast_to(value, batch_shape + (self.n,)).reshape(-1, self.n)
        except ValueError:
            raise ValueError(f"{what} of shape {value.shape} does not fit the poses' batch shape {batch_shape}: "
                             f"give shape ({self.n},) or {batch_shape + (self.n,)}") from None


# The largest success thresholds Robot.ik takes: a solution farther than 1 cm or 0.01 rad
# (0.6°) from the pose is not at it (a tool's accuracy is far below a millimetre); a larger
# tolerance would report success for poses out of reach.
MAX_TOL_POSITION = 1e-2
MAX_TOL_ORIENTATION = 1e-2


def _real_array(value: ArrayLike, what: str) -> np.ndarray:
    """``value`` as a float array; anything but real numbers (text, complex, bool, objects)
    is a TypeError rather than silently converted."""
    array = np.asarray(value)
    if array.dtype.kind not in "iuf":
        raise TypeError(f"{what} must hold real numbers (int or float), got an array of dtype {array.dtype}")
    return array.astype(float, copy=False)  # read only by the callers: a float array is used as it is


def _pose_targets(pose: ArrayLike) -> tuple[np.ndarray, tuple[int, ...]]:
    """(the poses as a ``(size, 4, 4)`` stack, their batch shape)."""
    pose = _real_array(pose, "pose")
    if pose.ndim < 2 or pose.shape[-2:] != (4, 4):
        raise ValueError(f"pose must have shape (4, 4) or (..., 4, 4), got {pose.shape}")
    targets = pose.reshape(-1, 4, 4)
    if not (np.abs(targets) <= MAX_ABS_LENGTH_M).all() and \
            np.max(np.abs(np.where(np.isfinite(targets), targets, 0.0)), initial=0.0) > MAX_ABS_LENGTH_M:
        raise ValueError(f"pose: an entry is beyond ±{MAX_ABS_LENGTH_M:g} (m), far out of any arm's reach; "
                         "give the position in metres")
    return targets, pose.shape[:-2]


def _iteration_cap(value: object, limit: int) -> int:
    """``max_iterations``: ``limit`` for None, else an int from 1 to ``limit``."""
    cap = limit if value is None else value
    if isinstance(cap, (bool, np.bool_)) or not isinstance(cap, (int, np.integer)):
        raise TypeError(f"max_iterations must be an integer (not a bool), got {excerpt(repr(value))}")
    if not 1 <= cap <= limit:
        raise ValueError(f"max_iterations must be an integer from 1 to {limit}, got {value!r}")
    return int(cap)


def _tolerance(value: object, what: str, default: float, bound: float, unit: str) -> float:
    """A success threshold: the default for None, else a real number in (0, ``bound``]."""
    if value is None:
        return default
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{what} must be a number ({unit}), got {excerpt(repr(value))}")
    if not 0.0 < float(value) <= bound:
        raise ValueError(f"{what} = {value!r} {unit}: give a tolerance above 0 and at most {bound:g} {unit} (a larger "
                         "one would call a pose out of reach solved)")
    return float(value)


def _length(value: object, what: str) -> float:
    """A clearance or activation distance: a real number from 0 to MAX_ABS_LENGTH_M (m)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{what} must be a number (m), got {excerpt(repr(value))}")
    if not 0.0 <= float(value) <= MAX_ABS_LENGTH_M:
        raise ValueError(f"{what} = {value!r} m: give a distance from 0 to {MAX_ABS_LENGTH_M:g} m")
    return float(value)


_OBSTACLE_TYPES = (SphereObstacle, CapsuleObstacle, BoxObstacle, PlaneObstacle)
# The collision criterion's band above the clearance while the IK moves a colliding solution
# apart (m): the pairs within 5 cm of the clearance push, so a step clears the nearest pair
# without running into the next one.
DEFAULT_ACTIVATION_BAND = 0.05
# The search for a collision-free solution (docs/ik.md, "Collision-free solutions"; measured
# on the 475 of bench_ik_collision.py's 2 000 poses whose plain answer collides):
# - each step moves the arm along its self-motion by REPAIR_STEP rad on the joint that moves
#   most, at most REPAIR_STEPS steps (up to 2 rad of self-motion: an elbow swung to the other
#   side of an obstacle): 0.1 rad × 20 solved all 475 at 1.3 ms a pose, 0.05 × 40 as many at
#   3.3 ms (twice the polishing solves);
# - a step that does not widen the least distance by REPAIR_PROGRESS (m) ends the repair (the
#   self-motion cannot help: a limit holds it, or the pair lies beyond the null space);
# - POLISH_ITERATIONS: the solver's steps that bring each moved configuration back onto the
#   pose (one attempt's);
# - FALLBACK_STARTS further solves from the solver's restart sequence (points beyond its own
#   ATTEMPTS), each repaired the same way, for a pose whose first solution's branch collides
#   (the repair alone solved 388 of the 475; fresh starts alone 463 with 8 of them, 475 with 30,
#   but their answers lie a median 3.2 rad from the solver's, this search's 0.7: the repair
#   comes first, so that an answer stays near the caller's seed or q0).
REPAIR_STEP = 0.1
REPAIR_STEPS = 20
REPAIR_PROGRESS = 1e-6
POLISH_ITERATIONS = 15
FALLBACK_STARTS = 8
# Without the compiled kernel (ARMGEN_KERNEL=reference, no C compiler): from this many
# configurations on the collision functions run as one NumPy replay (a fixed ~5–8 ms for a
# 7-DOF arm with the default slots), below it one CasADi call each (~0.25 ms).
REPLAY_FROM = 32


@dataclass
class _Found:
    """The collision-free search's answer per pose (flat over the batch)."""

    q: np.ndarray
    success: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    iterations: np.ndarray
    clearance: np.ndarray
    colliding: np.ndarray


class _CollisionFreeSearch:
    """Solutions of :meth:`Robot.ik` clear of the arm itself and of the obstacles (docs/ik.md,
    "Collision-free solutions"). A converged solution closer than the clearance is moved along
    the arm's self-motion down the collision criterion's gradient, ``Δq ∝ −(I − J⁺J) ∇H_C``,
    each step brought back onto the pose by the solver (from the moved configuration, its
    self-motion held there); when that does not clear it, the pose is solved again from the
    solver's restart sequence and each answer repaired the same way. Deterministic, and a pose
    gets the answer its row of a batch gets. With a step ``budget`` (the caller's
    max_iterations) a pose takes part in a solve only while it has that solve's steps left."""

    def __init__(self, robot: Robot, targets: np.ndarray, rest: np.ndarray, use_rest: float,
                 settings: tuple[float, float, int, int | None], obstacles: tuple[Obstacle, ...], clearance: float,
                 activation: float):
        from .description.collision import obstacle_parameters

        self.robot, self.targets, self.rest, self.use_rest = robot, targets, rest, use_rest
        self.tol_position, self.tol_orientation, self.cap, self.budget = settings
        self.clearance, self.activation = clearance, activation
        self.parameters = obstacle_parameters(obstacles, robot.collision.slots)
        self.rows = list(robot.task_rows)

    def _evaluate(self, name: str, q: np.ndarray, **scalars: float) -> dict[str, np.ndarray]:
        """A collision function at the rows of ``q`` (B ≥ 1, n): the compiled kernel's, else a
        few configurations one by one through CasADi and more through the NumPy replay
        (Robot._collision's paths, without its checks)."""
        flat = {k: v.reshape(-1, order="F") for k, v in self.parameters.items()}
        kernel = self.robot._kernel
        if kernel is not None:
            return kernel.evaluate(name, q, **flat, **scalars)
        numeric = self.robot._numeric
        if len(q) < REPLAY_FROM:
            rows = [numeric.evaluate(name, row, **self.parameters, **scalars) for row in q]
            return {k: np.array([row[k] for row in rows]) for k in rows[0]}
        return numeric.evaluate(name, q, **flat, **scalars)

    def least(self, q: np.ndarray) -> np.ndarray:
        """The least distance over the checked pairs at each row of ``q`` (an empty slot's is 1000 m)."""
        if not len(q):
            return np.empty(0)
        return self._evaluate("collision_distances", q)["d"].min(axis=-1)

    def affords(self, used: np.ndarray, steps: int) -> np.ndarray:
        """Which poses, having spent ``used`` steps, may take a solve of ``steps`` more."""
        return np.ones(len(used), bool) if self.budget is None else used + steps <= self.budget

    def _solve(self, index: np.ndarray, start: np.ndarray, rest: np.ndarray, use_rest: float,
               cap: int) -> tuple[np.ndarray, ...]:
        q, pos, ori, iterations, success = self.robot._ik_outputs(self.targets[index], np.ascontiguousarray(start),
                                                                   np.ascontiguousarray(rest), use_rest,
                                                                   self.tol_position, self.tol_orientation, cap)
        return q.T, pos.reshape(-1), ori.reshape(-1), iterations.reshape(-1).astype(int), success.reshape(-1) != 0

    def repair(self, index: np.ndarray, q: np.ndarray, least: np.ndarray, pos: np.ndarray, ori: np.ndarray,
               used: np.ndarray) -> tuple[np.ndarray, ...]:
        """Move the solutions ``q`` (least distance ``least``, pose errors ``pos``, ``ori``, steps
        ``used`` so far) of poses ``index`` along the self-motion until clear: the five updated."""
        robot = self.robot
        q, least, pos, ori, used = q.copy(), least.copy(), pos.copy(), ori.copy(), used.copy()
        going = least < self.clearance
        for _ in range(REPAIR_STEPS):
            going &= self.affords(used, POLISH_ITERATIONS)
            active = np.flatnonzero(going)
            if not active.size:
                break
            gradient = self._evaluate("collision_criterion", q[active], clearance=self.clearance,
                                      activation=self.activation)["grad_H_C"]
            jacobian = robot.jacobian(q[active])[:, self.rows, :]
            # row by row: NumPy's stacked products round differently by the batch's size, and one
            # pose must get the answer its row of a batch gets
            step = -np.array([g - np.linalg.pinv(j) @ (j @ g) for j, g in zip(jacobian, gradient)])
            size = np.abs(step).max(axis=1)
            trial = np.clip(q[active] + step * (REPAIR_STEP / np.maximum(size, 1e-300))[:, None], robot.qmin, robot.qmax)
            moved, moved_pos, moved_ori, iterations, converged = self._solve(index[active], trial, trial, 1.0,
                                                                              POLISH_ITERATIONS)
            used[active] += iterations
            moved_least = np.full(len(active), -np.inf)
            moved_least[converged] = self.least(moved[converged])
            better = converged & (moved_least >= least[active] + REPAIR_PROGRESS)
            taken = active[better]
            q[taken], least[taken] = moved[better], moved_least[better]
            pos[taken], ori[taken] = moved_pos[better], moved_ori[better]
            going[active[~better]] = False  # stalled: the self-motion does not widen the gap
            going[taken] = least[taken] < self.clearance
        return q, least, pos, ori, used

    def run(self, q: np.ndarray, success: np.ndarray, pos: np.ndarray, ori: np.ndarray,
            iterations: np.ndarray) -> _Found:
        """The search from the solver's answers (flat over the batch)."""
        from .symbolic import ik

        robot = self.robot
        least = self.least(q)
        colliding = success & (least < self.clearance)
        for attempt in range(FALLBACK_STARTS + 1):
            index = np.flatnonzero(colliding)
            if attempt > 0:  # a fresh start: only the poses with its steps left
                index = index[self.affords(iterations[index], self.cap)]
            if not index.size:
                break
            if attempt == 0:  # the solver's own answers first
                start_q, start_pos, start_ori, converged = q[index], pos[index], ori[index], np.ones(len(index), bool)
                start_least = least[index]
            else:
                start = np.broadcast_to(ik.sequence_point(robot.qmin, robot.qmax, ik.ATTEMPTS + attempt),
                                        (len(index), robot.n))
                start_q, start_pos, start_ori, spent, converged = self._solve(index, start, self.rest[index],
                                                                              self.use_rest, self.cap)
                iterations[index] += spent
                start_least = np.full(len(index), -np.inf)  # a miss is no answer
                start_least[converged] = self.least(start_q[converged])
            repaired = np.flatnonzero(converged)
            (start_q[repaired], start_least[repaired], start_pos[repaired], start_ori[repaired],
             iterations[index[repaired]]) = self.repair(index[repaired], start_q[repaired], start_least[repaired],
                                                        start_pos[repaired], start_ori[repaired],
                                                        iterations[index[repaired]])
            better = start_least > least[index]  # the answer that comes least close, so far
            chosen = index[better]
            q[chosen], least[chosen] = start_q[better], start_least[better]
            pos[chosen], ori[chosen] = start_pos[better], start_ori[better]
            colliding[chosen] = least[chosen] < self.clearance
        return _Found(q, success & ~colliding, pos, ori, iterations, least, colliding)


def parse_robot(text: str, source: str, sha256: str | None = None, directory: Path | None = None) -> Robot:
    """Parse robot TOML text (:func:`armgen.description.parse_description`) into a :class:`Robot`."""
    return Robot.from_description(parse_description(text, source, sha256, directory))


def load_robot(name_or_path: str | Path) -> Robot:
    """A robot by bundled name, robot TOML path or URDF path (``.urdf``: see :meth:`Robot.from_urdf`)."""
    return Robot.from_description(load_description(name_or_path))


def load_robot_any(robot: RobotDescription | str | Path) -> Robot:
    """A :class:`Robot` from a description, a bundled name or a path."""
    return Robot.from_description(robot) if isinstance(robot, RobotDescription) else load_robot(robot)
