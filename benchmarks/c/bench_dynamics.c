/*
 * Host benchmark driver for the generated dynamics of one robot: <prefix>_gravity(q, tau),
 * _rnea(q, dq, ddq, tau), _mass_matrix(q, M) and _coriolis(q, dq, c).
 *
 * Compiled by benchmarks/bench_dynamics.py with the strict flags, e.g.
 *   gcc -std=c99 -Wall ... -O2 -DBENCH_HEADER='"iiwa14.h"' -DBENCH_PREFIX=iiwa14 -DBENCH_NDOF=7 \
 *       [-DIIWA14_USE_FLOAT=1] bench_dynamics.c iiwa14.c -lm
 * The generated code is its own translation unit (no LTO), so a call is never inlined or
 * hoisted; the inputs cycle through a table of QTABLE pseudo-random (q, dq, ddq) and every
 * output feeds a running sum that is printed, so every result is live.
 *
 * Usage:
 *   bench time <function> <ncalls> <repeats>   print "ns_per_call <best of repeats>"
 *   (function: gravity, rnea, mass_matrix or coriolis)
 */
#define _POSIX_C_SOURCE 199309L

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include BENCH_HEADER

#ifndef BENCH_PREFIX
#error "define BENCH_PREFIX (the generated code's prefix)"
#endif
#ifndef BENCH_NDOF
#error "define BENCH_NDOF (number of joints)"
#endif

#define PASTE2(a, b) a##b
#define PASTE(a, b) PASTE2(a, b)
#define FN(name) PASTE(BENCH_PREFIX, name)
#define QTABLE 256 /* a power of two */

typedef PASTE(BENCH_PREFIX, _real) real_t;

static real_t qtab[QTABLE][BENCH_NDOF], dqtab[QTABLE][BENCH_NDOF], ddqtab[QTABLE][BENCH_NDOF];

/* Deterministic inputs: q in [-2, 2) rad, dq in [-2, 2) rad/s, ddq in [-10, 10) rad/s^2. */
static void fill_tables(void) {
  unsigned long state = 12345u;
  int i, k;
  for (i = 0; i < QTABLE; ++i) {
    for (k = 0; k < BENCH_NDOF; ++k) {
      state = (state * 1103515245u + 12345u) & 0x7fffffffu;
      qtab[i][k] = (real_t)(4.0 * ((double)state / 2147483648.0) - 2.0);
      state = (state * 1103515245u + 12345u) & 0x7fffffffu;
      dqtab[i][k] = (real_t)(4.0 * ((double)state / 2147483648.0) - 2.0);
      state = (state * 1103515245u + 12345u) & 0x7fffffffu;
      ddqtab[i][k] = (real_t)(20.0 * ((double)state / 2147483648.0) - 10.0);
    }
  }
}

enum which { GRAVITY, RNEA, MASS_MATRIX, CORIOLIS };

static double run(enum which fn, long ncalls) {
  real_t out[BENCH_NDOF * BENCH_NDOF];
  double sink = 0.0;
  long i;
  for (i = 0; i < ncalls; ++i) {
    long s = i & (QTABLE - 1);
    switch (fn) {
      case GRAVITY: FN(_gravity)(qtab[s], out); break;
      case RNEA: FN(_rnea)(qtab[s], dqtab[s], ddqtab[s], out); break;
      case MASS_MATRIX: FN(_mass_matrix)(qtab[s], out); break;
      case CORIOLIS: FN(_coriolis)(qtab[s], dqtab[s], out); break;
    }
    sink += (double)out[i % BENCH_NDOF];
  }
  return sink;
}

static double now_ns(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

int main(int argc, char **argv) {
  static const char *const names[] = {"gravity", "rnea", "mass_matrix", "coriolis"};
  int which = -1, k;
  fill_tables();
  if (argc >= 4 && strcmp(argv[1], "time") == 0) {
    for (k = 0; k < 4; ++k) {
      if (strcmp(argv[2], names[k]) == 0) which = k;
    }
  }
  if (which >= 0) {
    long ncalls = atol(argv[3]);
    int repeats = argc >= 5 ? atoi(argv[4]) : 5, r;
    double best = 1e300, sink = run((enum which)which, ncalls / 10 + 1); /* warm-up */
    for (r = 0; r < repeats; ++r) {
      double t0 = now_ns(), dt;
      sink += run((enum which)which, ncalls);
      dt = (now_ns() - t0) / (double)ncalls;
      if (dt < best) best = dt;
    }
    printf("ns_per_call %.3f\nsink %.6g\n", best, sink);
    return 0;
  }
  fprintf(stderr, "usage: %s time gravity|rnea|mass_matrix|coriolis <ncalls> [repeats]\n", argv[0]);
  return 2;
}
