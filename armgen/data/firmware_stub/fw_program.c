/*
 * On-board evaluator of a tool-path program, see fw_program.h. Each formula is the planner's
 * (armgen/planning/toolpath/geometry.py, timelaw.py) and SciPy's behind it (Rotation's
 * from_rotvec / compose / as_matrix, PPoly, RotationSpline's angular rate), in the same order
 * of operations where that is cheap, so that the double build agrees with the planner to
 * rounding. Stateless: each call finds its time-law segment, piece and interval by binary
 * search (log2 of the table's sizes: ~7 + 4 + 8 steps on the bar program).
 */
#include "fw_program.h"

#include <math.h>

/* SciPy's Rotation.from_rotvec switches to its Taylor series of sin(a/2)/a at this angle. */
#define ROTVEC_SERIES_ANGLE CTRL_LIT(1e-3)
/* RotationSpline's angular rate, k1 = (1 - cos n)/n^2, k2 = (n - sin n)/n^3 of the rotation
 * vector's norm n: the double build switches to the series where SciPy does (1e-4), to compute
 * what the planner computed. In float 1 - cos n and n - sin n cancel (k1 would lose
 * eps/n^2 relative: 12 % at 1e-3), so the series (4 terms, truncation below 1e-9 relative
 * for n <= 0.5) serves up to 0.5 and half-angle forms beyond. */
#if CTRL_USE_FLOAT
#define RATE_SERIES_ANGLE CTRL_LIT(0.5)
#else
#define RATE_SERIES_ANGLE CTRL_LIT(1e-4)
#endif

#define ONE CTRL_LIT(1.0)
#define TWO CTRL_LIT(2.0)
#define THREE CTRL_LIT(3.0)
#define HALF CTRL_LIT(0.5)

/* The largest index i in [0, n) with key(a[i]) <= x, 0 when there is none (or x is NaN):
 * SciPy's interval search (searchsorted(side="right") - 1, clamped). Branch-free halving (the
 * answer stays in [lo, lo + n)): a conditional select per step on the M4. */
#define DEFINE_SEARCH(name, type, key)                                                           \
  static int name(const type *a, int n, ctrl_real x) {                                          \
    int lo = 0;                                                                                  \
    while (n > 1) {                                                                              \
      int half = n / 2;                                                                          \
      lo = a[lo + half].key <= x ? lo + half : lo;                                               \
      n -= half;                                                                                 \
    }                                                                                            \
    return lo;                                                                                   \
  }
DEFINE_SEARCH(search_segment, fw_program_segment, t)
DEFINE_SEARCH(search_piece, fw_program_piece, start)
DEFINE_SEARCH(search_map, fw_program_map, u)
DEFINE_SEARCH(search_knot, fw_program_knot, tau)

static ctrl_real vec_dot(const ctrl_real *a, const ctrl_real *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void vec_cross(const ctrl_real *a, const ctrl_real *b, ctrl_real *out) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}

/* R (column-major) of q0 * exp(v): SciPy's Rotation.from_quat(q0) * Rotation.from_rotvec(v). */
static void rotate(const ctrl_real *q0, const ctrl_real *v, ctrl_real *R) {
  ctrl_real q[4];
  if (v[0] == CTRL_LIT(0.0) && v[1] == CTRL_LIT(0.0) && v[2] == CTRL_LIT(0.0)) {
    q[0] = q0[0]; /* exp(0) = (0, 0, 0, 1): the product is q0 exactly */
    q[1] = q0[1];
    q[2] = q0[2];
    q[3] = q0[3];
  } else {
    ctrl_real angle = CTRL_SQRT(vec_dot(v, v));
    ctrl_real angle2 = angle * angle;
    ctrl_real scale = angle <= ROTVEC_SERIES_ANGLE
                          ? HALF - angle2 / CTRL_LIT(48.0) + angle2 * angle2 / CTRL_LIT(3840.0)
                          : CTRL_SIN(angle / TWO) / angle;
    ctrl_real r[4], c[3];
    r[0] = v[0] * scale;
    r[1] = v[1] * scale;
    r[2] = v[2] * scale;
    r[3] = CTRL_COS(angle / TWO);
    vec_cross(q0, r, c);
    q[0] = q0[3] * r[0] + r[3] * q0[0] + c[0];
    q[1] = q0[3] * r[1] + r[3] * q0[1] + c[1];
    q[2] = q0[3] * r[2] + r[3] * q0[2] + c[2];
    q[3] = q0[3] * r[3] - q0[0] * r[0] - q0[1] * r[1] - q0[2] * r[2];
  }
  {
    ctrl_real x2 = q[0] * q[0], y2 = q[1] * q[1], z2 = q[2] * q[2], w2 = q[3] * q[3];
    ctrl_real xy = q[0] * q[1], zw = q[2] * q[3], xz = q[0] * q[2];
    ctrl_real yw = q[1] * q[3], yz = q[1] * q[2], xw = q[0] * q[3];
    R[0] = x2 - y2 - z2 + w2;
    R[1] = TWO * (xy + zw);
    R[2] = TWO * (xz - yw);
    R[3] = TWO * (xy - zw);
    R[4] = -x2 + y2 - z2 + w2;
    R[5] = TWO * (yz + xw);
    R[6] = TWO * (xz + yw);
    R[7] = TWO * (yz - xw);
    R[8] = -x2 - y2 + z2 + w2;
  }
}

