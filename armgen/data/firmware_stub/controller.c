/*
 * armgen joint controller, see controller.h and docs/firmware.md.
 *
 * The resolved-rate tick mirrors armgen/planning/cartesian.py operation by operation (same
 * formulas, same order of floating-point operations where it matters), so that the double
 * build reproduces a plan to rounding level; the float build is the same code in single
 * precision.
 */
#include "controller.h"

#include <float.h>
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "fw_ptp.h"

/* The segment evaluator must be built with the controller's precision and layout. */
typedef char ctrl_check_ptp_real[(sizeof(fw_real) == sizeof(ctrl_real)) ? 1 : -1];
typedef char ctrl_check_ptp_ncoef[(FW_PTP_NCOEF == CTRL_NCOEF) ? 1 : -1];

/* Euler with compensated (Kahan) summation: q is stored in the working precision, so in
 * float each step would otherwise round q to 24 bits and the rounding errors of 10^4 steps
 * add up. The double build integrates exactly like the Python planner (plain q + h q_dot). */
#ifndef CTRL_COMPENSATED_SUM
#define CTRL_COMPENSATED_SUM CTRL_USE_FLOAT
#endif

#define N CTRL_NDOF
#define TWO_PI CTRL_LIT(6.283185307179586)
/* |n dt - T| below this fraction of T: the motion's duration is a whole number of ticks. */
#define DURATION_RTOL CTRL_LIT(1e-4)
/* The circle's three points are collinear below this (|a x b| / (|a| |b|)), as the planner. */
#define COLLINEAR_TOL CTRL_LIT(1e-6)
/* The largest guards ctrl_init accepts: a guard beyond these guards nothing (and
 * qdot_max * dt stays far from overflow). qdot_max in rad/s (m/s), residual_abs in the task's
 * units per second, pos_err_max in m; residual_rel is a fraction of the command. */
#define QDOT_MAX_LIMIT CTRL_LIT(1.0e3)
#define RESIDUAL_REL_LIMIT CTRL_LIT(1.0)
#define RESIDUAL_ABS_LIMIT CTRL_LIT(1.0)
#define POS_ERR_MAX_LIMIT CTRL_LIT(1.0)
/* A playback plan must start where the arm is: |theta(t0) - q_start| below this, rad. */
#define PLAYBACK_START_TOL CTRL_LIT(1e-5)
/* Playback (and MOVE_TO): a joint's speed may reach qdot_max, and one tick's step qdot_max * dt,
 * times (1 + this): the planners accept a plan up to 1e-9 above a limit, and a float table value
 * (or a polynomial's chord) carries a few 1e-5 of rounding relative to a step; this covers both. */
#define PLAYBACK_STEP_RTOL CTRL_LIT(1e-3)
/* MOVE_TO. The IK's tolerances: float cannot resolve 1e-6 m on a ~1 m arm (its FK carries a
 * few 1e-7 of rounding), so 5e-5 m / rad there (half the 1e-4 the target is checked to);
 * 1e-9 in double. Its iteration cap (the generated loop's full search). */
#if CTRL_USE_FLOAT
#define MOVE_TO_TOL CTRL_LIT(5e-5)
#else
#define MOVE_TO_TOL CTRL_LIT(1e-9)
#endif
/* m: a program table's first point and FK(q_start) agree to rounding (the planner built the
 * table from FK(q_start) in double: ~1e-16 m; the float FK on the M4: ~1e-7 m per metre of
 * reach); 1e-5 m is far above both and far below any other start (a table for another task). */
#define PROGRAM_START_TOL CTRL_LIT(1e-5)
#define PROGRAM_START_TOL_RAD CTRL_LIT(1e-5) /* rad, likewise for the first rotation */
#define MOVE_TO_ITERATIONS CTRL_LIT(150.0)
/* The profile accelerates over this fraction of its duration and decelerates over as much. */
#define MOVE_TO_BLEND CTRL_LIT(0.25)
/* It plans with the limits times (1 - this): the guards (qdot_max) then never see rounding. */
#define MOVE_TO_MARGIN CTRL_LIT(1e-3)
#define QDDOT_MAX_LIMIT CTRL_LIT(1.0e4)
/* The longest MOVE_TO, in ticks: 2^24, the largest count a float holds exactly, so that the float
 * build's time k dt differs at every tick (beyond it neighbouring ticks would share a time and the
 * command stand still, then jump) and the count converts to uint32_t without overflow. The double
 * build takes the same bound, so both accept the same configurations: ctrl_init refuses a qdot_max
 * or qddot_max so low, for its dt, that a MOVE_TO over the joint's whole range would take longer
 * (4.7 h at 1 kHz, 28 min at 10 kHz): the lower bound of the limits. */
#define MOVE_TO_MAX_TICKS CTRL_LIT(16777216.0)
/* The step guard of played-back commands (emit_played) allows, beyond PLAYBACK_STEP_RTOL, the
 * rounding of the two commands it compares: an ulp of each (eps |q|, eps the precision's machine
 * epsilon) and, for MOVE_TO's q0 + s delta with s from a few operations, a few eps |delta|
 * (mt_delta, 0 in the other modes); 8 eps (|q| + |q_prev| + |delta|) covers both. A slow limit at
 * a fast tick in float needs it (a step of a few ulp of q; measured at most 1e-7 rad beyond,
 * tests/test_move_to_limits.py); in double it is ~1e-15 rad. */
#define STEP_ROUNDING CTRL_LIT(8.0)
#if CTRL_USE_FLOAT
#define REAL_EPSILON FLT_EPSILON
#else
#define REAL_EPSILON DBL_EPSILON
#endif
#if CTRL_HAS_DYNAMICS
/* The largest torque limit ctrl_init accepts, N m (N): the robot files' own bound (description
 * MAX_TORQUE); beyond it a limit guards nothing. */
#define TAU_MAX_LIMIT CTRL_LIT(1.0e7)
/* A command's |tau_ff_i| may reach tau_max[i] times (1 + this) before TORQUE: the float build's
 * rnea carries up to 2e-5 of the largest torque in rounding (the verifier's FLOAT_BOUNDS), a few
 * 1e-4 of a wrist joint's small limit beside a shoulder's large torque; a plan the planner
 * accepts at its limit (to 1e-9) must not stop on that rounding. */
#define TORQUE_RTOL CTRL_LIT(1e-3)
#endif

/* The spec 30 / 35 modes need generated functions a robot may lack (e.g. without redundancy):
 * the build sets these to 0 then, and ctrl_init rejects the mode. */
#ifndef CTRL_HAS_FAULT_TOLERANT
#define CTRL_HAS_FAULT_TOLERANT 1
#endif
#ifndef CTRL_HAS_MOVE_TO
#define CTRL_HAS_MOVE_TO 1 /* the generated <p>_ik; without it MOVE_TO is UNREACHABLE */
#endif
#ifndef CTRL_HAS_WEIGHTED_GPM
#define CTRL_HAS_WEIGHTED_GPM 1
#endif

enum { WIN_IDLE = 0, WIN_RAMP_UP = 1, WIN_HOLD = 2, WIN_RAMP_DOWN = 3 };

/* ------------------------------------------------------------------ small helpers */

static int finite_r(ctrl_real x) {
  ctrl_real d = x - x; /* 0 for finite x, NaN for inf and NaN */
  return d == d;
}

/* 1 when every x[i] is finite: x * 0 is 0 for finite x and NaN for NaN or inf, and a NaN
 * survives the sum (one multiply-add per element, no branches). */
static int all_finite(const ctrl_real *x, int n) {
  ctrl_real acc = CTRL_LIT(0.0);
  int i;
  for (i = 0; i < n; ++i) {
    acc = acc + x[i] * CTRL_LIT(0.0);
  }
  return acc == acc;
}

static ctrl_real min_r(ctrl_real a, ctrl_real b) { return a < b ? a : b; }
static ctrl_real max_r(ctrl_real a, ctrl_real b) { return a > b ? a : b; }

static ctrl_real dot3(const ctrl_real *a, const ctrl_real *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void cross3(const ctrl_real *a, const ctrl_real *b, ctrl_real *out) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}

static ctrl_real norm3(const ctrl_real *a) { return CTRL_SQRT(dot3(a, a)); }

/* out = A B for 3x3 column-major matrices */
static void matmul3(const ctrl_real *A, const ctrl_real *B, ctrl_real *out) {
  int r, col;
  for (col = 0; col < 3; ++col) {
    for (r = 0; r < 3; ++r) {
      out[r + 3 * col] = A[r] * B[3 * col] + A[r + 3] * B[1 + 3 * col] + A[r + 6] * B[2 + 3 * col];
    }
  }
}

/* ------------------------------------------------------------------ names */

const char *ctrl_state_name(ctrl_state s) {
  switch (s) {
    case CTRL_STATE_IDLE: return "IDLE";
    case CTRL_STATE_RUNNING: return "RUNNING";
    case CTRL_STATE_DONE: return "DONE";
    case CTRL_STATE_FAULT: return "FAULT";
    case CTRL_STATE_DEGRADED: return "DEGRADED";
    default: break;
  }
  return "?";
}

const char *ctrl_fault_name(ctrl_fault f) {
  switch (f) {
    case CTRL_FAULT_NONE: return "NONE";
    case CTRL_FAULT_BAD_CONFIG: return "BAD_CONFIG";
    case CTRL_FAULT_NONFINITE_INPUT: return "NONFINITE_INPUT";
    case CTRL_FAULT_NONFINITE_OUTPUT: return "NONFINITE_OUTPUT";
    case CTRL_FAULT_JOINT_LIMIT: return "JOINT_LIMIT";
    case CTRL_FAULT_SINGULAR: return "SINGULAR";
    case CTRL_FAULT_OVERRUN: return "OVERRUN";
    case CTRL_FAULT_TRACKING: return "TRACKING";
    case CTRL_FAULT_PLAYBACK: return "PLAYBACK";
    case CTRL_FAULT_BAD_ARGS: return "BAD_ARGS";
    case CTRL_FAULT_LOCK_REPORT: return "LOCK_REPORT";
    case CTRL_FAULT_REDUNDANCY: return "REDUNDANCY";
    case CTRL_FAULT_SPEED: return "SPEED";
    case CTRL_FAULT_UNREACHABLE: return "UNREACHABLE";
    case CTRL_FAULT_BAD_TARGET: return "BAD_TARGET";
    case CTRL_FAULT_TORQUE: return "TORQUE";
    case CTRL_FAULT_STALE: return "STALE";
    case CTRL_FAULT_COLLISION: return "COLLISION";
    default: break;
  }
  return "?";
}

/* ------------------------------------------------------------------ task: time law and path */

