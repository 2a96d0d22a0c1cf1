/*
 * The instruction timer of the bare-metal benchmark drivers on every core of
 * armgen.firmware.TARGETS, under QEMU -icount shift=0 (every guest instruction advances virtual
 * time by 1 ns): SysTick on the processor clock on the Arm cores (a 24-bit down-counter, one
 * count per 40 or 50 instructions on the MPS2 models), mcycle on RISC-V (one count per
 * instruction). The calibration loop of known length (two instructions per pass) gives the
 * instructions per count in the same run (benchmarks/README.md), as arm/fw_main.c does.
 */
#ifndef ARMGEN_BENCH_TIMER_H
#define ARMGEN_BENCH_TIMER_H

#include <stdint.h>

#if defined(__riscv)
static inline uint32_t timer_now(void) {
  uint32_t t;
  __asm__ volatile("csrr %0, mcycle" : "=r"(t));
  return t;
}
#define TIMER_ELAPSED(t0, t1) ((t1) - (t0))
static void timer_start(void) {}
#else
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SYST_MASK 0xFFFFFFu
#define timer_now() SYST_CVR
#define TIMER_ELAPSED(t0, t1) (((t0) - (t1)) & SYST_MASK)
static void timer_start(void) {
  SYST_RVR = SYST_MASK;
  SYST_CVR = 0u;
  SYST_CSR = 5u; /* ENABLE | CLKSOURCE = processor clock, no interrupt */
}
#endif

/* Timer counts of a loop of `iterations` two-instruction passes. */
__attribute__((noinline)) static uint32_t timed_calib(uint32_t iterations) {
  uint32_t t0, t1;
  t0 = timer_now();
#if defined(__riscv)
  __asm__ volatile("1: addi %0, %0, -1\n\tbnez %0, 1b" : "+r"(iterations));
#else
  __asm__ volatile(".syntax unified\n1: subs %0, %0, #1\n\tbne 1b" : "+r"(iterations)::"cc");
#endif
  t1 = timer_now();
  return TIMER_ELAPSED(t0, t1);
}

#endif