/* A curve's parameter w at path length u: SciPy's CubicHermiteSpline through the map's nodes,
 * its interval's coefficients computed as SciPy computes them (the same operations: the double
 * build gets its very numbers), beyond the ends the end intervals extrapolated. */
static ctrl_real map_w(const fw_program_map *map, int rows, ctrl_real u) {
  const fw_program_map *m0 = &map[search_map(map, rows - 1, u)];
  const fw_program_map *m1 = &m0[1];
  ctrl_real dx = m1->u - m0->u, x = u - m0->u;
  ctrl_real slope = (m1->w - m0->w) / dx;
  ctrl_real t = (m0->slope + m1->slope - TWO * slope) / dx;
  ctrl_real c0 = t / dx, c1 = (slope - m0->slope) / dx - t;
  return ((c0 * x + c1) * x + m0->slope) * x + m0->w;
}

/* Each kind at u on its (untrimmed) move: position p, rotation R, and in rate[6] the unit
 * tangent and the angular velocity per metre (the twist per m/s of path speed). */

static void eval_line(const fw_program_line *l, ctrl_real u, ctrl_real *p, ctrl_real *R, ctrl_real *rate) {
  ctrl_real x = u / l->length, v[3];
  int i;
  for (i = 0; i < 3; ++i) {
    p[i] = l->p0[i] + u * l->direction[i];
    rate[i] = l->direction[i];
    rate[i + 3] = l->omega[i];
    v[i] = x * l->rotvec[i];
  }
  rotate(l->q0, v, R);
}

static void eval_arc(const fw_program_arc *a, ctrl_real u, ctrl_real *p, ctrl_real *R, ctrl_real *rate) {
  ctrl_real phi = u / a->radius, x = u / a->length, v[3];
  ctrl_real c = CTRL_COS(phi), s = CTRL_SIN(phi);
  int i;
  for (i = 0; i < 3; ++i) {
    p[i] = a->centre[i] + a->radius * (c * a->e1[i] + s * a->e2[i]);
    rate[i] = -s * a->e1[i] + c * a->e2[i];
    rate[i + 3] = a->omega[i];
    v[i] = x * a->rotvec[i];
  }
  rotate(a->q0, v, R);
}

static void eval_corner(const fw_program *prog, const fw_program_corner *k, ctrl_real u, ctrl_real *p, ctrl_real *R,
                        ctrl_real *rate) {
  ctrl_real w = map_w(&prog->map[k->map], k->maps, u), m = ONE - w;
  ctrl_real b0 = m * m * m, b1 = THREE * m * m * w, b2 = THREE * m * w * w, b3 = w * w * w;
  ctrl_real d0 = m * m, d1 = TWO * m * w, d2 = w * w, d[3], speed, v[3];
  int i;
  for (i = 0; i < 3; ++i) {
    p[i] = b0 * k->control[0][i] + b1 * k->control[1][i] + b2 * k->control[2][i] + b3 * k->control[3][i];
    d[i] = THREE * (d0 * k->chord[0][i] + d1 * k->chord[1][i] + d2 * k->chord[2][i]);
    v[i] = w * k->rotvec[i];
  }
  speed = CTRL_SQRT(vec_dot(d, d));
  for (i = 0; i < 3; ++i) { /* a table whose curve stops (no direction) gives rate 0, not NaN */
    rate[i] = speed > CTRL_LIT(0.0) ? d[i] / speed : CTRL_LIT(0.0);
    rate[i + 3] = speed > CTRL_LIT(0.0) ? k->omega[i] / speed : CTRL_LIT(0.0);
  }
  rotate(k->q0, v, R);
}