/* s(tau) and ds/dtau of the rest-to-rest law, tau clamped to [0, 1] (paths.py TimeLaw). */
static void time_law(const ctrl_rr_config *rr, ctrl_real tau, ctrl_real *s, ctrl_real *ds) {
  tau = min_r(max_r(tau, CTRL_LIT(0.0)), CTRL_LIT(1.0));
  if (rr->law == CTRL_LAW_CUBIC) {
    ctrl_real tau2 = tau * tau;
    *s = CTRL_LIT(3.0) * tau2 - CTRL_LIT(2.0) * (tau2 * tau);
    *ds = CTRL_LIT(6.0) * tau - CTRL_LIT(6.0) * tau2;
  } else if (rr->law == CTRL_LAW_CONSTANT) {
    *s = tau;
    *ds = CTRL_LIT(1.0);
  } else {
    ctrl_real b = rr->blend;
    ctrl_real vmax = CTRL_LIT(1.0) / (CTRL_LIT(1.0) - b);
    ctrl_real acc = vmax / b;
    if (tau < b) {
      *s = CTRL_LIT(0.5) * acc * (tau * tau);
      *ds = acc * tau;
    } else if (tau <= CTRL_LIT(1.0) - b) {
      *s = CTRL_LIT(0.5) * acc * (b * b) + vmax * (tau - b);
      *ds = vmax;
    } else {
      ctrl_real r = CTRL_LIT(1.0) - tau;
      *s = CTRL_LIT(1.0) - CTRL_LIT(0.5) * acc * (r * r);
      *ds = acc * r;
    }
  }
}

/* Desired position p, rotation R (column-major) and task velocity [v; w] at time t. */
static void desired(const ctrl *c, ctrl_real t, ctrl_real *p, ctrl_real *R, ctrl_real *xdot) {
  const ctrl_rr_config *rr = &c->cfg.rr;
  ctrl_real T = rr->duration;
  ctrl_real s, ds, sdot;
  ctrl_real dp[3], dw[3];
  /* (the cartesian planner has turns = 1: 1 * s is s exactly, so its replay is unchanged) */
  int i;
  if (rr->path == CTRL_PATH_PROGRAM) { /* timelaw.py ProgramMotion: at rest before 0 and after its end */
    fw_program_desired(rr->program, t, p, R, xdot);
    return;
  }
  time_law(rr, t / T, &s, &ds);
  s = rr->turns * s; /* taskpath.py: path(turns * s), s_dot = turns * ds / T */
  ds = rr->turns * ds;
  if (rr->path == CTRL_PATH_CIRCLE) {
    ctrl_real phi = TWO_PI * s;
    ctrl_real cs = CTRL_COS(phi), sn = CTRL_SIN(phi);
    ctrl_real scale = TWO_PI * c->radius;
    for (i = 0; i < 3; ++i) {
      p[i] = c->centre[i] + c->radius * (cs * c->u[i] + sn * c->v[i]);
      dp[i] = scale * (-sn * c->u[i] + cs * c->v[i]);
      dw[i] = CTRL_LIT(0.0);
    }
    memcpy(R, c->R0, 9 * sizeof(ctrl_real));
  } else {
    for (i = 0; i < 3; ++i) {
      p[i] = c->p0[i] + s * c->delta[i];
      dp[i] = c->delta[i];
      dw[i] = c->axis_world[i] * rr->rot_angle;
    }
    if (rr->rot_angle == CTRL_LIT(0.0)) {
      memcpy(R, c->R0, 9 * sizeof(ctrl_real));
    } else { /* R0 * Rodrigues(axis, s * angle) */
      const ctrl_real *k = rr->rot_axis;
      ctrl_real ang = s * rr->rot_angle;
      ctrl_real sa = CTRL_SIN(ang), ca = CTRL_LIT(1.0) - CTRL_COS(ang);
      ctrl_real K[9], K2[9], Rot[9];
      K[0] = CTRL_LIT(0.0); K[3] = -k[2];         K[6] = k[1];
      K[1] = k[2];         K[4] = CTRL_LIT(0.0);  K[7] = -k[0];
      K[2] = -k[1];        K[5] = k[0];           K[8] = CTRL_LIT(0.0);
      matmul3(K, K, K2);
      for (i = 0; i < 9; ++i) {
        Rot[i] = ((i % 4 == 0) ? CTRL_LIT(1.0) : CTRL_LIT(0.0)) + sa * K[i] + ca * K2[i];
      }
      matmul3(c->R0, Rot, R);
    }
  }
  sdot = (t >= CTRL_LIT(0.0) && t <= T) ? ds / T : CTRL_LIT(0.0);
  for (i = 0; i < 3; ++i) {
    xdot[i] = dp[i] * sdot;
    xdot[3 + i] = dw[i] * sdot;
  }
}

/* e = 1/2 vee(R_d R^T - R R_d^T): the small-angle orientation error (cartesian.py). */
static void orientation_error(const ctrl_real *R, const ctrl_real *Rd, ctrl_real *e) {
  ctrl_real S[9]; /* S = Rd R^T, column-major */
  int r, col;
  for (col = 0; col < 3; ++col) {
    for (r = 0; r < 3; ++r) {
      S[r + 3 * col] = Rd[r] * R[col] + Rd[r + 3] * R[col + 3] + Rd[r + 6] * R[col + 6];
    }
  }
  e[0] = CTRL_LIT(0.5) * (S[5] - S[7]); /* S(2,1) - S(1,2), column-major */
  e[1] = CTRL_LIT(0.5) * (S[6] - S[2]); /* S(0,2) - S(2,0) */
  e[2] = CTRL_LIT(0.5) * (S[1] - S[3]); /* S(1,0) - S(0,1) */
}

/* ------------------------------------------------------------------ null-space operators */

static int uses_windows(const ctrl_rr_config *rr) {
  return rr->method == CTRL_METHOD_ZGHAL_IMPROVED || rr->method == CTRL_METHOD_COMBINED;
}

static ctrl_real ramp(ctrl_real x, int quadratic) {
  x = min_r(max_r(x, CTRL_LIT(0.0)), CTRL_LIT(1.0));
  return quadratic ? x * x : x;
}

/* The latched per-joint windows of spec 20 (armgen/planning/windows.py), advanced to t. */
static void windows_update(ctrl *c, ctrl_real t, const ctrl_real *q) {
  const ctrl_config *cfg = &c->cfg;
  const ctrl_rr_config *rr = &cfg->rr;
  int quadratic = rr->method != CTRL_METHOD_COMBINED;
  ctrl_real hold_min = rr->T_sum_L - rr->T_smo_L;
  int i;
  for (i = 0; i < N; ++i) {
    int st = c->win_state[i];
    int in_band = q[i] > cfg->q_max[i] - rr->theta_s || q[i] < cfg->q_min[i] + rr->theta_s;
    if (st == WIN_RAMP_DOWN) { /* the value reached at t, from which a re-entry ramps up */
      c->win_value[i] = max_r(CTRL_LIT(1.0) - ramp((t - c->win_t_event[i]) / rr->T_smo_L, quadratic), CTRL_LIT(0.0));
    }
    if ((st == WIN_IDLE || st == WIN_RAMP_DOWN) && in_band) {
      c->win_state[i] = WIN_RAMP_UP;
      c->win_t_event[i] = t;
      c->win_v_event[i] = c->win_value[i];
      if (c->win_openings[i] < 0xFFFFu) {
        ++c->win_openings[i];
      }
      st = WIN_RAMP_UP;
    }
    if (st == WIN_RAMP_UP) {
      ctrl_real v0 = c->win_v_event[i];
      c->win_value[i] = v0 + (CTRL_LIT(1.0) - v0) * ramp((t - c->win_t_event[i]) / rr->T_smo_L, quadratic);
      if (c->win_value[i] >= CTRL_LIT(1.0)) {
        c->win_state[i] = WIN_HOLD;
        c->win_t_event[i] = t;
        c->win_value[i] = CTRL_LIT(1.0);
      }
    } else if (st == WIN_HOLD) {
      if (t - c->win_t_event[i] >= hold_min && !in_band) {
        c->win_state[i] = WIN_RAMP_DOWN;
        c->win_t_event[i] = t;
        c->win_v_event[i] = CTRL_LIT(1.0);
      }
    } else if (st == WIN_RAMP_DOWN) {
      if (c->win_value[i] <= CTRL_LIT(0.0)) {
        c->win_state[i] = WIN_IDLE;
        c->win_value[i] = CTRL_LIT(0.0);
      }
    } else {
      /* WIN_IDLE outside the band: nothing to advance */
    }
  }
}

/* alpha of the configured method at (t, q) (cartesian.py CartesianPlanner.alpha). */
static void null_space_alpha(const ctrl *c, ctrl_real t, const ctrl_real *q, ctrl_real *alpha) {
  const ctrl_config *cfg = &c->cfg;
  const ctrl_rr_config *rr = &cfg->rr;
  ctrl_real T = rr->duration;
  ctrl_real a_r[N], a_l[N], grad[N], h;
  ctrl_real gamma_r = min_r(max_r((t - T / CTRL_LIT(2.0)) / rr->gamma_R_ramp, CTRL_LIT(0.0)), CTRL_LIT(1.0));
  int need_r = rr->method == CTRL_METHOD_REPETITIVE || rr->method == CTRL_METHOD_COMBINED;
  int need_l = rr->method != CTRL_METHOD_PINV && rr->method != CTRL_METHOD_REPETITIVE;
  int i;
  if (need_r) {
    ctrl_real t_sta = T / CTRL_LIT(2.0);
    if (t > t_sta && t < T) { /* off before T/2; its limit 0 at T (removable singularity) */
      ctrl_real x = (t - t_sta) / rr->T_smo_R;
      ctrl_real gain = min_r(x * x, CTRL_LIT(1.0)) * rr->rho_R;
      ctrl_real left = T - t;
      ctrl_gen_repetitive(q, cfg->q_start, &h, grad); /* grad H_R = q - q_start */
      for (i = 0; i < N; ++i) {
        a_r[i] = gain * -grad[i] / left;
      }
    } else {
      need_r = 0;
    }
  }
  if (need_l) {
    ctrl_gen_zghal(q, &h, grad); /* descent direction of the Zghal barrier */
    for (i = 0; i < N; ++i) {
      a_l[i] = -rr->rho_L * grad[i];
    }
  }
  for (i = 0; i < N; ++i) {
    ctrl_real r = need_r ? a_r[i] : CTRL_LIT(0.0);
    switch (rr->method) {
      case CTRL_METHOD_REPETITIVE:
        alpha[i] = r;
        break;
      case CTRL_METHOD_ZGHAL:
        alpha[i] = a_l[i];
        break;
      case CTRL_METHOD_ZGHAL_IMPROVED:
        alpha[i] = c->win_value[i] * a_l[i];
        break;
      case CTRL_METHOD_COMBINED:
        alpha[i] = gamma_r * r + c->win_value[i] * a_l[i];
        break;
      case CTRL_METHOD_PINV: /* minimum norm */
      default:
        alpha[i] = CTRL_LIT(0.0);
        break;
    }
  }
}

