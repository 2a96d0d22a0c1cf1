/*
 * armgen joint controller: a C99 controller object for a redundant arm, built on the
 * kinematics armgen generates (see docs/firmware.md).
 *
 *   ctrl c;                                   one object per arm; no heap, no globals
 *   ctrl_init(&c, &config);                   -> CTRL_FAULT_NONE, state IDLE
 *   every period dt:  ctrl_tick(&c, &in, &out);   out.q / out.qd are the joint commands
 *
 * State machine:
 *
 *   IDLE --START--> RUNNING --last tick--> DONE
 *                      |  \---STOP--------> DONE
 *                      |  \---any fault-----> FAULT   (latched until ctrl_init)
 *                      \---a joint reported locked (FAULT_TOLERANT)--> DEGRADED
 *   DEGRADED behaves as RUNNING (same transitions) with the locked joints frozen.
 *   (a fault detected in IDLE or DONE, e.g. a non-finite input, also goes to FAULT)
 *
 * Modes:
 *   CTRL_MODE_RESOLVED_RATE  the Cartesian task (a circle through three points, or a line,
 *       with a rest-to-rest time law) is computed on board from a few parameters; per tick
 *       q_dot = J+ x_dot + (I - J+ J) alpha through the generated step_gpm, alpha the
 *       null-space operator of spec 20 (minimum norm, repetitive, Zghal, windowed Zghal,
 *       combined), explicit Euler, optional closed loop (CLIK). This reproduces
 *       armgen/planning/cartesian.py tick by tick. The path may instead be a program
 *       (CTRL_PATH_PROGRAM): lines, arcs, rounded corners and sampled poses with the
 *       planner's trapezoidal time law, evaluated from a const table in flash (fw_program.h);
 *       then, as the planner does, a step whose q_dot exceeds a joint's qdot_max first has
 *       its self-motion scaled (the tool's twist unchanged). Every resolved-rate mode runs it.
 *   CTRL_MODE_PLAYBACK  joint-space polynomial segments (spec 40): per joint the knot times
 *       and six coefficients per segment, evaluated by the generated fw_ptp_eval; every
 *       command is checked against qdot_max[i] (speed and the step from the previous command).
 *   CTRL_MODE_SAMPLED  a sampled joint table (e.g. a snake plan): the command of tick k is row k
 *       of a const table in flash, exactly; q_dot the forward difference to the next row / dt.
 *       The same limit and speed checks as CTRL_MODE_PLAYBACK.
 *   CTRL_MODE_FAULT_TOLERANT  spec 30: the same on-board path (circle with turns, or line),
 *       closed loop, per tick the joint-manipulability index H_M and its gradient on the
 *       healthy columns (generated ft_index), then GPM (alpha = K grad H_M), WLN (generated
 *       wln_weights, plain or smooth rule) or minimum norm, solved by the generated
 *       step_fault with the lock mask. A joint reported locked in ctrl_input.locked freezes
 *       from that tick (velocity exactly 0); reproduces planning/fault_tolerant/planner.py.
 *   CTRL_MODE_WEIGHTED_GPM  spec 35: per tick the generated step_wgpm with the task's band,
 *       repulsion, damping, criteria gains and the ramp in/out of the secondary terms;
 *       reproduces planning/wgpm/planner.py. It cannot mask a locked joint (a lock faults).
 *
 * Collision (a robot with capsules, CTRL_HAS_COLLISION, and a task with [collision]: cfg.collision):
 * every resolved-rate mode adds the planners' -gain grad H_C to its null-space term, and every
 * command of every mode (MOVE_TO and SETPOINT included) is checked against the clearance
 * (CTRL_FAULT_COLLISION); ctrl_output.clearance reports its least distance (docs/collision.md).
 *
 * Every output is finite and inside the joint limits: on a fault the controller holds the
 * last command it emitted (velocity 0) and reports the cause; it never writes NaN.
 *
 * Matrices are column-major like the generated code. Units: SI (m, rad, s).
 */
#ifndef ARMGEN_CONTROLLER_H
#define ARMGEN_CONTROLLER_H

#include <stdint.h>

#include "ctrl_robot.h"
#include "fw_program.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Playback capacity: segments per plan (a compile-time size; -DCTRL_MAX_SEGMENTS=n). */
#ifndef CTRL_MAX_SEGMENTS
#define CTRL_MAX_SEGMENTS 16
#endif
#define CTRL_NCOEF 6 /* a0..a5 of theta(tau) = sum_j a_j tau^j, tau = t - knot[k] */
/* Sampled playback: the most table rows ctrl_init accepts (-DCTRL_MAX_SAMPLES=n). The generated
 * task_params.h checks at compile time that its table fits. */