/* k1, k2 of RotationSpline's rotation-vector rate to angular rate, I - k1 [r]x + k2 [r]x^2. */
static void rate_factors(ctrl_real n, ctrl_real *k1, ctrl_real *k2) {
  ctrl_real n2 = n * n;
  if (n <= RATE_SERIES_ANGLE) {
#if CTRL_USE_FLOAT
    *k1 = HALF - n2 * (CTRL_LIT(1.0) / CTRL_LIT(24.0) -
                       n2 * (CTRL_LIT(1.0) / CTRL_LIT(720.0) - n2 * (CTRL_LIT(1.0) / CTRL_LIT(40320.0))));
    *k2 = CTRL_LIT(1.0) / CTRL_LIT(6.0) -
          n2 * (CTRL_LIT(1.0) / CTRL_LIT(120.0) -
                n2 * (CTRL_LIT(1.0) / CTRL_LIT(5040.0) - n2 * (CTRL_LIT(1.0) / CTRL_LIT(362880.0))));
#else
    *k1 = HALF - n2 / CTRL_LIT(24.0); /* SciPy's two-term series */
    *k2 = CTRL_LIT(1.0) / CTRL_LIT(6.0) - n2 / CTRL_LIT(120.0);
#endif
  } else {
#if CTRL_USE_FLOAT
    ctrl_real sh = CTRL_SIN(HALF * n), ch = CTRL_COS(HALF * n);
    *k1 = TWO * sh * sh / n2;
    *k2 = (n - TWO * sh * ch) / (n2 * n);
#else
    *k1 = (ONE - CTRL_COS(n)) / n2;
    *k2 = (n - CTRL_SIN(n)) / (n2 * n);
#endif
  }
}

static void eval_spline(const fw_program *prog, const fw_program_spline *sp, ctrl_real u, ctrl_real *p, ctrl_real *R,
                        ctrl_real *rate) {
  ctrl_real w = map_w(&prog->map[sp->map], sp->maps, u);
  const fw_program_knot *k = &prog->knot[sp->knot + search_knot(&prog->knot[sp->knot], sp->knots, w)];
  ctrl_real x = w - k->tau, d[3], r[3], rdot[3], c1[3], c2[3], body[3], k1, k2, speed;
  int i;
  for (i = 0; i < 3; ++i) {
    p[i] = ((k->position[0][i] * x + k->position[1][i]) * x + k->position[2][i]) * x + k->position[3][i];
    d[i] = (THREE * k->position[0][i] * x + TWO * k->position[1][i]) * x + k->position[2][i];
    r[i] = ((k->rotvec[0][i] * x + k->rotvec[1][i]) * x + k->rotvec[2][i]) * x;
    rdot[i] = (THREE * k->rotvec[0][i] * x + TWO * k->rotvec[1][i]) * x + k->rotvec[2][i];
  }
  speed = CTRL_SQRT(vec_dot(d, d));
  rotate(k->q, r, R);
  rate_factors(CTRL_SQRT(vec_dot(r, r)), &k1, &k2);
  vec_cross(r, rdot, c1);
  vec_cross(r, c1, c2);
  for (i = 0; i < 3; ++i) {
    body[i] = rdot[i] - k1 * c1[i] + k2 * c2[i];
  }
  for (i = 0; i < 3; ++i) { /* body to base frame, per metre of path (0 where the curve stops) */
    rate[i] = speed > CTRL_LIT(0.0) ? d[i] / speed : CTRL_LIT(0.0);
    rate[i + 3] = speed > CTRL_LIT(0.0) ? (R[i] * body[0] + R[i + 3] * body[1] + R[i + 6] * body[2]) / speed
                                        : CTRL_LIT(0.0);
  }
}

ctrl_real fw_program_duration(const fw_program *prog) { return prog->duration; }

