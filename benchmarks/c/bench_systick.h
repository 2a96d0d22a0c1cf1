/*
 * SysTick timing for the bare-metal benchmark drivers (MPS2 AN386 under QEMU -icount shift=0,
 * where SysTick on the processor clock counts executed instructions / 40): the registers,
 * starting the counter, and the calibration loop of known length that gives instructions per
 * count in the run (benchmarks/README.md).
 */
#ifndef ARMGEN_BENCH_SYSTICK_H
#define ARMGEN_BENCH_SYSTICK_H

#include <stdint.h>

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SYST_MASK 0xFFFFFFu /* 24-bit down-counter */

static void systick_start(void) {
  SYST_RVR = SYST_MASK;
  SYST_CVR = 0u;
  SYST_CSR = 5u; /* ENABLE | CLKSOURCE = processor clock, no interrupt */
}

/* SysTick counts of a loop of `iterations` two-instruction passes. */
__attribute__((noinline)) static uint32_t timed_calib(uint32_t iterations) {
  uint32_t t0, t1;
  t0 = SYST_CVR;
  __asm__ volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(iterations)::"cc");
  t1 = SYST_CVR;
  return (t0 - t1) & SYST_MASK;
}

#endif