/* ------------------------------------------------------------------ init */

/* Ticks (not rounded) of the MOVE_TO profile moving joint i by d: the shortest time in which its
 * peak speed d / ((1 - b) T) and acceleration d / (b (1 - b) T^2) stay within the limits times
 * (1 - MOVE_TO_MARGIN), over dt. A real, never cast here: compared with MOVE_TO_MAX_TICKS. */
static ctrl_real move_to_ticks(const ctrl_config *cfg, int i, ctrl_real d) {
  const ctrl_real b = MOVE_TO_BLEND, keep = CTRL_LIT(1.0) - MOVE_TO_MARGIN;
  ctrl_real T = max_r(d / ((CTRL_LIT(1.0) - b) * keep * cfg->qdot_max[i]),
                      CTRL_SQRT(d / (b * (CTRL_LIT(1.0) - b) * keep * cfg->qddot_max[i])));
  return T / cfg->dt;
}

static int positive(ctrl_real x) { return finite_r(x) && x > CTRL_LIT(0.0); }
static int nonneg(ctrl_real x) { return finite_r(x) && x >= CTRL_LIT(0.0); }
static int at_most(ctrl_real x, ctrl_real limit) { return nonneg(x) && x <= limit; }

#if CTRL_HAS_COLLISION
/* ------------------------------------------------------------------ collision (docs/collision.md) */

/* The least of the task's distances at q: the self pairs and each moving capsule against each
 * obstacle slot (an inactive slot reports CTRL_CLEARANCE_UNCHECKED). A NaN stays (the planner's
 * clearance report takes the least of the same distances). */
static ctrl_real least_distance(const ctrl_collision *coll, const ctrl_real *q) {
  ctrl_real d[CTRL_NDIST], least;
  int k;
  coll->distances(q, d);
  least = d[0];
  for (k = 1; k < CTRL_NDIST; ++k) {
    least = (d[k] < least || d[k] != d[k]) ? d[k] : least;
  }
  return least;
}

/* The command q's least distance into *clearance: COLLISION below the task's clearance (as the
 * planner's check: a plan closer than it is infeasible), NONFINITE_OUTPUT for NaN. */
static ctrl_fault check_clearance(const ctrl_collision *coll, const ctrl_real *q, ctrl_real *clearance) {
  *clearance = least_distance(coll, q);
  if (!finite_r(*clearance)) {
    return CTRL_FAULT_NONFINITE_OUTPUT;
  }
  return *clearance < coll->clearance ? CTRL_FAULT_COLLISION : CTRL_FAULT_NONE;
}

/* -gain grad H_C(q), the planners' collision term (planning/common/collision.py criterion_term),
 * into term; 0 when the task only checks (gain 0, no criterion bound). */
static void collision_term(const ctrl *c, const ctrl_real *q, ctrl_real *term) {
  const ctrl_collision *coll = c->cfg.collision;
  ctrl_real h, grad[N];
  int i;
  if (coll == NULL || coll->criterion == NULL || coll->gain == CTRL_LIT(0.0)) {
    for (i = 0; i < N; ++i) {
      term[i] = CTRL_LIT(0.0);
    }
    return;
  }
  coll->criterion(q, coll->clearance, coll->activation, &h, grad);
  for (i = 0; i < N; ++i) {
    term[i] = -coll->gain * grad[i];
  }
}

/* alpha + the collision term at q: what the cartesian and fault-tolerant planners add to their
 * null-space vector (the step's status covers a non-finite gradient). */
static void add_collision_term(const ctrl *c, const ctrl_real *q, ctrl_real *alpha) {
  ctrl_real term[N];
  int i;
  if (c->cfg.collision == NULL || c->cfg.collision->gain == CTRL_LIT(0.0)) {
    return;
  }
  collision_term(c, q, term);
  for (i = 0; i < N; ++i) {
    alpha[i] = alpha[i] + term[i];
  }
}

/* The configuration's collision check, when it has one: bindings present, 0 <= clearance <
 * activation, gain >= 0 (> 0 needs the criterion), and finite distances at q_start (NaN or inf
 * in the task's obstacle slots show there). The held command's clearance. */
static int init_collision(ctrl *c) {
  const ctrl_collision *coll = c->cfg.collision;
  if (coll == NULL) {
    return 1;
  }
  if (coll->distances == NULL || !nonneg(coll->clearance) || !finite_r(coll->activation) ||
      !(coll->activation > coll->clearance) || !nonneg(coll->gain) ||
      (coll->gain > CTRL_LIT(0.0) && coll->criterion == NULL)) {
    return 0;
  }
  c->clearance = least_distance(coll, c->cfg.q_start);
  return finite_r(c->clearance);
}
#endif

static int method_valid(ctrl_method m) {
  switch (m) { /* the enum may be stored in a byte (-fshort-enums on bare-metal ARM) */
    case CTRL_METHOD_PINV:
    case CTRL_METHOD_REPETITIVE:
    case CTRL_METHOD_ZGHAL:
    case CTRL_METHOD_ZGHAL_IMPROVED:
    case CTRL_METHOD_COMBINED:
      return 1;
    default:
      break;
  }
  return 0;
}

#if CTRL_HAS_DYNAMICS
/* The feed-forward choice and the torque limits: a known choice, each limit in [0, TAU_MAX_LIMIT]. */
static int dynamics_valid(const ctrl_config *cfg) {
  int i, ok;
  switch (cfg->feedforward) { /* the enum may be stored in a byte (-fshort-enums on bare-metal ARM) */
    case CTRL_FF_NONE:
    case CTRL_FF_GRAVITY:
    case CTRL_FF_INVERSE_DYNAMICS:
      ok = 1;
      break;
    default:
      ok = 0;
      break;
  }
  for (i = 0; i < N; ++i) {
    ok = ok && at_most(cfg->tau_max[i], TAU_MAX_LIMIT);
  }
  return ok;
}
#endif

/* A program path: a well-formed table (fw_program_check), absolute (relative = 0), whose
 * time law ends within the task's duration (the planner rounds it up to whole ticks) and
 * whose first pose is FK(q_start) (start pose Tp, column-major 4x4), to PROGRAM_START_TOL(_RAD):
 * a table planned from another start is refused, not tracked. */
static int init_program(const ctrl *c, const ctrl_real *Tp) {
  const ctrl_rr_config *rr = &c->cfg.rr;
  ctrl_real p[3], R[9], xdot[6], d[3], R0[9], e[3];
  int i, r;
  if (rr->program == NULL || !fw_program_check(rr->program) || rr->relative != 0) return 0;
  if (!(fw_program_duration(rr->program) <= rr->duration * (CTRL_LIT(1.0) + DURATION_RTOL))) return 0;
  fw_program_desired(rr->program, CTRL_LIT(0.0), p, R, xdot);
  for (i = 0; i < 3; ++i) {
    d[i] = p[i] - Tp[12 + i];
    for (r = 0; r < 3; ++r) {
      R0[r + 3 * i] = Tp[r + 4 * i];
    }
  }
  orientation_error(R0, R, e);
  return norm3(d) <= PROGRAM_START_TOL && norm3(e) <= PROGRAM_START_TOL_RAD;
}

/* The path and time law shared by the resolved-rate modes: duration a whole number of ticks,
 * path built from FK(q_start) (paths.py CirclePath / LinePath, taskpath.py's relative points). */
static int init_path(ctrl *c) {
  const ctrl_config *cfg = &c->cfg;
  const ctrl_rr_config *rr = &cfg->rr;
  ctrl_real Tp[16], J[6 * N], ticks, via[3], end[3];
  int i, r;
  if (!positive(rr->duration) || cfg->dt > rr->duration) return 0;
  ticks = rr->duration / cfg->dt + CTRL_LIT(0.5);
  if (!(ticks >= CTRL_LIT(1.0) && ticks < CTRL_LIT(2.0e9))) return 0;
  c->n_ticks = (uint32_t)ticks;
  if (CTRL_FABS((ctrl_real)c->n_ticks * cfg->dt - rr->duration) > DURATION_RTOL * rr->duration) return 0;
  if (rr->law != CTRL_LAW_CUBIC && rr->law != CTRL_LAW_CONSTANT && rr->law != CTRL_LAW_TRAPEZOIDAL) return 0;
  /* blend is checked whatever the law: a NaN in the configuration is a broken configuration */
  if (!at_most(rr->blend, CTRL_LIT(0.5)) || (rr->law == CTRL_LAW_TRAPEZOIDAL && !positive(rr->blend))) return 0;
  if (!nonneg(rr->clik_gain) || !positive(rr->turns) || (rr->relative != 0 && rr->relative != 1)) return 0;
  for (r = 0; r < CTRL_NTASK; ++r) {
    if (rr->task_rows[r] < 0 || rr->task_rows[r] > 5 || (r > 0 && rr->task_rows[r] <= rr->task_rows[r - 1])) return 0;
  }
  if (!all_finite(rr->via, 3) || !all_finite(rr->end, 3) || !all_finite(rr->rot_axis, 3) || !finite_r(rr->rot_angle)) {
    return 0;
  }
  if (rr->path != CTRL_PATH_CIRCLE && rr->path != CTRL_PATH_LINE && rr->path != CTRL_PATH_PROGRAM) return 0;
  if (rr->path != CTRL_PATH_CIRCLE && rr->turns != CTRL_LIT(1.0)) return 0;

  ctrl_gen_fk_jacobian(cfg->q_start, Tp, J);
  if (!all_finite(Tp, 16)) return 0;
  if (rr->path == CTRL_PATH_PROGRAM) return init_program(c, Tp);
  for (i = 0; i < 3; ++i) {
    c->p0[i] = Tp[12 + i];
    for (r = 0; r < 3; ++r) {
      c->R0[r + 3 * i] = Tp[r + 4 * i];
    }
    via[i] = rr->relative ? rr->via[i] + c->p0[i] : rr->via[i];
    end[i] = rr->relative ? rr->end[i] + c->p0[i] : rr->end[i];
  }
  if (rr->path == CTRL_PATH_CIRCLE) { /* circumcircle of start, via, end (paths.py CirclePath) */
    ctrl_real a[3], b[3], nrm[3], d[3], aa, bb, ab, denom, scale, len;
    for (i = 0; i < 3; ++i) {
      a[i] = via[i] - c->p0[i];
      b[i] = end[i] - c->p0[i];
    }
    cross3(a, b, nrm);
    scale = norm3(a) * norm3(b);
    if (scale == CTRL_LIT(0.0) || norm3(nrm) < COLLINEAR_TOL * scale) return 0;
    aa = dot3(a, a);
    bb = dot3(b, b);
    ab = dot3(a, b);
    denom = CTRL_LIT(2.0) * (aa * bb - ab * ab);
    for (i = 0; i < 3; ++i) {
      c->centre[i] = c->p0[i] + (bb * (aa - ab) * a[i] + aa * (bb - ab) * b[i]) / denom;
      d[i] = c->p0[i] - c->centre[i];
    }
    c->radius = norm3(d);
    len = norm3(nrm);
    for (i = 0; i < 3; ++i) {
      c->u[i] = d[i] / c->radius;
      nrm[i] = nrm[i] / len;
    }
    cross3(nrm, c->u, c->v);
    if (!positive(c->radius) || !all_finite(c->centre, 3) || !all_finite(c->v, 3)) return 0;
  } else {
    for (i = 0; i < 3; ++i) {
      c->delta[i] = end[i] - c->p0[i];
      c->axis_world[i] = c->R0[i] * rr->rot_axis[0] + c->R0[i + 3] * rr->rot_axis[1] + c->R0[i + 6] * rr->rot_axis[2];
    }
  }
  return 1;
}