#ifndef CTRL_MAX_SAMPLES
#define CTRL_MAX_SAMPLES 65536
#endif

typedef enum {
  CTRL_STATE_IDLE = 0,    /* initialised, holding the start configuration, waiting for START */
  CTRL_STATE_RUNNING = 1, /* following the task, one tick per period */
  CTRL_STATE_DONE = 2,    /* the motion ended (or STOP): holding the last command */
  CTRL_STATE_FAULT = 3,   /* a fault latched: holding the last safe command, see ctrl_fault */
  CTRL_STATE_DEGRADED = 4 /* running with locked joints (FAULT_TOLERANT): still following the task */
} ctrl_state;

typedef enum {
  CTRL_FAULT_NONE = 0,             /* no fault */
  CTRL_FAULT_BAD_CONFIG = 1,       /* ctrl_init rejected the configuration (a non-finite or
                                      out-of-range parameter, a start outside the limits,
                                      collinear circle points, bad knots, ...) */
  CTRL_FAULT_NONFINITE_INPUT = 2,  /* the tick input holds NaN/inf (task-velocity input) */
  CTRL_FAULT_NONFINITE_OUTPUT = 3, /* a computed value (pose, gradient, joint velocity, the
                                      integrated command) is NaN/inf although every input
                                      was finite: an overflow */
  CTRL_FAULT_JOINT_LIMIT = 4,      /* the next joint command lies outside [q_min, q_max] */
  CTRL_FAULT_SINGULAR = 5,         /* a singular pose beyond the damping's reach: a joint
                                      speed above its qdot_max[i], or |J q_dot - x_dot| above the
                                      residual bound (the step could not meet the task) */
  CTRL_FAULT_OVERRUN = 6,          /* the scheduler reported a missed period (tick overrun) */
  CTRL_FAULT_TRACKING = 7,         /* the tool left the path by more than pos_err_max */
  CTRL_FAULT_PLAYBACK = 8,         /* the segment evaluator rejected the time or the knots */
  CTRL_FAULT_BAD_ARGS = 9,         /* a NULL pointer was passed (returned, not latched) */
  CTRL_FAULT_LOCK_REPORT = 10,     /* ctrl_input.locked names a joint the arm does not have, or
                                      withdraws a lock (a locked joint cannot come back) */
  CTRL_FAULT_REDUNDANCY = 11,      /* more joints locked than the mode can absorb (NDOF - NTASK
                                      in FAULT_TOLERANT; none in the other modes) */
  CTRL_FAULT_SPEED = 12,           /* playback or MOVE_TO: a commanded speed, or the step from the
                                      previous command, above the joint's qdot_max[i] (e.g. a period
                                      that does not fit the plan's knots) */
  CTRL_FAULT_UNREACHABLE = 13,     /* MOVE_TO: the on-board IK found no configuration inside the
                                      limits within its tolerances (or the build has no IK) */
  CTRL_FAULT_BAD_TARGET = 14,      /* MOVE_TO: ctrl_input.target is not a pose (its last row not
                                      0 0 0 1, or its 3x3 part no rotation: zero, scaled, sheared,
                                      mirrored); the generated IK's <P>_BAD_TARGET */
  CTRL_FAULT_TORQUE = 15,          /* a robot with inertials: the command's feed-forward torque
                                      |tau_ff_i| is above the joint's tau_max[i] (the command is not
                                      emitted; the arm holds the previous one) */
  CTRL_FAULT_STALE = 16,           /* the command stream went stale: the platform's watchdog (the
                                      host link, fw_link.h) stopped the arm and sent CTRL_CMD_STALE */
  CTRL_FAULT_COLLISION = 17        /* a robot with a collision model and a task with [collision]:
                                      the command's least checked distance (the arm to itself or to
                                      an obstacle) is below cfg.collision->clearance (the command is
                                      not emitted; the arm holds the previous one). Every mode,
                                      MOVE_TO and SETPOINT included */
} ctrl_fault;

