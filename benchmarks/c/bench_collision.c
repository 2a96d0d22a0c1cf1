/*
 * Host benchmark driver for a robot's generated collision functions:
 * <prefix>_collision_distances(q, spheres, capsules, boxes, planes, d) and
 * <prefix>_collision_criterion(q, spheres, capsules, boxes, planes, clearance, activation, H_C, grad).
 * The robot has one obstacle slot of each kind (benchmarks/bench_collision.py writes the robot
 * variant and bench_collision_inputs.h: QTABLE configurations `qtab`, the scene's obstacle
 * columns and BENCH_NPAIRS, the length of d).
 *
 * Compiled by bench_collision.py with the strict flags, e.g.
 *   gcc -std=c99 -Wall ... -O2 -DBENCH_HEADER='"iiwa14_c4.h"' -DBENCH_PREFIX=iiwa14_c4 -DBENCH_NDOF=7 \
 *       bench_collision.c iiwa14_c4.c -lm
 * The generated code is its own translation unit (no LTO), so a call is never inlined or hoisted;
 * the configurations cycle through the table and every output feeds a running sum that is
 * printed, so every result is live.
 *
 * Usage:
 *   bench time <distances|criterion> <ncalls> <repeats>   print "ns_per_call <best of repeats>"
 *   bench check                                           print d, H_C and grad per configuration
 */
#define _POSIX_C_SOURCE 199309L

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include BENCH_HEADER
#include "bench_collision_inputs.h"

#define PASTE2(a, b) a##b
#define PASTE(a, b) PASTE2(a, b)
#define FN(name) PASTE(BENCH_PREFIX, name)

static double run(int criterion, long ncalls) {
  real_t d[BENCH_NPAIRS], h, grad[BENCH_NDOF];
  double sink = 0.0;
  long i;
  for (i = 0; i < ncalls; ++i) {
    long s = i & (QTABLE - 1);
    if (criterion) {
      FN(_collision_criterion)(qtab[s], spheres, capsules, boxes, planes, clearance, activation, &h, grad);
      sink += (double)h + (double)grad[i % BENCH_NDOF];
    } else {
      FN(_collision_distances)(qtab[s], spheres, capsules, boxes, planes, d);
      sink += (double)d[i % BENCH_NPAIRS];
    }
  }
  return sink;
}

static double now_ns(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

int main(int argc, char **argv) {
  if (argc == 2 && strcmp(argv[1], "check") == 0) {
    real_t d[BENCH_NPAIRS], h, grad[BENCH_NDOF];
    int s, k;
    for (s = 0; s < QTABLE; ++s) {
      FN(_collision_distances)(qtab[s], spheres, capsules, boxes, planes, d);
      FN(_collision_criterion)(qtab[s], spheres, capsules, boxes, planes, clearance, activation, &h, grad);
      for (k = 0; k < BENCH_NPAIRS; ++k) printf("%.17g ", (double)d[k]);
      printf("%.17g", (double)h);
      for (k = 0; k < BENCH_NDOF; ++k) printf(" %.17g", (double)grad[k]);
      printf("\n");
    }
    return 0;
  }
  if (argc == 5 && strcmp(argv[1], "time") == 0) {
    int criterion = strcmp(argv[2], "criterion") == 0;
    long ncalls = atol(argv[3]), repeats = atol(argv[4]), r;
    double best = 1e300, sink = 0.0;
    if (!criterion && strcmp(argv[2], "distances") != 0) {
      fprintf(stderr, "unknown function %s (distances or criterion)\n", argv[2]);
      return 2;
    }
    sink += run(criterion, ncalls / 10 + 1); /* warm-up */
    for (r = 0; r < repeats; ++r) {
      double t0 = now_ns(), t1;
      sink += run(criterion, ncalls);
      t1 = now_ns();
      if ((t1 - t0) / (double)ncalls < best) best = (t1 - t0) / (double)ncalls;
    }
    printf("ns_per_call %.3f\nsink %g\n", best, sink);
    return 0;
  }
  fprintf(stderr, "usage: %s time <distances|criterion> <ncalls> <repeats> | check\n", argv[0]);
  return 2;
}