static int init_resolved_rate(ctrl *c) {
  const ctrl_rr_config *rr = &c->cfg.rr;
  if (!method_valid(rr->method)) return 0;
  if (!nonneg(rr->rho_R) || !positive(rr->T_smo_R) || !nonneg(rr->rho_L) || !positive(rr->theta_s) ||
      !positive(rr->T_smo_L) || !finite_r(rr->T_sum_L) || rr->T_sum_L < rr->T_smo_L || !positive(rr->gamma_R_ramp) ||
      !nonneg(rr->damping)) {
    return 0;
  }
  return init_path(c);
}

#if CTRL_HAS_FAULT_TOLERANT
static int init_fault_tolerant(ctrl *c) {
  const ctrl_ft_config *ft = &c->cfg.ft;
  int method_ok = ft->method == CTRL_FT_PINV || ft->method == CTRL_FT_GPM || ft->method == CTRL_FT_WLN;
  int index_ok = ft->index == CTRL_FT_INDEX_OMEGA || ft->index == CTRL_FT_INDEX_RELATIVE;
  int rule_ok = ft->rule == CTRL_WLN_PLAIN || ft->rule == CTRL_WLN_SMOOTH;
  if (!method_ok || !index_ok || !rule_ok || !nonneg(ft->K) || !nonneg(ft->b) || !positive(ft->v_band) ||
      !positive(ft->omega_floor) || !positive(ft->delta) || !positive(ft->epsilon) || !nonneg(ft->lambda_max) ||
      !all_finite(ft->a, N)) {
    return 0;
  }
  return init_path(c);
}
#endif

#if CTRL_HAS_WEIGHTED_GPM
static int init_weighted_gpm(ctrl *c) {
  const ctrl_wg_config *wg = &c->cfg.wg;
  int k;
  if (!(positive(wg->band) && wg->band < CTRL_LIT(0.5)) || !nonneg(wg->t_rmax) || !positive(wg->delta) ||
      !positive(wg->epsilon) || !nonneg(wg->rho_max) || !nonneg(wg->ramp_time) ||
      (wg->ramp_out != 0 && wg->ramp_out != 1)) {
    return 0;
  }
  for (k = 0; k < CTRL_WGPM_NCRIT; ++k) {
    if (!nonneg(wg->k_hi[k]) || !nonneg(wg->k_lo[k]) || wg->k_lo[k] > wg->k_hi[k] || !finite_r(wg->H_lo[k]) ||
        !finite_r(wg->H_hi[k]) || !(wg->H_hi[k] > wg->H_lo[k]) || !(wg->u_th[k] >= CTRL_LIT(0.0)) ||
        !(wg->u_th[k] <= CTRL_LIT(1.0)) || !positive(wg->u_band[k])) {
      return 0;
    }
  }
  if (!init_path(c)) return 0;
  return !(wg->ramp_out && CTRL_LIT(2.0) * wg->ramp_time > c->cfg.rr.duration);
}
#endif

static int init_playback(ctrl *c) {
  const ctrl_config *cfg = &c->cfg;
  const ctrl_pb_config *pb = &cfg->pb;
  ctrl_real span;
  int i, k;
  if (pb->nseg < 1 || pb->nseg > CTRL_MAX_SEGMENTS || pb->n_ticks < 1) return 0;
  for (k = 0; k <= pb->nseg; ++k) {
    if (!finite_r(pb->knots[k]) || (k > 0 && !(pb->knots[k] > pb->knots[k - 1]))) return 0;
  }
  /* The period must fit the knots: n_ticks periods span the plan (the last tick is clamped
   * to the last knot, so it may be shorter by up to one period). */
  span = pb->knots[pb->nseg] - pb->knots[0];
  if (!((ctrl_real)pb->n_ticks * cfg->dt >= span * (CTRL_LIT(1.0) - DURATION_RTOL) &&
        (ctrl_real)(pb->n_ticks - 1) * cfg->dt < span)) {
    return 0;
  }
  for (i = 0; i < N; ++i) {
    if (pb->active[i] != 0 && pb->active[i] != 1) return 0;
    if (pb->active[i]) {
      if (!all_finite(pb->coeffs[i], pb->nseg * CTRL_NCOEF)) return 0;
      if (CTRL_FABS(pb->coeffs[i][0] - cfg->q_start[i]) > PLAYBACK_START_TOL) return 0;
    }
  }
  c->n_ticks = (uint32_t)pb->n_ticks;
  return 1;
}

/* The sampled table, once: present, a row count within CTRL_MAX_SAMPLES, every value finite,
 * row 0 at q_start. The ticks read it through the copied pointer (the table is const data). */
static int init_sampled(ctrl *c) {
  const ctrl_config *cfg = &c->cfg;
  const ctrl_sp_config *sp = &cfg->sp;
  int32_t k;
  int i;
  if (sp->table == NULL || sp->n_samples < 2 || sp->n_samples > CTRL_MAX_SAMPLES) return 0;
  for (k = 0; k < sp->n_samples; ++k) {
    if (!all_finite(sp->table + (size_t)k * N, N)) return 0;
  }
  for (i = 0; i < N; ++i) {
    if (CTRL_FABS(sp->table[i] - cfg->q_start[i]) > PLAYBACK_START_TOL) return 0;
  }
  c->n_ticks = (uint32_t)(sp->n_samples - 1);
  return 1;
}

ctrl_fault ctrl_init(ctrl *c, const ctrl_config *config) {
  int i, ok;
  if (c == NULL) {
    return CTRL_FAULT_BAD_ARGS;
  }
  (void)memset(c, 0, sizeof(*c));
  c->state = CTRL_STATE_FAULT;
  c->fault = CTRL_FAULT_BAD_CONFIG;
#if CTRL_HAS_COLLISION
  c->clearance = CTRL_CLEARANCE_UNCHECKED;
#endif
  if (config == NULL) {
    return CTRL_FAULT_BAD_ARGS;
  }
  c->cfg = *config; /* validated once, here; the ticks use only this copy */
  config = &c->cfg;
  ok = positive(config->dt) &&
       at_most(config->residual_rel, RESIDUAL_REL_LIMIT) && at_most(config->residual_abs, RESIDUAL_ABS_LIMIT) &&
       at_most(config->pos_err_max, POS_ERR_MAX_LIMIT);
  for (i = 0; i < N; ++i) {
    ctrl_real q = config->q_start[i], lo = config->q_min[i], hi = config->q_max[i];
    int limits = finite_r(lo) && finite_r(hi) && lo < hi;
    int inside = limits && finite_r(q) && q >= lo && q <= hi;
    /* held after a bad configuration: q_start when valid, else mid-range (else 0: no limits) */
    c->q_hold[i] = inside ? q : (limits ? lo + CTRL_LIT(0.5) * (hi - lo) : CTRL_LIT(0.0));
    c->mask[i] = CTRL_LIT(1.0);
    ok = ok && inside && positive(config->qdot_max[i]) && config->qdot_max[i] <= QDOT_MAX_LIMIT &&
         positive(config->qddot_max[i]) && config->qddot_max[i] <= QDDOT_MAX_LIMIT &&
         move_to_ticks(config, i, hi - lo) <= MOVE_TO_MAX_TICKS; /* false for inf and NaN too */
  }
#if CTRL_HAS_DYNAMICS
  ok = ok && dynamics_valid(config);
#endif
#if CTRL_HAS_COLLISION
  ok = ok && init_collision(c); /* after q_start's check: it measures there */
#endif
  if (ok) {
    switch (config->mode) {
      case CTRL_MODE_RESOLVED_RATE: ok = init_resolved_rate(c); break;
      case CTRL_MODE_PLAYBACK: ok = init_playback(c); break;
      case CTRL_MODE_SAMPLED: ok = init_sampled(c); break;
#if CTRL_HAS_FAULT_TOLERANT
      case CTRL_MODE_FAULT_TOLERANT: ok = init_fault_tolerant(c); break;
#endif
#if CTRL_HAS_WEIGHTED_GPM
      case CTRL_MODE_WEIGHTED_GPM: ok = init_weighted_gpm(c); break;
#endif
      default: ok = 0; break;
    }
  }
  if (!ok) {
    return CTRL_FAULT_BAD_CONFIG;
  }
  for (i = 0; i < N; ++i) {
    c->q[i] = config->q_start[i];
    c->q_carry[i] = CTRL_LIT(0.0);
  }
  c->state = CTRL_STATE_IDLE;
  c->fault = CTRL_FAULT_NONE;
  return CTRL_FAULT_NONE;
}

/* ------------------------------------------------------------------ ticks */

static int moving(const ctrl *c) { return c->state == CTRL_STATE_RUNNING || c->state == CTRL_STATE_DEGRADED; }

static ctrl_real tick_time(const ctrl *c) {
  const ctrl_config *cfg = &c->cfg;
  if (cfg->mode == CTRL_MODE_PLAYBACK && !c->moving_to && !c->following) {
    const ctrl_pb_config *pb = &cfg->pb;
    ctrl_real t_end = pb->knots[pb->nseg];
    if (c->k >= c->n_ticks) {
      return t_end; /* the plan's last sample is its last knot */
    }
    return min_r(pb->knots[0] + (ctrl_real)c->k * cfg->dt, t_end);
  }
  return (ctrl_real)c->k * cfg->dt;
}

