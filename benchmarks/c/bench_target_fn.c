/*
 * Bare-metal benchmark of a robot's generated `<prefix>_fk_jacobian` and `<prefix>_ik` on any
 * core of armgen.firmware.TARGETS under QEMU (benchmarks/bench_targets.py builds and runs it;
 * bench_timer.h: the timer). Every call is timed on its own; a stub of the same signature
 * timed the same way is the harness's cost, subtracted by the script. Output, "key value"
 * lines over semihosting:
 *
 *   calib_insns / calib_ticks          known instruction count and its timer counts
 *   fk_calls, fk_sum, fk_max           fk_jacobian over the table of configurations (timer counts)
 *   fk_stub_sum                        the stub, as many calls
 *   ik_calls, ik_ok, ik_sum, ik_max    ik from the seed to each pose (status OK counted)
 *   ik_steps_at_max                    the iterations of the slowest ik call
 *   ik_stub_sum                        the stub, as many calls
 *
 * bench_poses.h (written by the script) holds BENCH_QS configurations `qtab`, BENCH_POSES
 * tool poses `pose` (column-major) and the seed, in the robot's real type.
 */
#include <stdint.h>

#include BENCH_HEADER
#include "bench_poses.h"
#include "bench_timer.h"
#include "semihost.h"

#define P_(x, y) x##y
#define P(x, y) P_(x, y)
#define FN(name) P(BENCH_PREFIX, name)
typedef P(BENCH_PREFIX, _real) real_t;
typedef P(BENCH_PREFIX, _status) status_t;

typedef void (*fk_fn)(const real_t *q, real_t *T, real_t *J);
typedef status_t (*ik_fn)(const real_t *, const real_t *, const real_t *, real_t, real_t, real_t, real_t, real_t *,
                          real_t *, real_t *, real_t *, real_t *);

static real_t T_out[16], J_out[6 * BENCH_NDOF];
volatile real_t bench_sink;
/* Read through volatile pointers so that the timed calls are real calls. */
static fk_fn volatile selected_fk;
static ik_fn volatile selected_ik;

__attribute__((noinline)) static void stub_fk(const real_t *q, real_t *T, real_t *J) {
  (void)q;
  (void)T;
  (void)J;
}

__attribute__((noinline)) static status_t stub_ik(const real_t *T, const real_t *q_seed, const real_t *rest, real_t use,
                                                   real_t tp, real_t to, real_t it, real_t *q, real_t *pe, real_t *oe,
                                                   real_t *n, real_t *ok) {
  (void)T, (void)q_seed, (void)rest, (void)use, (void)tp, (void)to, (void)it, (void)q, (void)pe, (void)oe, (void)n,
      (void)ok;
  return (status_t)0;
}

static uint32_t fk_pass(uint32_t *max) {
  uint32_t i, t0, t1, d, sum = 0u;
  *max = 0u;
  for (i = 0; i < BENCH_QS; ++i) {
    fk_fn fn = selected_fk;
    t0 = timer_now();
    fn(qtab[i], T_out, J_out);
    t1 = timer_now();
    d = TIMER_ELAPSED(t0, t1);
    sum += d;
    *max = d > *max ? d : *max;
  }
  return sum;
}

static uint32_t ik_pass(uint32_t *max, uint32_t *ok, uint32_t *steps_at_max) {
  uint32_t i, t0, t1, d, sum = 0u;
  real_t q[BENCH_NDOF], pos, ori, iterations = (real_t)0, success;
  *max = 0u;
  *ok = 0u;
  *steps_at_max = 0u;
  for (i = 0; i < BENCH_POSES; ++i) {
    ik_fn fn = selected_ik;
    status_t status;
    t0 = timer_now();
    status = fn(pose[i], seed, seed, (real_t)0, BENCH_TOL, BENCH_TOL, (real_t)BENCH_MAX_ITERATIONS, q, &pos, &ori,
                &iterations, &success);
    t1 = timer_now();
    d = TIMER_ELAPSED(t0, t1);
    sum += d;
    *ok += status == (status_t)0 ? 1u : 0u;
    if (d > *max) {
      *max = d;
      *steps_at_max = (uint32_t)iterations;
    }
  }
  return sum;
}

int main(void) {
  uint32_t small, large, max, ok, steps;
  timer_start();
  small = timed_calib(1000u);
  large = timed_calib(101000u);
  sh_put_kv("calib_insns", 2u * 100000u);
  sh_put_kv("calib_ticks", large - small);

  sh_put_kv("fk_calls", BENCH_QS);
  selected_fk = stub_fk;
  sh_put_kv("fk_stub_sum", fk_pass(&max));
  selected_fk = FN(_fk_jacobian);
  sh_put_kv("fk_sum", fk_pass(&max));
  sh_put_kv("fk_max", max);

  sh_put_kv("ik_calls", BENCH_POSES);
  selected_ik = stub_ik;
  sh_put_kv("ik_stub_sum", ik_pass(&max, &ok, &steps));
  selected_ik = FN(_ik);
  sh_put_kv("ik_sum", ik_pass(&max, &ok, &steps));
  sh_put_kv("ik_max", max);
  sh_put_kv("ik_ok", ok);
  sh_put_kv("ik_steps_at_max", steps);
  bench_sink = T_out[12] + J_out[5];
  sh_puts("done\n");
  return 0;
}
