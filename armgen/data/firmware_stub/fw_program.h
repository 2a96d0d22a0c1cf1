/*
 * On-board evaluator of a tool-path program (lines, arcs, rounded corners, sampled poses) and
 * its time law, from a constant table in flash written by armgen/firmware/program_table.py
 * (program_table_c). fw_program_desired(t) is what the planner's ProgramMotion(t) returns
 * (armgen/planning/toolpath/geometry.py and timelaw.py): the same numbers, the same formulas.
 *
 * The table (SI units: m, s, rad; every real a ctrl_real written as CTRL_LIT(<the planner's
 * double>), so the double build holds the planner's numbers exactly; quaternions are SciPy's
 * (x, y, z, w)):
 *
 *   fw_program            duration (s) and length (m) of the program, then a count and a
 *                         pointer per array below (count 0: NULL; sizes FW_PROGRAM_<ARRAY>).
 *   segment[SEGMENTS]     the time law s(t): segment k starts at time t, path length s, path
 *                         speed v (m/s) and keeps the acceleration a (m/s^2) until the next
 *                         one (the last until `duration`). segment[0] is t = s = v = 0.
 *                         The planner's ~4000 grid cells, merged where one quadratic
 *                         reproduces several to 1e-14 m (program_table.MERGE_TOL).
 *   piece[PIECES]         the path, in order: kind (FW_PROGRAM_LINE/ARC/CORNER/SPLINE), index
 *                         into that kind's array, start (path length where the piece begins,
 *                         m), u0 (where it begins on its move: > 0 when a rounded corner
 *                         trimmed the move's start, m) and length (m). A piece evaluates its
 *                         move at u0 + u, u in [0, length].
 *   line[LINES]           p0, unit direction, length of the whole (untrimmed) move, and its
 *                         turn: start rotation q0, rotation vector (rad, frame of q0) turned
 *                         uniformly over the move, angular velocity per metre (rad/m, base).
 *   arc[ARCS]             centre, radius, unit e1 (towards the start) and e2 (towards the
 *                         sweep): p = centre + radius (cos(u/r) e1 + sin(u/r) e2); then the
 *                         move's length and turn as a line's.
 *   corner[CORNERS]       a rounded corner: the cubic Bezier's 4 control points and their 3
 *                         differences, the turn (per unit of the Bezier parameter w: q0,
 *                         rotation vector, angular velocity in rad per unit w), and its map.
 *   spline[SPLINES]       a poses move: its map (first, count) and its knot intervals (first,
 *                         count).
 *   map[MAPS]             the maps w(u) from path length to a curve's parameter, the nodes of
 *                         the planner's CubicHermiteSpline: u (m), w and dw/du at each (the
 *                         cubic Hermite interpolant between nodes; beyond the ends the end
 *                         intervals extrapolate, as SciPy's). A curve's map has >= 2 rows.
 *   knot[KNOTS]           a poses move's spline intervals: left end tau_i (chord length, m),
 *                         the rotation at it (quaternion), the position spline's coefficients
 *                         (SciPy's CubicSpline, c[j][axis] of x^(3-j), x = w - tau_i) and the
 *                         RotationSpline's rotation-vector coefficients (of x^3, x^2, x; frame
 *                         of q); w is the chord length the map gives.
 *
 * Sizes: each array is a `static const` array of its length FW_PROGRAM_SEGMENTS, _PIECES,
 * _LINES, _ARCS, _CORNERS, _SPLINES, _MAPS, _KNOTS, macros of the generated header (one program
 * per header; include it in one translation unit). The controller keeps only a pointer to the
 * fw_program: no heap, no copies. Flash per row, double (float: the reals halve): segment 32 B,
 * piece 32, line 136, arc 168, corner 256, spline 16, map 24, knot 208; a rounded corner has a
 * 257-row map, a poses move 16 map rows and one knot per CSV row. The bar program of issue 26
 * (4 lines, 2 arcs, 5 corners): 36 KB double, 18 KB float.
 */
#ifndef ARMGEN_FW_PROGRAM_H
#define ARMGEN_FW_PROGRAM_H

#include <stddef.h>

#include "ctrl_robot.h"

/* fw_program_check: a unit vector or quaternion of the table is unit to this (the planner's
 * are to ~1e-16; rounded to float and squared there, to a few 1e-7), and the time law ends
 * where the path does, at rest, to this fraction of the length / of its top speed. */
#if CTRL_USE_FLOAT
#define FW_PROGRAM_UNIT_TOL CTRL_LIT(1e-5)
#else
#define FW_PROGRAM_UNIT_TOL CTRL_LIT(1e-12)
#endif
#define FW_PROGRAM_END_RTOL CTRL_LIT(1e-4)

