/*
 * Bare-metal benchmark of a generated `<prefix>_fk_jacobian(q, T, J)` on the MPS2 AN386
 * (Cortex-M4F) under QEMU, built with firmware_stub/arm/{startup.c,semihost.c,mps2_an386.ld}.
 *
 * Executed instructions are measured with SysTick on the processor clock while QEMU runs with
 * `-icount shift=0` (every guest instruction advances virtual time by exactly 1 ns, and the
 * SysTick read is exact at the I/O access). DWT CYCCNT is not modelled by QEMU 7.2 (reads 0).
 * The tick length in instructions is calibrated in the same run with a loop of known length
 * (`subs`/`bne`, 2 instructions per iteration). Output: "key value" lines over semihosting:
 *
 *   calib_insns / calib_ticks     known instruction count and its ticks -> insns per tick
 *   ticks_empty                   the timing harness around a loop of 0 iterations
 *   ticks_fn     (ncalls)         loop of ncalls calls of BENCH_FN, q cycling through a table
 *   ticks_stub   (ncalls)         the same loop calling a stub (one instruction, `bx lr`)
 *
 * so (ticks_fn - ticks_stub) * insns_per_tick / ncalls + 1 is the instructions executed inside
 * BENCH_FN per call, inclusive of sinf/cosf (the same quantity as callgrind's --toggle-collect),
 * and (ticks_fn - ticks_empty) * insns_per_tick / ncalls is the cost per loop iteration.
 */
#include <stdint.h>

#include BENCH_HEADER
#include "bench_systick.h"
#include "semihost.h"

#ifndef BENCH_NCALLS
#define BENCH_NCALLS 4096
#endif
#define QTABLE 64 /* a power of two */


typedef BENCH_REAL real_t;
typedef void (*kin_fn)(const real_t *q, real_t *T, real_t *J);

static real_t qtab[QTABLE][BENCH_NDOF];
static real_t T_out[16], J_out[6 * BENCH_NDOF];
volatile real_t bench_sink;
/* Read through a volatile pointer so the compiler cannot specialise run() per callee. */
static kin_fn volatile selected_fn;

__attribute__((noinline)) static void stub_fn(const real_t *q, real_t *T, real_t *J) {
  (void)q;
  (void)T;
  (void)J;
}

static void fill_table(void) {
  uint32_t state = 12345u;
  int i, k;
  for (i = 0; i < QTABLE; ++i) {
    for (k = 0; k < BENCH_NDOF; ++k) {
      state = (state * 1103515245u + 12345u) & 0x7fffffffu;
      /* [-2, 2) rad, computed in float: no double arithmetic anywhere in the image */
      qtab[i][k] = (real_t)((float)(state >> 8) * (4.0f / 8388608.0f) - 2.0f);
    }
  }
}

__attribute__((noinline)) static uint32_t timed_loop(uint32_t ncalls) {
  kin_fn fn = selected_fn;
  uint32_t i, t0, t1;
  t0 = SYST_CVR;
  for (i = 0; i < ncalls; ++i) {
    fn(qtab[i & (QTABLE - 1u)], T_out, J_out);
  }
  t1 = SYST_CVR;
  return (t0 - t1) & SYST_MASK;
}

int main(void) {
  uint32_t calib_small, calib_large;
  fill_table();
  systick_start();

  /* 2 * (large - small) instructions between the two calibration runs */
  calib_small = timed_calib(1000u);
  calib_large = timed_calib(101000u);
  sh_put_kv("calib_insns", 2u * 100000u);
  sh_put_kv("calib_ticks", calib_large - calib_small);

  selected_fn = stub_fn;
  sh_put_kv("ticks_empty", timed_loop(0u));
  sh_put_kv("ncalls", BENCH_NCALLS);
  sh_put_kv("ticks_stub", timed_loop(BENCH_NCALLS));
  selected_fn = BENCH_FN;
  sh_put_kv("ticks_fn", timed_loop(BENCH_NCALLS));
  bench_sink = T_out[12] + J_out[5];
  sh_puts("done\n");
  return 0;
}
