/*
 * Host benchmark driver for a generated `<prefix>_fk_jacobian(q, T, J)` (or any function
 * with the same shape: const real q[NDOF] in, real T[16] and real J[6*NDOF] out).
 *
 * Compiled by benchmarks/bench_kinematics.py with the strict flags, e.g.
 *   gcc -std=c99 -Wall ... -O2 -DBENCH_HEADER='"modular8.h"' -DBENCH_FN=modular8_fk_jacobian \
 *       -DBENCH_REAL=modular8_real -DBENCH_NDOF=8 [-DMODULAR8_USE_FLOAT=1] \
 *       bench_fk_jacobian.c modular8.c -lm
 * The function under test lives in its own translation unit (no LTO), so the call cannot be
 * inlined or hoisted; q cycles through a table of QTABLE pseudo-random configurations and a
 * running sum of outputs is printed, so every result is live.
 *
 * Usage:
 *   bench time  <ncalls> <repeats>   print "ns_per_call <best of repeats>"
 *   bench count <ncalls>             just make ncalls calls (for valgrind --tool=callgrind)
 *   bench check q_1 ... q_NDOF       print T (16 values) and J (6*NDOF values), column-major
 */
#define _POSIX_C_SOURCE 199309L

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include BENCH_HEADER

#ifndef BENCH_FN
#error "define BENCH_FN (the function under test)"
#endif
#ifndef BENCH_REAL
#define BENCH_REAL double
#endif
#ifndef BENCH_NDOF
#error "define BENCH_NDOF (number of joints)"
#endif

#define QTABLE 256 /* a power of two; callgrind runs use multiples of it */

typedef BENCH_REAL real_t;

static real_t qtab[QTABLE][BENCH_NDOF];

/* Deterministic configurations in [-2, 2) rad (inside every bundled robot's limits). */
static void fill_table(void) {
  unsigned long state = 12345u;
  int i, k;
  for (i = 0; i < QTABLE; ++i) {
    for (k = 0; k < BENCH_NDOF; ++k) {
      state = (state * 1103515245u + 12345u) & 0x7fffffffu;
      qtab[i][k] = (real_t)(4.0 * ((double)state / 2147483648.0) - 2.0);
    }
  }
}

static double run(long ncalls) {
  real_t T[16], J[6 * BENCH_NDOF];
  double sink = 0.0;
  long i;
  for (i = 0; i < ncalls; ++i) {
    BENCH_FN(qtab[i & (QTABLE - 1)], T, J);
    sink += (double)T[12] + (double)J[i % (6 * BENCH_NDOF)];
  }
  return sink;
}

static double now_ns(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

int main(int argc, char **argv) {
  fill_table();
  if (argc >= 3 && strcmp(argv[1], "time") == 0) {
    long ncalls = atol(argv[2]);
    int repeats = argc >= 4 ? atoi(argv[3]) : 5;
    double best = 1e300, sink = run(ncalls / 10 + 1); /* warm-up */
    int r;
    for (r = 0; r < repeats; ++r) {
      double t0 = now_ns(), dt;
      sink += run(ncalls);
      dt = (now_ns() - t0) / (double)ncalls;
      if (dt < best) best = dt;
    }
    printf("ns_per_call %.3f\nsink %.6g\n", best, sink);
    return 0;
  }
  if (argc >= 3 && strcmp(argv[1], "count") == 0) {
    printf("sink %.6g\n", run(atol(argv[2])));
    return 0;
  }
  if (argc == 2 + BENCH_NDOF && strcmp(argv[1], "check") == 0) {
    real_t q[BENCH_NDOF], T[16], J[6 * BENCH_NDOF];
    int k;
    for (k = 0; k < BENCH_NDOF; ++k) q[k] = (real_t)atof(argv[2 + k]);
    BENCH_FN(q, T, J);
    for (k = 0; k < 16; ++k) printf("%.17g\n", (double)T[k]);
    for (k = 0; k < 6 * BENCH_NDOF; ++k) printf("%.17g\n", (double)J[k]);
    return 0;
  }
  fprintf(stderr, "usage: %s time <ncalls> [repeats] | count <ncalls> | check q_1..q_%d\n", argv[0], BENCH_NDOF);
  return 2;
}