#if CTRL_HAS_DYNAMICS
/* The feed-forward torque of the command (q, q_dot, q_ddot) the configuration asks for. */
static void feedforward_torque(const ctrl *c, const ctrl_real *q, const ctrl_real *qd, const ctrl_real *qdd,
                               ctrl_real *tau) {
  int i;
  switch (c->cfg.feedforward) {
    case CTRL_FF_INVERSE_DYNAMICS:
      ctrl_gen_rnea(q, qd, qdd, tau);
      break;
    case CTRL_FF_GRAVITY:
      ctrl_gen_gravity(q, tau);
      break;
    case CTRL_FF_NONE:
    default:
      for (i = 0; i < N; ++i) {
        tau[i] = CTRL_LIT(0.0);
      }
      break;
  }
}

/* TORQUE when a joint with a limit (tau_max[i] > 0) would need more (TORQUE_RTOL for rounding). */
static ctrl_fault check_torque(const ctrl *c, const ctrl_real *tau) {
  int i;
  if (!all_finite(tau, N)) {
    return CTRL_FAULT_NONFINITE_OUTPUT;
  }
  for (i = 0; i < N; ++i) {
    ctrl_real limit = c->cfg.tau_max[i];
    if (limit > CTRL_LIT(0.0) && CTRL_FABS(tau[i]) > limit * (CTRL_LIT(1.0) + TORQUE_RTOL)) {
      return CTRL_FAULT_TORQUE;
    }
  }
  return CTRL_FAULT_NONE;
}
#endif

static void emit_hold(const ctrl *c, ctrl_output *out) {
  int i;
  out->tick = c->k;
  out->t = c->t_hold;
  for (i = 0; i < N; ++i) {
    out->q[i] = c->q_hold[i];
    out->qd[i] = CTRL_LIT(0.0);
    out->window[i] = c->win_value[i];
  }
#if CTRL_HAS_DYNAMICS
  /* holding still: the gravity torques of the held command (rnea at rest is gravity); none
   * after a rejected configuration (the drives must not be enabled) */
  if (c->fault != CTRL_FAULT_BAD_CONFIG && c->cfg.feedforward != CTRL_FF_NONE) {
    ctrl_gen_gravity(c->q_hold, out->tau_ff);
  } else {
    for (i = 0; i < N; ++i) {
      out->tau_ff[i] = CTRL_LIT(0.0);
    }
  }
#endif
  out->pos_err = c->pos_err;
  out->ori_err = c->ori_err;
#if CTRL_HAS_COLLISION
  out->clearance = c->clearance;
#endif
  out->locked = c->locked;
  out->state = c->state;
  out->fault = c->fault;
}

/* The command of this tick emitted: held (its q_dot the next difference's previous one), output,
 * and DONE after the last tick. */
static void emit(ctrl *c, ctrl_real t, const ctrl_real *q, const ctrl_real *qd, ctrl_output *out) {
  int i;
  c->t_hold = t;
  out->tick = c->k;
  out->t = t;
  for (i = 0; i < N; ++i) {
    c->q_hold[i] = q[i];
    c->qd_prev[i] = qd[i];
    out->q[i] = q[i];
    out->qd[i] = qd[i];
    out->window[i] = c->win_value[i];
  }
  out->pos_err = c->pos_err;
  out->ori_err = c->ori_err;
#if CTRL_HAS_COLLISION
  out->clearance = c->clearance;
#endif
  if (c->k >= c->n_ticks) {
    c->state = CTRL_STATE_DONE;
  }
  out->locked = c->locked;
  out->state = c->state;
  out->fault = c->fault;
}

#if CTRL_HAS_DYNAMICS
/* The command's feed-forward torque tau from (q, q_dot, q_ddot), q_ddot the mode's own (qdd) or,
 * where the mode has none (qdd NULL), the backward difference of the commanded velocities
 * (q_dot - the previous command's q_dot) / dt; and its check against the torque limits. */
static ctrl_fault command_torque(const ctrl *c, const ctrl_real *q, const ctrl_real *qd, const ctrl_real *qdd,
                                 ctrl_real *tau) {
  ctrl_real difference[N];
  const ctrl_real *acceleration = qdd;
  int i;
  if (c->cfg.feedforward == CTRL_FF_NONE) { /* nothing computed, nothing to check */
    for (i = 0; i < N; ++i) {
      tau[i] = CTRL_LIT(0.0);
    }
    return CTRL_FAULT_NONE;
  }
  if (acceleration == NULL && c->cfg.feedforward == CTRL_FF_INVERSE_DYNAMICS) {
    for (i = 0; i < N; ++i) {
      difference[i] = (qd[i] - c->qd_prev[i]) / c->cfg.dt;
    }
    acceleration = difference;
  }
  feedforward_torque(c, q, qd, acceleration, tau);
  return check_torque(c, tau);
}

/* Holding (IDLE, DONE, FAULT): the held command is at rest, so the next command's backward
 * difference (a SETPOINT taking over) starts from rest, not from the velocity of the last
 * command before a STOP. (The WLN rule, qd_prev's other reader, never runs after a hold.) */
static void at_rest(ctrl *c) {
  int i;
  for (i = 0; i < N; ++i) {
    c->qd_prev[i] = CTRL_LIT(0.0);
  }
}
#endif

/* The command of this tick, accepted: with a collision check, first its least distance against
 * the clearance (COLLISION: nothing is emitted, the arm holds); with dynamics, its feed-forward
 * torque and the torque limits (TORQUE: likewise); then emitted. */
static ctrl_fault accept(ctrl *c, ctrl_real t, const ctrl_real *q, const ctrl_real *qd, const ctrl_real *qdd,
                         ctrl_output *out) {
#if CTRL_HAS_COLLISION
  ctrl_real clearance = CTRL_CLEARANCE_UNCHECKED;
  if (c->cfg.collision != NULL) {
    ctrl_fault fc = check_clearance(c->cfg.collision, q, &clearance);
    if (fc != CTRL_FAULT_NONE) {
      return fc;
    }
  }
#endif
#if CTRL_HAS_DYNAMICS
  ctrl_real tau[N];
  int i;
  ctrl_fault f = command_torque(c, q, qd, qdd, tau);
  if (f != CTRL_FAULT_NONE) {
    return f;
  }
#if CTRL_HAS_COLLISION
  c->clearance = clearance;
#endif
  emit(c, t, q, qd, out);
  for (i = 0; i < N; ++i) {
    out->tau_ff[i] = tau[i];
  }
#else
  (void)qdd; /* no dynamics: the command's acceleration is not needed */
#if CTRL_HAS_COLLISION
  c->clearance = clearance;
#endif
  emit(c, t, q, qd, out);
#endif
  return CTRL_FAULT_NONE;
}

static ctrl_fault check_command(const ctrl *c, const ctrl_real *q) {
  const ctrl_real *lo = c->cfg.q_min, *hi = c->cfg.q_max;
  int i, inside = 1;
  for (i = 0; i < N; ++i) { /* false for NaN as well */
    inside &= (q[i] >= lo[i]) & (q[i] <= hi[i]);
  }
  if (inside) return CTRL_FAULT_NONE;
  return all_finite(q, N) ? CTRL_FAULT_JOINT_LIMIT : CTRL_FAULT_NONFINITE_OUTPUT;
}

/* Explicit Euler to the next tick's command (locked joints have q_dot = 0: frozen exactly). */
static void integrate(ctrl *c, const ctrl_real *qd) {
  ctrl_real *q = c->q;
  int i;
  for (i = 0; i < N; ++i) {
#if CTRL_COMPENSATED_SUM
    ctrl_real y = c->cfg.dt * qd[i] - c->q_carry[i];
    ctrl_real s = q[i] + y;
    c->q_carry[i] = (s - q[i]) - y;
    q[i] = s;
#else
    q[i] = q[i] + c->cfg.dt * qd[i];
#endif
  }
  ++c->k;
}

/* Pose, tracking error and the commanded task velocity xdot + offset + K_p e at (t, q):
 * cartesian.py / taskpath.py. Returns J (for the residual check) in J. */
static void task_command(ctrl *c, const ctrl_input *in, ctrl_real t, const ctrl_real *q, ctrl_real *J,
                         ctrl_real *cmd, ctrl_real *cmd_max) {
  const ctrl_rr_config *rr = &c->cfg.rr;
  ctrl_real Tp[16], R[9], pd[3], Rd[9], xdot[6], e[6];
  int i, r;
  ctrl_gen_fk_jacobian(q, Tp, J); /* finite for finite q; overflow would show in q_dot */
  for (i = 0; i < 3; ++i) {
    for (r = 0; r < 3; ++r) {
      R[r + 3 * i] = Tp[r + 4 * i];
    }
  }
  desired(c, t, pd, Rd, xdot);
  if (in != NULL) {
    for (r = 0; r < 6; ++r) {
      xdot[r] = xdot[r] + in->xdot_offset[r];
    }
  }
  for (i = 0; i < 3; ++i) {
    e[i] = pd[i] - Tp[12 + i];
  }
  orientation_error(R, Rd, e + 3);
  c->pos_err = norm3(e);
  c->ori_err = norm3(e + 3);
  if (rr->clik_gain > CTRL_LIT(0.0)) {
    for (r = 0; r < 6; ++r) {
      xdot[r] = xdot[r] + rr->clik_gain * e[r];
    }
  }
  *cmd_max = CTRL_LIT(0.0);
  for (r = 0; r < CTRL_NTASK; ++r) {
    cmd[r] = xdot[rr->task_rows[r]];
    *cmd_max = max_r(*cmd_max, CTRL_FABS(cmd[r]));
  }
}

/* Stage 1 of planning/toolpath/limits.py for programs: when a joint's q_dot exceeds its
 * qdot_max, the self-motion q_n = q_dot - J+ J q_dot (J on the task rows and the healthy
 * columns) is scaled by the largest s in [0, 1] that keeps inside its limit every joint
 * whose tool part alone fits; the tool's twist J q_dot is unchanged. (A joint whose tool part
 * alone is too fast is left to the speed guard: the planner slowed the tool there.) */
