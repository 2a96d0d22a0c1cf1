/*
 * Bare-metal benchmark of fw_program_desired (firmware_stub/fw_program.c) on the MPS2 AN386
 * (Cortex-M4F) under QEMU -icount shift=0, built with firmware_stub/arm/{startup.c,semihost.c,
 * mps2_an386.ld} and a program table "table.h" (program_table_c, named fw_program_table).
 *
 * Method as benchmarks/c/bench_fk_jacobian_arm.c: SysTick on the processor clock counts
 * executed instructions / 40 under -icount shift=0, calibrated in the run with a loop of known
 * length. Each call is timed alone, at the plan's tick times t = k * BENCH_DT for k = 0 ..
 * BENCH_TICKS - 1, then the same harness around a stub. Output over semihosting, "key value":
 *
 *   check 1|0                  fw_program_check's verdict
 *   calib_insns / calib_ticks  a loop of known length: instructions per SysTick count
 *   call <k> <systicks>        one line per tick
 *   out <k> <18 words>         its p, R (column-major), xdot as the bits of each float (exact)
 *   stub_sum <systicks>        the harness around a stub, BENCH_TICKS calls
 */
#include <stdint.h>
#include <string.h>

#include "fw_program.h"
#include "bench_systick.h"
#include "semihost.h"
#include "table.h"


typedef void (*desired_fn)(const fw_program *prog, ctrl_real t, ctrl_real *p, ctrl_real *R, ctrl_real *xdot);
static desired_fn volatile selected_fn; /* volatile: the timed call is a real call */
static ctrl_real p_out[3], R_out[9], xdot_out[6];

__attribute__((noinline)) static void stub_fn(const fw_program *prog, ctrl_real t, ctrl_real *p, ctrl_real *R,
                                              ctrl_real *xdot) {
  (void)prog;
  (void)t;
  (void)p;
  (void)R;
  (void)xdot;
}

__attribute__((noinline)) static uint32_t timed_call(ctrl_real t) {
  desired_fn fn = selected_fn;
  uint32_t t0, t1;
  t0 = SYST_CVR;
  fn(&fw_program_table, t, p_out, R_out, xdot_out);
  t1 = SYST_CVR;
  return (t0 - t1) & SYST_MASK;
}

/* " <bits>" per value: the float's representation, read back exactly by the benchmark. */
static void put_bits(const ctrl_real *x, int n) {
  int i;
  for (i = 0; i < n; ++i) {
    uint32_t bits;
    memcpy(&bits, &x[i], sizeof(bits));
    sh_puts(" ");
    sh_put_u32(bits);
  }
}

int main(void) {
  uint32_t k, stub = 0u, calib;
  systick_start();
  calib = timed_calib(101000u) - timed_calib(1000u);
  sh_put_kv("check", (uint32_t)fw_program_check(&fw_program_table));
  sh_put_kv("calib_insns", 200000u);
  sh_put_kv("calib_ticks", calib);
  selected_fn = fw_program_desired;
  for (k = 0u; k < BENCH_TICKS; ++k) {
    uint32_t d = timed_call((ctrl_real)k * BENCH_DT);
    sh_puts("call ");
    sh_put_u32(k);
    sh_puts(" ");
    sh_put_u32(d);
    sh_puts("\nout ");
    sh_put_u32(k);
    put_bits(p_out, 3);
    put_bits(R_out, 9);
    put_bits(xdot_out, 6);
    sh_puts("\n");
  }
  selected_fn = stub_fn;
  for (k = 0u; k < BENCH_TICKS; ++k) {
    stub += timed_call((ctrl_real)k * BENCH_DT);
  }
  sh_put_kv("stub_sum", stub);
  sh_exit(0);
}