/* piece kinds */
#define FW_PROGRAM_LINE 0
#define FW_PROGRAM_ARC 1
#define FW_PROGRAM_CORNER 2
#define FW_PROGRAM_SPLINE 3

typedef struct {
  ctrl_real t, s, v, a; /* start time (s), path length (m), speed (m/s); acceleration (m/s^2) */
} fw_program_segment;

typedef struct {
  int kind;         /* FW_PROGRAM_LINE, _ARC, _CORNER or _SPLINE */
  int index;        /* into fw_program.line, .arc, .corner or .spline */
  ctrl_real start;  /* path length where the piece begins, m */
  ctrl_real u0;     /* where the piece begins on its move, m */
  ctrl_real length; /* m */
} fw_program_piece;

typedef struct {
  ctrl_real p0[3];        /* m */
  ctrl_real direction[3]; /* unit */
  ctrl_real length;       /* of the whole move, m */
  ctrl_real q0[4];        /* rotation at the move's start */
  ctrl_real rotvec[3];    /* turn over the move, rad */
  ctrl_real omega[3];     /* angular velocity per metre of path, rad/m, base frame */
} fw_program_line;

typedef struct {
  ctrl_real centre[3]; /* m */
  ctrl_real radius;    /* m */
  ctrl_real e1[3];     /* unit, centre to start */
  ctrl_real e2[3];     /* unit, in the plane, towards the sweep */
  ctrl_real length;    /* of the whole move, m */
  ctrl_real q0[4];
  ctrl_real rotvec[3];
  ctrl_real omega[3]; /* rad/m */
} fw_program_arc;

typedef struct {
  ctrl_real control[4][3]; /* Bezier control points, m */
  ctrl_real chord[3][3];   /* control[i + 1] - control[i] */
  ctrl_real q0[4];         /* rotation where the corner begins */
  ctrl_real rotvec[3];     /* turn over the corner (w from 0 to 1), rad */
  ctrl_real omega[3];      /* angular velocity per unit w, rad, base frame */
  int map, maps;           /* first row and rows in fw_program.map */
} fw_program_corner;

typedef struct {
  int map, maps;     /* first row and rows in fw_program.map */
  int knot, knots;   /* first interval and intervals in fw_program.knot */
} fw_program_spline;

typedef struct {
  ctrl_real u;     /* path length on the move, m */
  ctrl_real w;     /* the curve's parameter there */
  ctrl_real slope; /* dw/du there, 1/m (1 / |dp/dw|) */
} fw_program_map;

typedef struct {
  ctrl_real tau;            /* left end of the interval (chord length), m */
  ctrl_real q[4];           /* rotation at tau */
  ctrl_real position[4][3]; /* p = c0 x^3 + c1 x^2 + c2 x + c3 per axis, x = w - tau, m */
  ctrl_real rotvec[3][3];   /* rotation vector c0 x^3 + c1 x^2 + c2 x (frame of q), rad */
} fw_program_knot;

typedef struct {
  ctrl_real duration; /* s */
  ctrl_real length;   /* m */
  int segments;
  const fw_program_segment *segment;
  int pieces;
  const fw_program_piece *piece;
  int lines;
  const fw_program_line *line;
  int arcs;
  const fw_program_arc *arc;
  int corners;
  const fw_program_corner *corner;
  int splines;
  const fw_program_spline *spline;
  int maps;
  const fw_program_map *map;
  int knots;
  const fw_program_knot *knot;
} fw_program;

/* 1 when the table is well formed (counts and indices consistent, every number finite, times,
 * path lengths and interval ends strictly increasing, unit vectors and quaternions unit to
 * FW_PROGRAM_UNIT_TOL, the time law at rest at both ends and ending where the path does),
 * else 0. fw_program_desired may only be called on a table it accepted. */
int fw_program_check(const fw_program *prog);

/* The time law's duration, s. */
ctrl_real fw_program_duration(const fw_program *prog);

/* The desired tool pose and twist at time t (s): position p[3] (m), rotation R[9]
 * column-major, twist xdot[6] = [v; w] (m/s, rad/s, base frame). t is clamped to
 * [0, duration]: at rest at the start before 0 (and for NaN), at the end from `duration` on. */
void fw_program_desired(const fw_program *prog, ctrl_real t, ctrl_real *p, ctrl_real *R, ctrl_real *xdot);

#endif /* ARMGEN_FW_PROGRAM_H */