static ctrl_fault limit_self_motion(const ctrl *c, const ctrl_real *J, ctrl_real *qd) {
  const ctrl_config *cfg = &c->cfg;
  ctrl_real Jm[6 * N], v[CTRL_NTASK], zero[N], tool[N], scale = CTRL_LIT(1.0);
  int i, r, over = 0;
  for (i = 0; i < N; ++i) {
    over |= CTRL_FABS(qd[i]) > cfg->qdot_max[i];
  }
  if (!over) return CTRL_FAULT_NONE;
  for (i = 0; i < N; ++i) {
    for (r = 0; r < 6; ++r) {
      Jm[r + 6 * i] = J[r + 6 * i] * c->mask[i];
    }
    zero[i] = CTRL_LIT(0.0);
  }
  for (r = 0; r < CTRL_NTASK; ++r) {
    ctrl_real sum = CTRL_LIT(0.0);
    for (i = 0; i < N; ++i) {
      sum = sum + Jm[cfg->rr.task_rows[r] + 6 * i] * qd[i];
    }
    v[r] = sum;
  }
  if (ctrl_gen_step_gpm(Jm, v, zero, CTRL_LIT(0.0), tool) != CTRL_GEN_OK) return CTRL_FAULT_NONFINITE_OUTPUT;
  for (i = 0; i < N; ++i) {
    ctrl_real null_i = qd[i] - tool[i];
    if (CTRL_FABS(tool[i]) <= cfg->qdot_max[i] && null_i != CTRL_LIT(0.0)) {
      ctrl_real limit = null_i > CTRL_LIT(0.0) ? cfg->qdot_max[i] : -cfg->qdot_max[i];
      scale = min_r(scale, (limit - tool[i]) / null_i);
    }
  }
  scale = max_r(scale, CTRL_LIT(0.0));
  for (i = 0; i < N; ++i) {
    ctrl_real limit = cfg->qdot_max[i];
    qd[i] = tool[i] + scale * (qd[i] - tool[i]);
    /* the joint that set the scale lands on its limit, up to one rounding: onto it exactly (the
     * planner accepts it to 1e-9; the speed guard's strict > would not) */
    if (CTRL_FABS(tool[i]) <= limit && CTRL_FABS(qd[i]) > limit) {
      qd[i] = qd[i] > CTRL_LIT(0.0) ? limit : -limit;
    }
  }
  return CTRL_FAULT_NONE;
}

/* The step's q_dot within the speed limits the way the planner keeps it (programs only). */
static ctrl_fault limit_speed(const ctrl *c, const ctrl_real *J, ctrl_real *qd) {
  return c->cfg.rr.path == CTRL_PATH_PROGRAM ? limit_self_motion(c, J, qd) : CTRL_FAULT_NONE;
}

/* max over the task rows of sum_i |J_ri q_dot_i|, the size of the terms J q_dot sums: its
 * rounding is a few ulp of this, not of |J q_dot|. A strong null-space term makes these
 * products large while they cancel to the (small) command, so the residual guard's relative
 * part also takes this scale (only when the command's scale alone would fault: no cost on
 * the ticks that pass). Without it a float program with GPM K = 50 faulted at its first
 * tick, at rest: a command of ~0 against the rounding of large cancelling products. */
static ctrl_real product_scale(const ctrl_config *cfg, const ctrl_real *J, const ctrl_real *qd) {
  ctrl_real scale = CTRL_LIT(0.0);
  int i, r;
  for (r = 0; r < CTRL_NTASK; ++r) {
    ctrl_real sum = CTRL_LIT(0.0);
    for (i = 0; i < N; ++i) {
      sum = sum + CTRL_FABS(J[6 * i + cfg->rr.task_rows[r]] * qd[i]);
    }
    scale = max_r(scale, sum);
  }
  return scale;
}

/* The guards every resolved-rate step passes before its command is accepted: speed
 * (qdot_max), task residual |J q_dot - cmd| (only for undamped steps: damping trades the
 * residual for a bounded speed by design) and tracking. */
static ctrl_fault check_step(const ctrl *c, const ctrl_real *J, const ctrl_real *cmd, ctrl_real cmd_max,
                             const ctrl_real *qd, int damped) {
  const ctrl_config *cfg = &c->cfg;
  ctrl_real v[6], res_max = CTRL_LIT(0.0);
  int i, r;
  /* q_dot is finite here: every step's status covers its output */
  /* A singular pose: with lambda = 0 the step's floored pivots give a huge velocity, or one
   * that does not meet the task (damping > 0: the same once the damping is exceeded). */
  for (i = 0; i < N; ++i) {
    if (CTRL_FABS(qd[i]) > cfg->qdot_max[i]) return CTRL_FAULT_SINGULAR;
  }
  if (!damped) {
    ctrl_real v0 = CTRL_LIT(0.0), v1 = CTRL_LIT(0.0), v2 = CTRL_LIT(0.0);
    ctrl_real v3 = CTRL_LIT(0.0), v4 = CTRL_LIT(0.0), v5 = CTRL_LIT(0.0);
    for (i = 0; i < N; ++i) { /* v = J q_dot, column by column, in registers */
      const ctrl_real *col = J + 6 * i;
      ctrl_real w = qd[i];
      v0 = v0 + col[0] * w;
      v1 = v1 + col[1] * w;
      v2 = v2 + col[2] * w;
      v3 = v3 + col[3] * w;
      v4 = v4 + col[4] * w;
      v5 = v5 + col[5] * w;
    }
    v[0] = v0;
    v[1] = v1;
    v[2] = v2;
    v[3] = v3;
    v[4] = v4;
    v[5] = v5;
    for (r = 0; r < CTRL_NTASK; ++r) {
      res_max = max_r(res_max, CTRL_FABS(v[cfg->rr.task_rows[r]] - cmd[r]));
    }
    if (res_max > cfg->residual_rel * cmd_max + cfg->residual_abs &&
        res_max > cfg->residual_rel * product_scale(cfg, J, qd) + cfg->residual_abs) {
      return CTRL_FAULT_SINGULAR;
    }
  }
  if (cfg->pos_err_max > CTRL_LIT(0.0) && c->pos_err > cfg->pos_err_max) return CTRL_FAULT_TRACKING;
  return CTRL_FAULT_NONE;
}

static ctrl_fault tick_resolved_rate(ctrl *c, const ctrl_input *in, ctrl_real t, ctrl_output *out) {
  const ctrl_rr_config *rr = &c->cfg.rr;
  ctrl_real *q = c->q;
  ctrl_real J[6 * N], cmd[CTRL_NTASK], alpha[N], qd[N], cmd_max;
  ctrl_fault f;

  f = check_command(c, q);
  if (f != CTRL_FAULT_NONE) return f;
  if (uses_windows(rr)) {
    windows_update(c, t, q);
  }
  task_command(c, in, t, q, J, cmd, &cmd_max);
  null_space_alpha(c, t, q, alpha);
#if CTRL_HAS_COLLISION
  add_collision_term(c, q, alpha); /* beside the method's own terms, as cartesian.py */
#endif
  /* the step's status covers its inputs (cmd, alpha) and q_dot: NaN/inf in any is a fault */
  if (ctrl_gen_step_gpm(J, cmd, alpha, rr->damping, qd) != CTRL_GEN_OK) return CTRL_FAULT_NONFINITE_OUTPUT;
  f = limit_speed(c, J, qd);
  if (f != CTRL_FAULT_NONE) return f;
  f = check_step(c, J, cmd, cmd_max, qd, 0);
  if (f != CTRL_FAULT_NONE) return f;
  f = accept(c, t, q, qd, NULL, out); /* q_ddot: the backward difference of q_dot */
  if (f != CTRL_FAULT_NONE) return f;
  if (moving(c)) {
    integrate(c, qd);
  }
  return CTRL_FAULT_NONE;
}

#if CTRL_HAS_FAULT_TOLERANT
/* Spec 30 (fault_tolerant/planner.py FaultTolerantPlanner.evaluate), one tick: index on the
 * healthy columns, GPM / WLN / minimum norm through step_fault with the lock mask. Fixed
 * cost per method: ft_index, at most two step_fault calls, wln_weights. */
static ctrl_fault tick_fault_tolerant(ctrl *c, const ctrl_input *in, ctrl_real t, ctrl_output *out) {
  const ctrl_ft_config *ft = &c->cfg.ft;
  ctrl_real *q = c->q;
  ctrl_real J[6 * N], cmd[CTRL_NTASK], cmd_max, omega[N], grad[N], grad_w[N], h_m, w;
  ctrl_real W[N], alpha[N], active[N], qd[N], lam = CTRL_LIT(0.0), sigma = CTRL_LIT(0.0);
  ctrl_real k_alpha = ft->method == CTRL_FT_GPM ? ft->K : CTRL_LIT(0.0);
  ctrl_fault f;
  int i;

  f = check_command(c, q);
  if (f != CTRL_FAULT_NONE) return f;
  task_command(c, in, t, q, J, cmd, &cmd_max); /* cmd: step_fault's status covers it */
  ctrl_gen_ft_index(J, c->mask, ft->a, ft->delta, omega, &h_m, grad, &w, grad_w);
  if (ft->index == CTRL_FT_INDEX_RELATIVE) { /* H_M / w by the quotient rule */
    for (i = 0; i < N; ++i) {
      grad[i] = grad[i] / w - h_m * grad_w[i] / (w * w);
      omega[i] = omega[i] / w;
    }
  }
  if (!all_finite(omega, N) || !all_finite(grad, N)) return CTRL_FAULT_NONFINITE_OUTPUT;
  for (i = 0; i < N; ++i) { /* WLN: alpha = 0 * grad, a (signed) zero; no memset call */
    W[i] = CTRL_LIT(1.0);
    alpha[i] = k_alpha * grad[i];
  }
  if (ft->method == CTRL_FT_WLN) {
    const ctrl_real *reference = c->qd_prev; /* plain rule: the previous tick's velocity */
    ctrl_real v_band = CTRL_LIT(0.0);
    if (ft->rule == CTRL_WLN_SMOOTH) { /* the unweighted minimum-norm motion of this tick: W = 1, alpha = 0 */
      if (ctrl_gen_step_fault(J, cmd, c->mask, W, alpha, ft->epsilon, ft->lambda_max, qd, &lam, &sigma) !=
          CTRL_GEN_OK) {
        return CTRL_FAULT_NONFINITE_OUTPUT;
      }
      reference = qd;
      v_band = ft->v_band;
    }
    ctrl_gen_wln_weights(grad, omega, reference, c->mask, ft->b, ft->omega_floor, v_band, W, active);
  }
#if CTRL_HAS_COLLISION
  add_collision_term(c, q, alpha); /* after the WLN probe (which runs without it), as the planner */
#endif
  if (ctrl_gen_step_fault(J, cmd, c->mask, W, alpha, ft->epsilon, ft->lambda_max, qd, &lam, &sigma) != CTRL_GEN_OK) {
    return CTRL_FAULT_NONFINITE_OUTPUT;
  }
  /* a locked joint's q_dot is exactly 0: step_fault scales its column by mask/W = 0 and adds
   * mask * alpha = 0 (finite, as the status says) */
  f = limit_speed(c, J, qd);
  if (f != CTRL_FAULT_NONE) return f;
  f = check_step(c, J, cmd, cmd_max, qd, lam > CTRL_LIT(0.0));
  if (f != CTRL_FAULT_NONE) return f;
  f = accept(c, t, q, qd, NULL, out); /* q_ddot: the backward difference of q_dot */
  if (f != CTRL_FAULT_NONE) return f;
  if (moving(c)) {
    integrate(c, qd);
  }
  return CTRL_FAULT_NONE;
}