void fw_program_desired(const fw_program *prog, ctrl_real t, ctrl_real *p, ctrl_real *R, ctrl_real *xdot) {
  const fw_program_segment *seg;
  const fw_program_piece *piece;
  ctrl_real time = CTRL_LIT(0.0), moving = ONE, tau, s, sdot, u; /* moving: 0 from the end on */
  int i;
  if (t >= prog->duration) {
    time = prog->duration;
    moving = CTRL_LIT(0.0);
  } else if (t > CTRL_LIT(0.0)) {
    time = t;
  } else {
    /* before the start, or NaN: at rest at the start */
  }
  seg = &prog->segment[search_segment(prog->segment, prog->segments, time)];
  tau = time - seg->t;
  sdot = (seg->v + seg->a * tau) * moving;
  s = seg->s + seg->v * tau + HALF * seg->a * tau * tau;
  if (s > prog->length) {
    s = prog->length;
  }
  if (s < CTRL_LIT(0.0)) {
    s = CTRL_LIT(0.0);
  }
  piece = &prog->piece[search_piece(prog->piece, prog->pieces, s)];
  u = s - piece->start;
  if (u < CTRL_LIT(0.0)) {
    u = CTRL_LIT(0.0);
  }
  if (u > piece->length) {
    u = piece->length;
  }
  u += piece->u0;
  switch (piece->kind) {
    case FW_PROGRAM_LINE:
      eval_line(&prog->line[piece->index], u, p, R, xdot);
      break;
    case FW_PROGRAM_ARC:
      eval_arc(&prog->arc[piece->index], u, p, R, xdot);
      break;
    case FW_PROGRAM_CORNER:
      eval_corner(prog, &prog->corner[piece->index], u, p, R, xdot);
      break;
    default: /* FW_PROGRAM_SPLINE (fw_program_check admits no other kind) */
      eval_spline(prog, &prog->spline[piece->index], u, p, R, xdot);
      break;
  }
  for (i = 0; i < 6; ++i) {
    xdot[i] *= sdot;
  }
}

/* ------------------------------------------------------------------ fw_program_check */

static int finite(ctrl_real x) {
  ctrl_real d = x - x; /* 0 for finite x, NaN for inf and NaN */
  return d == d;
}

static int finite_n(const ctrl_real *x, int n) {
  int i;
  for (i = 0; i < n; ++i) {
    if (!finite(x[i])) {
      return 0;
    }
  }
  return 1;
}

static int unit(const ctrl_real *x, int n) {
  ctrl_real sq = CTRL_LIT(0.0);
  int i;
  for (i = 0; i < n; ++i) {
    sq += x[i] * x[i];
  }
  return CTRL_FABS(sq - ONE) <= TWO * FW_PROGRAM_UNIT_TOL;
}

/* first + count within [0, total], count >= 1 (no overflow) */
static int range_ok(int first, int count, int total) { return first >= 0 && count >= 1 && count <= total - first; }

static int array_ok(int count, const void *array) { return count >= 0 && ((count == 0) == (array == NULL)); }

static int turn_ok(const ctrl_real *q0, const ctrl_real *rotvec, const ctrl_real *omega) {
  return finite_n(q0, 4) && unit(q0, 4) && finite_n(rotvec, 3) && finite_n(omega, 3);
}

static int map_ok(const fw_program *prog, int first, int rows) {
  int i;
  if (rows < 2 || !range_ok(first, rows, prog->maps)) {
    return 0;
  }
  for (i = first; i < first + rows; ++i) {
    const fw_program_map *m = &prog->map[i];
    if (!finite(m->u) || !finite(m->w) || !finite(m->slope) ||
        (i > first && !(prog->map[i].u > prog->map[i - 1].u))) {
      return 0;
    }
  }
  return 1;
}

static int spline_ok(const fw_program *prog, const fw_program_spline *sp) {
  int i;
  if (!map_ok(prog, sp->map, sp->maps) || !range_ok(sp->knot, sp->knots, prog->knots)) {
    return 0;
  }
  for (i = sp->knot; i < sp->knot + sp->knots; ++i) {
    const fw_program_knot *k = &prog->knot[i];
    if (!finite(k->tau) || !finite_n(k->q, 4) || !unit(k->q, 4) || !finite_n(&k->position[0][0], 12) ||
        !finite_n(&k->rotvec[0][0], 9) || (i > sp->knot && !(k->tau > prog->knot[i - 1].tau))) {
      return 0;
    }
  }
  return 1;
}

static int line_ok(const fw_program_line *l) {
  return finite_n(l->p0, 3) && finite_n(l->direction, 3) && unit(l->direction, 3) && finite(l->length) &&
         l->length > CTRL_LIT(0.0) && turn_ok(l->q0, l->rotvec, l->omega);
}