typedef enum {
  CTRL_CMD_NONE = 0,  /* keep going */
  CTRL_CMD_START = 1, /* IDLE -> RUNNING (this tick is tick 0 of the motion) */
  CTRL_CMD_STOP = 2,  /* RUNNING -> DONE, holding the current command */
  CTRL_CMD_MOVE_TO = 3, /* IDLE or DONE -> RUNNING: to the tool pose ctrl_input.target (on-board IK,
                          then a joint-space profile within qdot_max and qddot_max); ignored
                          while moving (STOP first). START is not accepted after it (ctrl_init) */
  CTRL_CMD_MOVE_TO_JOINTS = 4, /* as MOVE_TO, to the joint target ctrl_input.q_ref (no IK) */
  CTRL_CMD_SETPOINT = 5, /* the caller's joint command for this tick, ctrl_input.q_ref / qd_ref (a
                          streamed trajectory, a controlled stop): in IDLE, DONE or while moving
                          (it takes over from the mode or a MOVE_TO), RUNNING; through the checks of
                          playback (limits, speed, the step from the previous command). A tick
                          without a setpoint after one holds (STOP: DONE). START is not accepted after */
  CTRL_CMD_STALE = 6     /* the platform's watchdog: latch STALE, holding the current command */
} ctrl_command;

typedef enum {
  CTRL_MODE_RESOLVED_RATE = 0,
  CTRL_MODE_PLAYBACK = 1,
  CTRL_MODE_FAULT_TOLERANT = 2,
  CTRL_MODE_WEIGHTED_GPM = 3,
  CTRL_MODE_SAMPLED = 4
} ctrl_mode;
typedef enum { CTRL_FT_PINV = 0, CTRL_FT_GPM = 1, CTRL_FT_WLN = 2 } ctrl_ft_method;
typedef enum { CTRL_FT_INDEX_OMEGA = 0, CTRL_FT_INDEX_RELATIVE = 1 } ctrl_ft_index;
typedef enum { CTRL_WLN_PLAIN = 0, CTRL_WLN_SMOOTH = 1 } ctrl_wln_rule;
#define CTRL_WGPM_NCRIT 4 /* criteria of step_wgpm: manipulability, joint manipulability, Zghal, condition */
typedef enum { CTRL_PATH_LINE = 0, CTRL_PATH_CIRCLE = 1, CTRL_PATH_PROGRAM = 2 } ctrl_path_type;
#if CTRL_HAS_DYNAMICS
/* The feed-forward torque of each command (a robot with inertials): none, the gravity torques
 * g(q), or the inverse dynamics M(q) qdd + C(q, qd) qd + g(q) of the command. */
typedef enum { CTRL_FF_NONE = 0, CTRL_FF_GRAVITY = 1, CTRL_FF_INVERSE_DYNAMICS = 2 } ctrl_feedforward;
#endif
typedef enum { CTRL_LAW_CUBIC = 0, CTRL_LAW_TRAPEZOIDAL = 1, CTRL_LAW_CONSTANT = 2 } ctrl_time_law;
typedef enum {
  CTRL_METHOD_PINV = 0,           /* alpha = 0 (minimum norm) */
  CTRL_METHOD_REPETITIVE = 1,     /* alpha_R */
  CTRL_METHOD_ZGHAL = 2,          /* alpha_L, always on */
  CTRL_METHOD_ZGHAL_IMPROVED = 3, /* windows * alpha_L, quadratic window ramps */
  CTRL_METHOD_COMBINED = 4        /* gamma_R alpha_R + windows * alpha_L, linear window ramps */
} ctrl_method;

/* Resolved-rate task: the path is built on board from FK(q_start) and these points, or
 * read from a program table. */