#endif

#if CTRL_HAS_WEIGHTED_GPM
/* smoothstep of wgpm/planner.py: x clamped to [0, 1], x^2 (3 - 2x). */
static ctrl_real smoothstep(ctrl_real x) {
  x = min_r(max_r(x, CTRL_LIT(0.0)), CTRL_LIT(1.0));
  return x * x * (CTRL_LIT(3.0) - CTRL_LIT(2.0) * x);
}

#if CTRL_HAS_COLLISION
/* wgpm/planner.py wgpm_null_space_term: step_wgpm's q_dot is linear in its null-space vector z, so
 * z + W_b alpha_C (alpha_C the collision term, unramped) adds W_b alpha_C - W_b^2 J^T (J W_b^2 J^T +
 * rho^2 I)^-1 J W_b alpha_C (W_b = I - diag(w_c), rho the step's damping) =
 * W_b step_gpm(J W_b, 0, alpha_C, rho). */
static ctrl_fault add_wgpm_collision_term(const ctrl *c, const ctrl_real *J, const ctrl_real *q, const ctrl_real *w_c,
                                          ctrl_real rho, ctrl_real *qd) {
  ctrl_real alpha[N], Jw[6 * N], zero[CTRL_NTASK], r[N];
  int i, k;
  if (c->cfg.collision == NULL || c->cfg.collision->gain == CTRL_LIT(0.0)) {
    return CTRL_FAULT_NONE;
  }
  collision_term(c, q, alpha);
  for (i = 0; i < N; ++i) {
    for (k = 0; k < 6; ++k) {
      Jw[k + 6 * i] = J[k + 6 * i] * (CTRL_LIT(1.0) - w_c[i]);
    }
  }
  for (k = 0; k < CTRL_NTASK; ++k) {
    zero[k] = CTRL_LIT(0.0);
  }
  if (ctrl_gen_step_gpm(Jw, zero, alpha, rho, r) != CTRL_GEN_OK) {
    return CTRL_FAULT_NONFINITE_OUTPUT;
  }
  for (i = 0; i < N; ++i) {
    qd[i] = qd[i] + (CTRL_LIT(1.0) - w_c[i]) * r[i];
  }
  return CTRL_FAULT_NONE;
}
#endif

/* Spec 35 (wgpm/planner.py WgpmPlanner.evaluate), one tick: step_wgpm with the ramp. */
static ctrl_fault tick_weighted_gpm(ctrl *c, const ctrl_input *in, ctrl_real t, ctrl_output *out) {
  const ctrl_wg_config *wg = &c->cfg.wg;
  ctrl_real *q = c->q;
  ctrl_real J[6 * N], cmd[CTRL_NTASK], cmd_max, qd[N], w_c[N], rho, sigma, gains[CTRL_WGPM_NCRIT];
  ctrl_real h[CTRL_WGPM_NCRIT], ramp_value = CTRL_LIT(1.0);
  ctrl_fault f;
  int i;

  f = check_command(c, q);
  if (f != CTRL_FAULT_NONE) return f;
  task_command(c, in, t, q, J, cmd, &cmd_max); /* cmd: step_wgpm's status covers it */
  if (wg->ramp_time > CTRL_LIT(0.0)) {
    ctrl_real up = smoothstep(t / wg->ramp_time);
    ctrl_real down = wg->ramp_out ? smoothstep((c->cfg.rr.duration - t) / wg->ramp_time) : CTRL_LIT(1.0);
    ramp_value = up * down;
  }
  if (ctrl_gen_step_wgpm(J, q, cmd, wg->band, wg->t_rmax, wg->epsilon, wg->rho_max, wg->delta, ramp_value, wg->H_lo,
                         wg->H_hi, wg->k_hi, wg->k_lo, wg->u_th, wg->u_band, qd, w_c, &rho, &sigma, gains,
                         h) != CTRL_GEN_OK) {
    return CTRL_FAULT_NONFINITE_OUTPUT;
  }
  for (i = 0; i < N; ++i) {
    c->win_value[i] = w_c[i]; /* reported in out.window: the joint-limit weights W_c */
  }
#if CTRL_HAS_COLLISION
  f = add_wgpm_collision_term(c, J, q, w_c, rho, qd);
  if (f != CTRL_FAULT_NONE) {
    return f;
  }
#endif
  f = limit_speed(c, J, qd);
  if (f != CTRL_FAULT_NONE) return f;
  f = check_step(c, J, cmd, cmd_max, qd, rho > CTRL_LIT(0.0));
  if (f != CTRL_FAULT_NONE) return f;
  f = accept(c, t, q, qd, NULL, out); /* q_ddot: the backward difference of q_dot */
  if (f != CTRL_FAULT_NONE) return f;
  if (moving(c)) {
    integrate(c, qd);
  }
  return CTRL_FAULT_NONE;
}
#endif

/* What the rounding of joint i's two commands, q and the held one, may add to their step
 * (STEP_ROUNDING; mt_delta is 0 outside MOVE_TO). */
static ctrl_real step_rounding(const ctrl *c, const ctrl_real *q, int i) {
  return STEP_ROUNDING * REAL_EPSILON * (CTRL_FABS(q[i]) + CTRL_FABS(c->q_hold[i]) + CTRL_FABS(c->mt_delta[i]));
}

/* A played-back command (PLAYBACK, SAMPLED, MOVE_TO) through the checks of playback: the limits,
 * finite velocities, and each joint's speed: |q_dot_i| <= qdot_max[i] and one tick's step at most
 * qdot_max[i] * dt (a little more for rounding: PLAYBACK_STEP_RTOL, STEP_ROUNDING); then accepted
 * (its torque, accept: qdd the mode's acceleration, or NULL), emitted, and the next tick due. */
static ctrl_fault emit_played(ctrl *c, ctrl_real t, const ctrl_real *q, const ctrl_real *qd, const ctrl_real *qdd,
                              ctrl_output *out) {
  const ctrl_config *cfg = &c->cfg;
  ctrl_fault f = check_command(c, q);
  int i;
  if (f == CTRL_FAULT_NONE && !all_finite(qd, N)) f = CTRL_FAULT_NONFINITE_OUTPUT;
  if (f != CTRL_FAULT_NONE) return f;
  for (i = 0; i < N; ++i) {
    ctrl_real speed_max = cfg->qdot_max[i] * (CTRL_LIT(1.0) + PLAYBACK_STEP_RTOL);
    ctrl_real step = CTRL_FABS(q[i] - c->q_hold[i]), step_max = speed_max * cfg->dt;
    /* the rounding allowance only for a step beyond step_max (rare): no cost on a tick that passes */
    if (CTRL_FABS(qd[i]) > speed_max || (step > step_max && step - step_max > step_rounding(c, q, i))) {
      return CTRL_FAULT_SPEED;
    }
  }
  f = accept(c, t, q, qd, qdd, out);
  if (f != CTRL_FAULT_NONE) return f;
  if (moving(c)) {
    ++c->k;
  }
  return CTRL_FAULT_NONE;
}

/* Playback, tick k: theta, omega and the polynomials' own acceleration eps at t. */
static ctrl_fault tick_playback(ctrl *c, ctrl_real t, ctrl_output *out) {
  const ctrl_config *cfg = &c->cfg;
  const ctrl_pb_config *pb = &cfg->pb;
  ctrl_real q[N], qd[N], qdd[N], th[3];
  int i;
  for (i = 0; i < N; ++i) {
    if (pb->active[i]) {
      if (fw_ptp_eval(pb->coeffs[i], pb->knots, pb->nseg, t, th) != FW_PTP_OK) return CTRL_FAULT_PLAYBACK;
      q[i] = th[0];
      qd[i] = th[1];
      qdd[i] = th[2];
    } else {
      q[i] = cfg->q_start[i];
      qd[i] = CTRL_LIT(0.0);
      qdd[i] = CTRL_LIT(0.0);
    }
  }
  return emit_played(c, t, q, qd, qdd, out);
}

/* Sampled playback, tick k: q = row k exactly; q_dot = (row k+1 - row k) / dt, the velocity
 * that reaches the next command in one period (0 at the last row: the plan ends there). So
 * the speed guard on q_dot checks the step to the next row one tick ahead, and the step guard
 * the step from the previous command (the start, on tick 0). */
static ctrl_fault tick_sampled(ctrl *c, ctrl_real t, ctrl_output *out) {
  const ctrl_config *cfg = &c->cfg;
  const ctrl_real *row = cfg->sp.table + (size_t)c->k * N;
  const ctrl_real *next = c->k < c->n_ticks ? row + N : row;
  ctrl_real q[N], qd[N];
  int i;
  for (i = 0; i < N; ++i) {
    q[i] = row[i];
    qd[i] = (next[i] - row[i]) / cfg->dt;
  }
  return emit_played(c, t, q, qd, NULL, out); /* q_ddot: the backward difference of q_dot (accept) */
}

static void latch(ctrl *c, ctrl_fault f, ctrl_real t) {
  c->state = CTRL_STATE_FAULT;
  c->fault = f;
  c->t_hold = t;
}

/* The lock flags of this tick: a new lock is taken over (FAULT_TOLERANT: masked from this
 * tick; state DEGRADED), a flag on a joint the arm does not have or a withdrawn lock is a
 * LOCK_REPORT fault, more locks than the mode absorbs a REDUNDANCY fault. */
static ctrl_fault update_locks(ctrl *c, uint32_t reported) {
  uint32_t all = (N >= 32) ? 0xFFFFFFFFu : ((1u << N) - 1u);
  uint32_t count = 0u, bits;
  uint32_t allowed = c->cfg.mode == CTRL_MODE_FAULT_TOLERANT ? (uint32_t)(N - CTRL_NTASK) : 0u;
  int i;
  if ((reported & ~all) != 0u || (c->locked & ~reported) != 0u) return CTRL_FAULT_LOCK_REPORT;
  for (bits = reported; bits != 0u; bits &= bits - 1u) {
    ++count;
  }
  if (count > allowed) return CTRL_FAULT_REDUNDANCY;
  if (reported != c->locked) { /* a new lock (a lock is never withdrawn): the mask follows */
    c->locked = reported;
    for (i = 0; i < N; ++i) {
      c->mask[i] = (((reported >> i) & 1u) != 0u) ? CTRL_LIT(0.0) : CTRL_LIT(1.0);
    }
  }
  if (reported != 0u && c->state == CTRL_STATE_RUNNING) {
    c->state = CTRL_STATE_DEGRADED;
  }
  return CTRL_FAULT_NONE;
}