static int arc_ok(const fw_program_arc *a) {
  return finite_n(a->centre, 3) && finite(a->radius) && a->radius > CTRL_LIT(0.0) && finite_n(a->e1, 3) &&
         finite_n(a->e2, 3) && unit(a->e1, 3) && unit(a->e2, 3) &&
         CTRL_FABS(vec_dot(a->e1, a->e2)) <= FW_PROGRAM_UNIT_TOL && finite(a->length) && a->length > CTRL_LIT(0.0) &&
         turn_ok(a->q0, a->rotvec, a->omega);
}

static int corner_ok(const fw_program *prog, const fw_program_corner *k) {
  return finite_n(&k->control[0][0], 12) && finite_n(&k->chord[0][0], 9) && turn_ok(k->q0, k->rotvec, k->omega) &&
         map_ok(prog, k->map, k->maps);
}

/* A piece: its numbers, and its kind's entry (the index checked before it is used). */
static int piece_ok(const fw_program *prog, const fw_program_piece *pc) {
  int i = pc->index, ok = 0;
  if (finite(pc->start) && finite(pc->u0) && finite(pc->length) && pc->u0 >= CTRL_LIT(0.0) &&
      pc->length > CTRL_LIT(0.0) && i >= 0) {
    switch (pc->kind) {
      case FW_PROGRAM_LINE:
        ok = i < prog->lines && line_ok(&prog->line[i]);
        break;
      case FW_PROGRAM_ARC:
        ok = i < prog->arcs && arc_ok(&prog->arc[i]);
        break;
      case FW_PROGRAM_CORNER:
        ok = i < prog->corners && corner_ok(prog, &prog->corner[i]);
        break;
      case FW_PROGRAM_SPLINE:
        ok = i < prog->splines && spline_ok(prog, &prog->spline[i]);
        break;
      default:
        break;
    }
  }
  return ok;
}

int fw_program_check(const fw_program *prog) {
  const fw_program_segment *last;
  ctrl_real top = CTRL_LIT(0.0), tau;
  int k;
  if (prog == NULL || !finite(prog->duration) || !(prog->duration > CTRL_LIT(0.0)) || !finite(prog->length) ||
      !(prog->length > CTRL_LIT(0.0)) || prog->segments < 1 || prog->pieces < 1 ||
      !array_ok(prog->segments, prog->segment) || !array_ok(prog->pieces, prog->piece) ||
      !array_ok(prog->lines, prog->line) || !array_ok(prog->arcs, prog->arc) ||
      !array_ok(prog->corners, prog->corner) || !array_ok(prog->splines, prog->spline) ||
      !array_ok(prog->maps, prog->map) || !array_ok(prog->knots, prog->knot)) {
    return 0;
  }
  /* the time law: from rest at 0, times and path lengths increasing, speeds >= 0 */
  for (k = 0; k < prog->segments; ++k) {
    const fw_program_segment *g = &prog->segment[k];
    if (!finite(g->t) || !finite(g->s) || !finite(g->v) || !finite(g->a) || !(g->v >= CTRL_LIT(0.0)) ||
        !(g->t < prog->duration) || !(g->s < prog->length)) {
      return 0;
    }
    if (k == 0 ? (g->t != CTRL_LIT(0.0) || g->s != CTRL_LIT(0.0) || g->v != CTRL_LIT(0.0))
               : !(g->t > prog->segment[k - 1].t && g->s > prog->segment[k - 1].s)) {
      return 0;
    }
    top = g->v > top ? g->v : top;
  }
  last = &prog->segment[prog->segments - 1];
  tau = prog->duration - last->t; /* ... to rest where the path ends */
  if (CTRL_FABS(last->s + last->v * tau + HALF * last->a * tau * tau - prog->length) >
          FW_PROGRAM_END_RTOL * prog->length ||
      CTRL_FABS(last->v + last->a * tau) > FW_PROGRAM_END_RTOL * top) {
    return 0;
  }
  /* the pieces: from 0, end to end, up to the path's length */
  for (k = 0; k < prog->pieces; ++k) {
    const fw_program_piece *pc = &prog->piece[k];
    ctrl_real end = k + 1 < prog->pieces ? prog->piece[k + 1].start : prog->length;
    if (!piece_ok(prog, pc) || (k == 0 && pc->start != CTRL_LIT(0.0)) || !(end > pc->start) ||
        CTRL_FABS(pc->start + pc->length - end) > FW_PROGRAM_END_RTOL * prog->length) {
      return 0;
    }
  }
  return 1;
}
