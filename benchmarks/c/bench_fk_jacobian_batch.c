/*
 * The C side of benchmarks/bench_kernel.py's batch row: `<prefix>_fk_jacobian` called from C
 * on a batch of configurations, each sample's T and J stored (the work the Python API's batched
 * call does, minus Python).
 *
 * Compiled by bench_kernel.py with the strict flags and the kernel's own (api_kernel.OPTIMISATION,
 * -ffp-contract=off):
 *   gcc ... -DBENCH_HEADER='"robot.h"' -DBENCH_FN=robot_fk_jacobian -DBENCH_NDOF=7 \
 *       bench_fk_jacobian_batch.c robot.c -lm
 * Usage: bench q.bin <count> <repeats>: reads count * NDOF doubles (one configuration after
 * another) and prints "ns_per_sample <best wall of repeats>", "cpu_ns_per_sample <best CPU>"
 * and "checksum <sum of outputs>". Each repeat writes into freshly allocated outputs, as each
 * Python call does (first-touch page faults included on both sides), allocated as NumPy
 * allocates large arrays on Linux: aligned to 2 MiB and marked for transparent huge pages
 * (madvise MADV_HUGEPAGE), so that both sides pay the same page faults.
 */
#define _DEFAULT_SOURCE /* madvise, posix_memalign, clock_gettime */

#include <stdio.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <time.h>

#include BENCH_HEADER

static double seconds(clockid_t clock) {
  struct timespec t;
  clock_gettime(clock, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

#define HUGE_PAGE_BYTES ((size_t)1 << 21)

/* count doubles, 2 MiB aligned, huge pages advised (NumPy's large-array allocation on Linux). */
static double *outputs(size_t count) {
  void *memory = NULL;
  if (posix_memalign(&memory, HUGE_PAGE_BYTES, sizeof(double) * count) != 0) return NULL;
#ifdef MADV_HUGEPAGE
  (void)madvise(memory, sizeof(double) * count, MADV_HUGEPAGE);
#endif
  return memory;
}

int main(int argc, char **argv) {
  long count, i;
  int repeats, r;
  double *q, best = 1e300, best_cpu = 1e300, checksum = 0.0;
  FILE *f;
  if (argc != 4) return 2;
  count = atol(argv[2]);
  repeats = atoi(argv[3]);
  q = malloc(sizeof(double) * BENCH_NDOF * (size_t)count);
  f = fopen(argv[1], "rb");
  if (q == NULL || f == NULL || fread(q, sizeof(double), BENCH_NDOF * (size_t)count, f) != BENCH_NDOF * (size_t)count) {
    return 3;
  }
  fclose(f);
  for (r = 0; r < repeats; ++r) {
    double *T = outputs(16 * (size_t)count);
    double *J = outputs(6 * BENCH_NDOF * (size_t)count);
    double start, start_cpu, elapsed, elapsed_cpu;
    if (T == NULL || J == NULL) return 3;
    start = seconds(CLOCK_MONOTONIC);
    start_cpu = seconds(CLOCK_PROCESS_CPUTIME_ID);
    for (i = 0; i < count; ++i) BENCH_FN(q + BENCH_NDOF * i, T + 16 * i, J + 6 * BENCH_NDOF * i);
    elapsed = seconds(CLOCK_MONOTONIC) - start;
    elapsed_cpu = seconds(CLOCK_PROCESS_CPUTIME_ID) - start_cpu;
    if (elapsed < best) best = elapsed;
    if (elapsed_cpu < best_cpu) best_cpu = elapsed_cpu;
    checksum += T[16 * (count - 1) + 12] + J[6 * BENCH_NDOF * (count - 1)];
    free(T);
    free(J);
  }
  printf("ns_per_sample %.3f\ncpu_ns_per_sample %.3f\nchecksum %.17g\n", 1e9 * best / (double)count,
         1e9 * best_cpu / (double)count, checksum);
  free(q);
  return 0;
}