/* The rest-to-rest trapezoid s(tau), tau = t / T in [0, 1], ds/dtau and d2s/dtau2: accelerating
 * over the first MOVE_TO_BLEND of the time, decelerating over the last. */
static void move_to_profile(ctrl_real tau, ctrl_real *s, ctrl_real *ds, ctrl_real *dds) {
  const ctrl_real b = MOVE_TO_BLEND;
  const ctrl_real k = CTRL_LIT(1.0) / (b * (CTRL_LIT(1.0) - b));
  tau = min_r(max_r(tau, CTRL_LIT(0.0)), CTRL_LIT(1.0));
  if (tau < b) {
    *s = CTRL_LIT(0.5) * k * tau * tau;
    *ds = k * tau;
    *dds = k;
  } else if (tau > CTRL_LIT(1.0) - b) {
    ctrl_real r = CTRL_LIT(1.0) - tau;
    *s = CTRL_LIT(1.0) - CTRL_LIT(0.5) * k * r * r;
    *ds = k * r;
    *dds = -k;
  } else {
    *s = (tau - CTRL_LIT(0.5) * b) / (CTRL_LIT(1.0) - b);
    *ds = CTRL_LIT(1.0) / (CTRL_LIT(1.0) - b);
    *dds = CTRL_LIT(0.0);
  }
}

/* MOVE_TO: solve the IK on board from the held command, then plan the shortest common
 * duration (whole ticks) in which every joint's peak speed and acceleration stay within its
 * limits (move_to_ticks). Returns BAD_TARGET for a target that is not a pose, UNREACHABLE when
 * the IK does not converge or its answer lies outside the limits. */
static ctrl_fault plan_move_to(ctrl *c, const ctrl_real *q);

static ctrl_fault start_move_to(ctrl *c, const ctrl_real *target) {
  ctrl_real q[N];
  if (!all_finite(target, 16)) return CTRL_FAULT_NONFINITE_INPUT;
#if CTRL_HAS_MOVE_TO
  {
    ctrl_real pe, oe, iterations, success;
    ctrl_gen_status status = ctrl_gen_ik(target, c->q_hold, c->q_hold, CTRL_LIT(1.0), MOVE_TO_TOL, MOVE_TO_TOL,
                                         MOVE_TO_ITERATIONS, q, &pe, &oe, &iterations, &success);
    if (status == CTRL_GEN_BAD_TARGET) return CTRL_FAULT_BAD_TARGET;
    if (status != CTRL_GEN_OK || !(success > CTRL_LIT(0.5))) return CTRL_FAULT_UNREACHABLE;
  }
#else
  return CTRL_FAULT_UNREACHABLE;
#endif
  if (check_command(c, q) != CTRL_FAULT_NONE) return CTRL_FAULT_UNREACHABLE;
  return plan_move_to(c, q);
}

/* The move from the held command to q (inside the limits) in the shortest whole number of ticks. */
static ctrl_fault plan_move_to(ctrl *c, const ctrl_real *q) {
  const ctrl_config *cfg = &c->cfg;
  ctrl_real ticks = CTRL_LIT(0.0);
  uint32_t n;
  int i;
  for (i = 0; i < N; ++i) {
    /* |delta_i| within the joint's range, which ctrl_init bounded to MOVE_TO_MAX_TICKS */
    ticks = max_r(ticks, move_to_ticks(cfg, i, CTRL_FABS(q[i] - c->q_hold[i])));
    c->mt_q0[i] = c->q_hold[i];
    c->mt_delta[i] = q[i] - c->q_hold[i];
  }
  n = (uint32_t)ticks + 1u; /* whole ticks, at least one: the duration only grows */
  c->mt_T = (ctrl_real)n * cfg->dt;
  c->n_ticks = n;
  c->moving_to = 1;
  c->following = 0;
  c->k = 0;
  c->state = CTRL_STATE_RUNNING;
  return CTRL_FAULT_NONE;
}

/* MOVE_TO_JOINTS: the MOVE_TO profile to a joint target inside the limits (else JOINT_LIMIT). */
static ctrl_fault start_move_to_joints(ctrl *c, const ctrl_real *q) {
  if (!all_finite(q, N)) return CTRL_FAULT_NONFINITE_INPUT;
  if (check_command(c, q) != CTRL_FAULT_NONE) return CTRL_FAULT_JOINT_LIMIT;
  return plan_move_to(c, q);
}

/* SETPOINT, tick k: the caller's command through the checks of a played-back command; a locked
 * joint must keep its held position (else LOCK_REPORT). Without a setpoint this tick: the hold. */
static ctrl_fault tick_setpoint(ctrl *c, const ctrl_input *in, ctrl_real t, ctrl_output *out) {
  ctrl_real zero[N];
  int i;
  if (in == NULL || in->command != CTRL_CMD_SETPOINT) {
    for (i = 0; i < N; ++i) {
      zero[i] = CTRL_LIT(0.0);
    }
    return emit_played(c, t, c->q_hold, zero, NULL, out);
  }
  for (i = 0; i < N; ++i) {
    if (((c->locked >> i) & 1u) != 0u && in->q_ref[i] != c->q_hold[i]) return CTRL_FAULT_LOCK_REPORT;
  }
  return emit_played(c, t, in->q_ref, in->qd_ref, NULL, out);
}

/* MOVE_TO, tick k: the profile's command, through the checks of a played-back command (limits,
 * speed, and the step from the last command: the last tick's too, whose q_dot is 0), with the
 * profile's own acceleration (0 on the last tick: at rest). */
static ctrl_fault tick_move_to(ctrl *c, ctrl_real t, ctrl_output *out) {
  ctrl_real q[N], qd[N], qdd[N], s, ds, dds;
  int i;
  move_to_profile(t / c->mt_T, &s, &ds, &dds);
  for (i = 0; i < N; ++i) {
    q[i] = (c->k >= c->n_ticks) ? c->mt_q0[i] + c->mt_delta[i] : c->mt_q0[i] + s * c->mt_delta[i];
    qd[i] = (c->k >= c->n_ticks) ? CTRL_LIT(0.0) : ds * c->mt_delta[i] / c->mt_T;
    qdd[i] = (c->k >= c->n_ticks) ? CTRL_LIT(0.0) : dds * c->mt_delta[i] / (c->mt_T * c->mt_T);
  }
  return emit_played(c, t, q, qd, qdd, out);
}

static ctrl_fault tick_mode(ctrl *c, const ctrl_input *in, ctrl_real t, ctrl_output *out) {
  if (c->following) return tick_setpoint(c, in, t, out);
  if (c->moving_to) return tick_move_to(c, t, out);
  switch (c->cfg.mode) {
    case CTRL_MODE_PLAYBACK: return tick_playback(c, t, out);
    case CTRL_MODE_SAMPLED: return tick_sampled(c, t, out);
#if CTRL_HAS_FAULT_TOLERANT
    case CTRL_MODE_FAULT_TOLERANT: return tick_fault_tolerant(c, in, t, out);
#endif
#if CTRL_HAS_WEIGHTED_GPM
    case CTRL_MODE_WEIGHTED_GPM: return tick_weighted_gpm(c, in, t, out);
#endif
    case CTRL_MODE_RESOLVED_RATE:
    default: return tick_resolved_rate(c, in, t, out);
  }
}

ctrl_fault ctrl_tick(ctrl *c, const ctrl_input *in, ctrl_output *out) {
  ctrl_command cmd = in != NULL ? in->command : CTRL_CMD_NONE;
  if (c == NULL || out == NULL) {
    return CTRL_FAULT_BAD_ARGS;
  }
  if (c->state != CTRL_STATE_FAULT) {
    ctrl_real t = moving(c) ? tick_time(c) : c->t_hold;
    int starting = c->state == CTRL_STATE_IDLE && cmd == CTRL_CMD_START;
    ctrl_fault f0;
    ctrl_fault lock = in != NULL ? update_locks(c, in->locked) : CTRL_FAULT_NONE;
    if (in != NULL && !all_finite(in->xdot_offset, 6)) {
      latch(c, CTRL_FAULT_NONFINITE_INPUT, t);
    } else if (lock != CTRL_FAULT_NONE) {
      latch(c, lock, t);
    } else if ((moving(c) || starting) && in != NULL && in->missed_ticks > 0u) {
      latch(c, CTRL_FAULT_OVERRUN, t);
    } else if (moving(c) && cmd == CTRL_CMD_STOP) {
      c->state = CTRL_STATE_DONE;
      c->t_hold = t;
    } else if (!moving(c) && cmd == CTRL_CMD_MOVE_TO && (f0 = start_move_to(c, in->target)) != CTRL_FAULT_NONE) {
      latch(c, f0, t); /* the arm holds where it is */
    } else if (!moving(c) && cmd == CTRL_CMD_MOVE_TO_JOINTS && (f0 = start_move_to_joints(c, in->q_ref)) != CTRL_FAULT_NONE) {
      latch(c, f0, t);
    } else if (cmd == CTRL_CMD_STALE) {
      latch(c, CTRL_FAULT_STALE, t); /* holds the current command */
    } else {
      if (cmd == CTRL_CMD_SETPOINT && (!c->following || !moving(c))) { /* takes over: tick 0 of the setpoints */
        c->following = 1;
        c->moving_to = 0;
        c->k = 0;
        c->n_ticks = 0xFFFFFFFFu; /* no last tick: the caller ends it (STOP) */
        c->state = c->locked != 0u ? CTRL_STATE_DEGRADED : CTRL_STATE_RUNNING;
        t = tick_time(c);
      }
      if (c->moving_to && c->k == 0u) {
        t = tick_time(c); /* the MOVE_TO just accepted: its tick 0 */
      }
      if (starting) {
        c->state = c->locked != 0u ? CTRL_STATE_DEGRADED : CTRL_STATE_RUNNING;
        c->k = 0;
        t = tick_time(c);
      }
      if (moving(c)) {
        ctrl_fault f = tick_mode(c, in, t, out);
        if (f == CTRL_FAULT_NONE) {
          return CTRL_FAULT_NONE;
        }
        latch(c, f, t);
      }
    }
  }
#if CTRL_HAS_DYNAMICS
  at_rest(c);
#endif
  emit_hold(c, out);
  return c->fault;
}