typedef struct {
  ctrl_path_type path;
  const fw_program *program; /* CTRL_PATH_PROGRAM: the program and its time law, a const table
                            (in flash; ctrl_init checks it and keeps only this pointer); else NULL */
  ctrl_real via[3];      /* circle: the second point, m (base frame) */
  ctrl_real end[3];      /* circle: the third point; line: the end point, m */
  ctrl_real rot_axis[3]; /* line: unit axis of the orientation change, in the start tool frame */
  ctrl_real rot_angle;   /* line: total orientation change about rot_axis, rad (0: hold) */
  ctrl_real duration;    /* T, s; a multiple of dt */
  ctrl_time_law law;
  ctrl_real blend;       /* trapezoidal law: fraction of T spent accelerating, (0, 0.5]; [0, 0.5] for the others */
  ctrl_method method;
  ctrl_real rho_R, T_smo_R;          /* repetitive operator gain and lambda_R ramp, s */
  ctrl_real rho_L, theta_s;          /* Zghal gain, window band from a limit (rad) */
  ctrl_real T_smo_L, T_sum_L;        /* window ramp and minimum open time, s */
  ctrl_real gamma_R_ramp;            /* combined: gamma_R ramp from T/2, s */
  int relative;          /* 1: via and end are offsets from the start position (FAULT_TOLERANT,
                            WEIGHTED_GPM; 0 in RESOLVED_RATE) */
  ctrl_real turns;       /* circle: turns over the duration (1 in RESOLVED_RATE) */
  ctrl_real clik_gain;   /* 1/s; > 0 closes the loop on position and orientation error */
  ctrl_real damping;     /* lambda for step_gpm; 0 = exact pseudo-inverse (see docs) */
  int task_rows[CTRL_NTASK]; /* which rows of [v; w] the step uses, ascending */
} ctrl_rr_config;

/* Fault tolerant (spec 30). */
typedef struct {
  ctrl_ft_method method;
  ctrl_ft_index index;       /* H_M, or H_M / w (relative) */
  ctrl_real K;               /* GPM gain */
  ctrl_real b;               /* WLN weight gain */
  ctrl_wln_rule rule;
  ctrl_real v_band;          /* smooth rule's activation band, rad/s */
  ctrl_real omega_floor;     /* WLN: omega_i floored here */
  ctrl_real delta;           /* smoothing of omega_i = sqrt(det + delta^2) */
  ctrl_real a[CTRL_NDOF];    /* weights of H_M = sum a_i omega_i */
  ctrl_real epsilon;         /* step_fault: sigma_min below which damping starts */
  ctrl_real lambda_max;      /* step_fault: the largest damping */
} ctrl_ft_config;

/* Weighted GPM (spec 35); the criteria in step_wgpm's order. */
typedef struct {
  ctrl_real band, t_rmax, delta;
  ctrl_real epsilon, rho_max;
  ctrl_real ramp_time;       /* s; 0: secondary terms on from the start */
  int ramp_out;              /* 1: they ramp out again before the end */
  ctrl_real H_lo[CTRL_WGPM_NCRIT], H_hi[CTRL_WGPM_NCRIT], k_hi[CTRL_WGPM_NCRIT];
  ctrl_real k_lo[CTRL_WGPM_NCRIT], u_th[CTRL_WGPM_NCRIT], u_band[CTRL_WGPM_NCRIT];
} ctrl_wg_config;

/* Playback: per robot joint, the segment coefficients on shared knots. */
typedef struct {
  int nseg;                                  /* 1 .. CTRL_MAX_SEGMENTS */
  int32_t n_ticks;                           /* last tick index (ticks 0 .. n_ticks) */
  ctrl_real knots[CTRL_MAX_SEGMENTS + 1];    /* s, strictly increasing */
  int active[CTRL_NDOF];                     /* 1: the joint plays its segments; 0: holds q_start */
  ctrl_real coeffs[CTRL_NDOF][CTRL_MAX_SEGMENTS * CTRL_NCOEF]; /* rad, s */
} ctrl_pb_config;

/* Sampled playback: one table row per tick. The controller keeps the pointer, not a copy (the
 * table is large: rows x NDOF reals): the table must be const data in flash (or read-only
 * memory) that never changes while the controller lives. ctrl_init validates it once (not
 * NULL, 2 .. CTRL_MAX_SAMPLES rows, every value finite, row 0 at q_start). */
typedef struct {
  const ctrl_real *table;    /* n_samples rows of CTRL_NDOF, row-major: q_i of tick k = table[k * CTRL_NDOF + i] */
  int32_t n_samples;         /* rows; ticks 0 .. n_samples - 1, one per period dt */
} ctrl_sp_config;

#if CTRL_HAS_COLLISION
/* The task's collision check (docs/collision.md, "On the board"): the generated functions bound to
 * the task's obstacle slots (task_params.h defines both bindings and this constant struct, in
 * flash), the hard minimum distance, and the criterion's settings (the planner's, SI). */
