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
 *                      \---any fault-----> FAULT   (latched until ctrl_init)
 *   (a fault detected in IDLE or DONE, e.g. a non-finite input, also goes to FAULT)
 *
 * Modes:
 *   CTRL_MODE_RESOLVED_RATE  the Cartesian task (a circle through three points, or a line,
 *       with a rest-to-rest time law) is computed on board from a few parameters; per tick
 *       q_dot = J+ x_dot + (I - J+ J) alpha through the generated step_gpm, alpha the
 *       null-space operator of spec 20 (minimum norm, repetitive, Zghal, windowed Zghal,
 *       combined), explicit Euler, optional closed loop (CLIK). This reproduces
 *       armgen/planning/cartesian.py tick by tick.
 *   CTRL_MODE_PLAYBACK  joint-space polynomial segments (spec 40): per joint the knot times
 *       and six coefficients per segment, evaluated by the generated fw_ptp_eval.
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

#ifdef __cplusplus
extern "C" {
#endif

/* Playback capacity: segments per plan (a compile-time size; -DCTRL_MAX_SEGMENTS=n). */
#ifndef CTRL_MAX_SEGMENTS
#define CTRL_MAX_SEGMENTS 16
#endif
#define CTRL_NCOEF 6 /* a0..a5 of theta(tau) = sum_j a_j tau^j, tau = t - knot[k] */

typedef enum {
  CTRL_STATE_IDLE = 0,    /* initialised, holding the start configuration, waiting for START */
  CTRL_STATE_RUNNING = 1, /* following the task, one tick per period */
  CTRL_STATE_DONE = 2,    /* the motion ended (or STOP): holding the last command */
  CTRL_STATE_FAULT = 3    /* a fault latched: holding the last safe command, see ctrl_fault */
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
                                      speed above qdot_max, or |J q_dot - x_dot| above the
                                      residual bound (the step could not meet the task) */
  CTRL_FAULT_OVERRUN = 6,          /* the scheduler reported a missed period (tick overrun) */
  CTRL_FAULT_TRACKING = 7,         /* the tool left the path by more than pos_err_max */
  CTRL_FAULT_PLAYBACK = 8,         /* the segment evaluator rejected the time or the knots */
  CTRL_FAULT_BAD_ARGS = 9          /* a NULL pointer was passed (returned, not latched) */
} ctrl_fault;

typedef enum {
  CTRL_CMD_NONE = 0,  /* keep going */
  CTRL_CMD_START = 1, /* IDLE -> RUNNING (this tick is tick 0 of the motion) */
  CTRL_CMD_STOP = 2   /* RUNNING -> DONE, holding the current command */
} ctrl_command;

typedef enum { CTRL_MODE_RESOLVED_RATE = 0, CTRL_MODE_PLAYBACK = 1 } ctrl_mode;
typedef enum { CTRL_PATH_LINE = 0, CTRL_PATH_CIRCLE = 1 } ctrl_path_type;
typedef enum { CTRL_LAW_CUBIC = 0, CTRL_LAW_TRAPEZOIDAL = 1, CTRL_LAW_CONSTANT = 2 } ctrl_time_law;
typedef enum {
  CTRL_METHOD_PINV = 0,           /* alpha = 0 (minimum norm) */
  CTRL_METHOD_REPETITIVE = 1,     /* alpha_R */
  CTRL_METHOD_ZGHAL = 2,          /* alpha_L, always on */
  CTRL_METHOD_ZGHAL_IMPROVED = 3, /* windows * alpha_L, quadratic window ramps */
  CTRL_METHOD_COMBINED = 4        /* gamma_R alpha_R + windows * alpha_L, linear window ramps */
} ctrl_method;

/* Resolved-rate task: the path is built on board from FK(q_start) and these points. */
typedef struct {
  ctrl_path_type path;
  ctrl_real via[3];      /* circle: the second point, m (base frame) */
  ctrl_real end[3];      /* circle: the third point; line: the end point, m */
  ctrl_real rot_axis[3]; /* line: unit axis of the orientation change, in the start tool frame */
  ctrl_real rot_angle;   /* line: total orientation change about rot_axis, rad (0: hold) */
  ctrl_real duration;    /* T, s; a multiple of dt */
  ctrl_time_law law;
  ctrl_real blend;       /* trapezoidal law: fraction of T spent accelerating, (0, 0.5] */
  ctrl_method method;
  ctrl_real rho_R, T_smo_R;          /* repetitive operator gain and lambda_R ramp, s */
  ctrl_real rho_L, theta_s;          /* Zghal gain, window band from a limit (rad) */
  ctrl_real T_smo_L, T_sum_L;        /* window ramp and minimum open time, s */
  ctrl_real gamma_R_ramp;            /* combined: gamma_R ramp from T/2, s */
  ctrl_real clik_gain;   /* 1/s; > 0 closes the loop on position and orientation error */
  ctrl_real damping;     /* lambda for step_gpm; 0 = exact pseudo-inverse (see docs) */
  int task_rows[CTRL_NTASK]; /* which rows of [v; w] the step uses, ascending */
} ctrl_rr_config;

/* Playback: per robot joint, the segment coefficients on shared knots. */
typedef struct {
  int nseg;                                  /* 1 .. CTRL_MAX_SEGMENTS */
  int32_t n_ticks;                           /* last tick index (ticks 0 .. n_ticks) */
  ctrl_real knots[CTRL_MAX_SEGMENTS + 1];    /* s, strictly increasing */
  int active[CTRL_NDOF];                     /* 1: the joint plays its segments; 0: holds q_start */
  ctrl_real coeffs[CTRL_NDOF][CTRL_MAX_SEGMENTS * CTRL_NCOEF]; /* rad, s */
} ctrl_pb_config;

typedef struct {
  ctrl_mode mode;
  ctrl_real dt;                 /* tick period, s */
  ctrl_real q_start[CTRL_NDOF]; /* start configuration (and the repetitive target) */
  ctrl_real q_min[CTRL_NDOF];   /* joint limits */
  ctrl_real q_max[CTRL_NDOF];
  ctrl_real qdot_max;           /* singular-pose guard: max |q_dot_i|, rad/s */
  ctrl_real residual_rel;       /* singular-pose guard: |J q_dot - x_dot|_inf may reach */
  ctrl_real residual_abs;       /*   residual_rel * |x_dot|_inf + residual_abs */
  ctrl_real pos_err_max;        /* tracking guard, m; 0 disables */
  ctrl_rr_config rr;            /* CTRL_MODE_RESOLVED_RATE */
  ctrl_pb_config pb;            /* CTRL_MODE_PLAYBACK */
} ctrl_config;

/* What the platform hands the controller every tick. */
typedef struct {
  ctrl_command command;
  ctrl_real xdot_offset[6]; /* task-velocity input [v; w] (m/s, rad/s) added to the path's,
                               e.g. an operator jog or a sensor correction; zeros if unused */
  uint32_t missed_ticks;    /* periods the scheduler missed since the previous tick */
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
  ctrl_state state;
  ctrl_fault fault;
} ctrl_output;

/* The controller object: fixed-size arrays only. Treat as opaque. */
typedef struct {
  const ctrl_config *cfg;     /* must outlive the controller (e.g. const, in flash) */
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
} ctrl;

/* Validate the configuration and set up the task. Returns CTRL_FAULT_NONE (state IDLE,
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