typedef struct {
  ctrl_real clearance;  /* m, >= 0: a command whose least distance is below it is the COLLISION fault */
  ctrl_real activation; /* m, > clearance: the criterion H_C acts below this distance */
  ctrl_real gain;       /* rad^2/s, >= 0: the resolved-rate modes add -gain grad H_C to their null-space
                           term, as the planners do; 0: only the check */
  /* d (CTRL_NDIST) at q: the generated collision_distances with the task's obstacle slots */
  void (*distances)(const ctrl_real *q, ctrl_real *d);
  /* H_C and grad H_C (CTRL_NDOF) at q: the generated collision_criterion with the same slots;
   * NULL when gain is 0 (never called then) */
  void (*criterion)(const ctrl_real *q, ctrl_real clearance, ctrl_real activation, ctrl_real *h, ctrl_real *grad);
} ctrl_collision;
/* ctrl_output.clearance while nothing is checked (no cfg.collision): the generated distance of
 * an inactive obstacle slot, "nothing near" */
#define CTRL_CLEARANCE_UNCHECKED CTRL_LIT(1000.0)
#endif

typedef struct {
  ctrl_mode mode;
  ctrl_real dt;                 /* tick period, s */
  ctrl_real q_start[CTRL_NDOF]; /* start configuration (and the repetitive target) */
  ctrl_real q_min[CTRL_NDOF];   /* joint limits */
  ctrl_real q_max[CTRL_NDOF];
  ctrl_real qdot_max[CTRL_NDOF]; /* speed guard per joint: max |q_dot_i|, rad/s (m/s), (0, 1e3];
                                   the robot file's qdlim where it gives one */
  ctrl_real qddot_max[CTRL_NDOF]; /* MOVE_TO acceleration per joint, rad/s^2 (m/s^2), (0, 1e4];
                                   the robot file's qddlim where it gives one. With qdot_max
                                   bounded below: MOVE_TO over the joint's whole range
                                   must take at most 2^24 ticks (docs/firmware.md, MOVE_TO) */
  ctrl_real residual_rel;       /* singular-pose guard: |J q_dot - x_dot|_inf may reach */
  ctrl_real residual_abs;       /*   residual_rel * |x_dot|_inf + residual_abs; each in [0, 1] */
  ctrl_real pos_err_max;        /* tracking guard, m, [0, 1]; 0 disables */
  ctrl_rr_config rr;            /* the path: RESOLVED_RATE, FAULT_TOLERANT, WEIGHTED_GPM */
  ctrl_pb_config pb;            /* CTRL_MODE_PLAYBACK */
  ctrl_ft_config ft;            /* CTRL_MODE_FAULT_TOLERANT */
  ctrl_wg_config wg;            /* CTRL_MODE_WEIGHTED_GPM */
  ctrl_sp_config sp;            /* CTRL_MODE_SAMPLED (points to a const table: not copied) */
#if CTRL_HAS_DYNAMICS
  ctrl_feedforward feedforward; /* what ctrl_output.tau_ff holds (CTRL_FF_NONE: zeros, no check) */
  ctrl_real tau_max[CTRL_NDOF]; /* torque limit per joint, N m (N for a prismatic joint), [0, 1e7];
                                   0: none. A command whose |tau_ff_i| exceeds it is a TORQUE fault */
#endif
#if CTRL_HAS_COLLISION
  const ctrl_collision *collision; /* the task's collision check (const data that never changes while
                                      the controller lives); NULL: none (a task without [collision]) */
#endif
} ctrl_config;

/* What the platform hands the controller every tick. */
typedef struct {
  ctrl_command command;
  ctrl_real xdot_offset[6]; /* task-velocity input [v; w] (m/s, rad/s) added to the path's,
                               e.g. an operator jog or a sensor correction; zeros if unused */
  uint32_t missed_ticks;    /* periods the scheduler missed since the previous tick */
  uint32_t locked;          /* bit i: joint i is locked (as its drive reports it); a lock is
                               permanent: clearing a reported bit is a LOCK_REPORT fault */
  ctrl_real target[16];     /* MOVE_TO: the tool pose, 4x4 homogeneous, column-major (m) */
  ctrl_real q_ref[CTRL_NDOF];  /* MOVE_TO_JOINTS: the joint target; SETPOINT: the joint command */
  ctrl_real qd_ref[CTRL_NDOF]; /* SETPOINT: the joint velocity command */
} ctrl_input;

/* What the controller hands back every tick: always finite, always inside the limits. */
typedef struct {
  uint32_t tick;              /* tick index of the motion this output belongs to */
  ctrl_real t;                /* s */
  ctrl_real q[CTRL_NDOF];     /* joint position command */
  ctrl_real qd[CTRL_NDOF];    /* joint velocity command (feed-forward); 0 while holding */
  ctrl_real pos_err;          /* |p_d - p|, m (resolved-rate) */
  ctrl_real ori_err;          /* |orientation error|, rad (resolved-rate) */
  ctrl_real window[CTRL_NDOF];/* joint-limit windows gamma_L (windowed methods) */
  uint32_t locked;            /* bit i: joint i frozen as locked */
  ctrl_state state;
  ctrl_fault fault;
#if CTRL_HAS_DYNAMICS
  ctrl_real tau_ff[CTRL_NDOF]; /* feed-forward torque of the command, N m (N): gravity(q) or
                                  rnea(q, qd, qdd) per cfg.feedforward; while holding (IDLE, DONE,
                                  FAULT) gravity(q) of the held command; zeros with CTRL_FF_NONE */
#endif
#if CTRL_HAS_COLLISION
  ctrl_real clearance;         /* m: the least checked distance of the command (the arm to itself or
                                  to the task's obstacles; negative: overlapping); while holding, the
                                  held command's. CTRL_CLEARANCE_UNCHECKED without cfg.collision */
#endif
} ctrl_output;

/* The controller object: fixed-size arrays only. Treat as opaque. */
typedef struct {
  ctrl_config cfg;            /* the validated copy ctrl_init made: later changes to the
                                 caller's configuration are never seen */
  ctrl_state state;
  ctrl_fault fault;
  uint32_t k;                 /* tick index within the motion */
  uint32_t n_ticks;           /* index of the last tick */
  ctrl_real t_hold;           /* time of the held command */
  ctrl_real q[CTRL_NDOF];     /* candidate command of tick k (integrated) */
  ctrl_real q_carry[CTRL_NDOF]; /* compensated-summation carry of the integrator */
  ctrl_real q_hold[CTRL_NDOF];  /* last emitted command (safe) */
  ctrl_real pos_err, ori_err;   /* diagnostics of the last emitted command */
  /* path, built by ctrl_init */
  ctrl_real p0[3];            /* start position */
  ctrl_real R0[9];            /* start orientation, column-major */
  ctrl_real centre[3], u[3], v[3], radius; /* circle */
  ctrl_real delta[3];         /* line: end - start */
  ctrl_real axis_world[3];    /* line: R0 * rot_axis */
  /* joint-limit windows (spec 20), one latch per joint */
  uint8_t win_state[CTRL_NDOF];
  uint16_t win_openings[CTRL_NDOF];
  ctrl_real win_value[CTRL_NDOF], win_t_event[CTRL_NDOF], win_v_event[CTRL_NDOF];
  /* fault tolerance */
  uint32_t locked;              /* bit i: joint i locked */
  ctrl_real mask[CTRL_NDOF];    /* 1 healthy, 0 locked: step_fault's column mask */
  ctrl_real qd_prev[CTRL_NDOF]; /* previous tick's command velocity (WLN plain rule) */
  /* MOVE_TO: q = mt_q0 + s(t / mt_T) mt_delta, s the trapezoid of move_to_profile */
  int moving_to;
  ctrl_real mt_q0[CTRL_NDOF], mt_delta[CTRL_NDOF], mt_T;
  int following; /* CTRL_CMD_SETPOINT: the caller's setpoints, not the mode, make the commands */
#if CTRL_HAS_COLLISION
  ctrl_real clearance; /* least checked distance of the held command (CTRL_CLEARANCE_UNCHECKED: none) */
#endif
} ctrl;

/* Validate the configuration, copy it into the controller and set up the task. Returns CTRL_FAULT_NONE (state IDLE,
 * holding q_start) or CTRL_FAULT_BAD_CONFIG (state FAULT; the held command is q_start where
 * it is finite and inside the limits, else 0: do not enable the drives). */
ctrl_fault ctrl_init(ctrl *c, const ctrl_config *config);

/* One control period. `in` may be NULL (no command, no task-velocity input). Writes `out`
 * (always finite) and returns the latched fault (CTRL_FAULT_NONE while healthy). */
ctrl_fault ctrl_tick(ctrl *c, const ctrl_input *in, ctrl_output *out);

/* Static names for logs: "IDLE", "JOINT_LIMIT", ... ("?" for an unknown value). */
const char *ctrl_state_name(ctrl_state s);
const char *ctrl_fault_name(ctrl_fault f);

#ifdef __cplusplus
}
#endif

#endif /* ARMGEN_CONTROLLER_H */
