/*
 * Cortex-M4F runner of the joint controller (MPS2 AN386 under qemu-system-arm, or the board
 * with a debugger; the other cores of armgen.firmware.TARGETS too, the RISC-V one timed by its
 * mcycle counter instead of SysTick): runs the compiled-in task (`fw_task`, task_params.h) tick by tick and
 * prints the commanded trajectory as CSV over semihosting (reals in C99 hex, see fw_csv.h),
 * then "# key value" lines:
 *
 *   tick_systicks_sum / _max / _min   SysTick counts spent inside ctrl_tick, over `ticks`
 *   stub_systicks_sum                 the same harness around an empty function, `ticks` calls
 *   calib_insns / calib_ticks         a loop of known length: instructions per SysTick count
 *   stack_peak_bytes                  deepest main-stack use (the stack is painted at start)
 *   sizeof_ctrl / sizeof_config       bytes of the controller object and of its configuration
 *
 * Under `qemu-system-arm -icount shift=0` every instruction advances time by 1 ns and SysTick
 * (processor clock, 25 MHz) is read exactly, so the counts are executed instructions / 40:
 * see benchmarks/README.md. DWT CYCCNT is not modelled by QEMU 7.2.
 *
 * Ticks run back to back. A tick whose execution exceeds its period (dt, or FW_PERIOD_NS
 * when defined, at FW_CPU_HZ) is reported to the controller as missed periods on the next
 * tick (CTRL_FAULT_OVERRUN; the START tick included). The tick's cost in processor cycles is
 * estimated from SysTick: on hardware SysTick counts cycles; under QEMU -icount a SysTick
 * count stands for several instructions (calibrated at start, calib_insns / calib_ticks),
 * each at least one cycle on the M4, so cycles >= SysTick counts * that ratio.
 * The task's lock schedule (fw_lock_tick, fw_lock_mask: the plan's fault, or one the plan did
 * not know) is reported through ctrl_input.locked, as a drive would.
 * Build with FW_PRINT_ROWS=0 to print the summary only.
 */
#include <stdint.h>
#include <string.h>

#include "controller.h"
#include "fw_csv.h"
#include "fw_task.h"
#include "semihost.h"

#ifndef FW_PRINT_ROWS
#define FW_PRINT_ROWS 1
#endif
#ifndef FW_EXTRA_TICKS
#define FW_EXTRA_TICKS 2
#endif
#ifdef FW_MOVE_TO
extern const ctrl_real fw_move_to_target[16]; /* the tool pose, column-major (the benchmark's) */
#endif
#ifndef FW_MOVE_TO_MAX_TICKS
#define FW_MOVE_TO_MAX_TICKS 100000u /* a MOVE_TO run stops here at the latest */
#endif
#ifndef FW_CPU_HZ
#define FW_CPU_HZ 25000000u /* MPS2 AN386 processor clock, the SysTick source */
#endif

#if defined(__riscv)
/* RISC-V (riscv/startup.c): the mcycle counter counts up, 32 bits read; processor cycles on
 * hardware, executed instructions under QEMU -icount shift=0 (1 per count, calibrated below). */
static inline uint32_t timer_now(void) {
  uint32_t t;
  __asm__ volatile("csrr %0, mcycle" : "=r"(t));
  return t;
}
#define TIMER_ELAPSED(t0, t1) ((t1) - (t0))
#else
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SYST_MASK 0xFFFFFFu
#define timer_now() SYST_CVR
#define TIMER_ELAPSED(t0, t1) (((t0) - (t1)) & SYST_MASK) /* SysTick counts down, 24 bits */
#endif
#define STACK_PAINT 0xA5C3A5C3u

extern uint32_t __stack_limit[];

typedef ctrl_fault (*tick_fn)(ctrl *c, const ctrl_input *in, ctrl_output *out);
static tick_fn volatile selected_tick; /* volatile: the timed call is a real call */
static ctrl controller;
static char line[FW_CSV_LINE_MAX];

__attribute__((noinline)) static ctrl_fault stub_tick(ctrl *c, const ctrl_input *in, ctrl_output *out) {
  (void)c;
  (void)in;
  (void)out;
  return CTRL_FAULT_NONE;
}

__attribute__((noinline)) static uint32_t timed_tick(ctrl *c, const ctrl_input *in, ctrl_output *out) {
  tick_fn fn = selected_tick;
  uint32_t t0, t1;
  t0 = timer_now();
  (void)fn(c, in, out);
  t1 = timer_now();
  return TIMER_ELAPSED(t0, t1);
}

__attribute__((noinline)) static uint32_t timed_calib(uint32_t iterations) {
  uint32_t t0, t1;
  t0 = timer_now();
#if defined(__riscv)
  __asm__ volatile("1: addi %0, %0, -1\n\tbnez %0, 1b" : "+r"(iterations));
#else
  /* unified syntax: GCC hands Thumb-1 (Armv6-M) inline assembly to the assembler in the
   * divided syntax, where `subs` with three operands does not exist */
  __asm__ volatile(".syntax unified\n1: subs %0, %0, #1\n\tbne 1b" : "+r"(iterations)::"cc");
#endif
  t1 = timer_now();
  return TIMER_ELAPSED(t0, t1);
}

/* Fill the unused main stack (below this frame) with a pattern. */
__attribute__((noinline)) static void paint_stack(void) {
  volatile uint32_t marker = 0u;
  uint32_t *p = __stack_limit;
  uint32_t *end = (uint32_t *)((uintptr_t)&marker & ~(uintptr_t)3u) - 64;
  while (p < end) {
    *p++ = STACK_PAINT;
  }
  (void)marker;
}

static uint32_t stack_peak_bytes(void) {
  extern uint32_t __stack_top[];
  const uint32_t *p = __stack_limit;
  while (p < __stack_top && *p == STACK_PAINT) {
    ++p;
  }
  return (uint32_t)((uintptr_t)__stack_top - (uintptr_t)p);
}

static void put_kv(const char *key, uint32_t value) {
  sh_puts("# ");
  sh_put_kv(key, value);
}

int main(void) {
  ctrl_input in;
  ctrl_output out;
  ctrl_fault init;
  uint32_t i, sum = 0u, max = 0u, min = 0xFFFFFFFFu, stub = 0u, ticks = 0u, period, limit;
  uint32_t calib_ticks, calib_insns = 2u * 100000u, insns_per_count;
  int32_t after = -1;

  paint_stack();
#if !defined(__riscv)
  SYST_RVR = SYST_MASK;
  SYST_CVR = 0u;
  SYST_CSR = 5u; /* ENABLE | CLKSOURCE = processor clock, no interrupt */
#endif

  calib_ticks = timed_calib(101000u) - timed_calib(1000u);
  if (calib_ticks == 0u) {
    calib_ticks = 1u;
  }
  /* whole instructions per SysTick count (40 under QEMU, 1 on hardware): rounded down, the
   * cycles below stay a lower bound, and the ticks need no 64-bit division (libgcc's, 0.7 KB) */
  insns_per_count = (calib_insns > calib_ticks) ? (calib_insns / calib_ticks) : 1u;
  init = ctrl_init(&controller, &fw_task);
  (void)fw_csv_header(line, sizeof(line));
  sh_puts(line);
#ifdef FW_PERIOD_NS
  period = (uint32_t)(((uint64_t)FW_PERIOD_NS * FW_CPU_HZ) / 1000000000u);
#else
  period = (uint32_t)(fw_task.dt * (ctrl_real)FW_CPU_HZ);
#endif
  if (period == 0u) {
    period = 1u;
  }
  memset(&in, 0, sizeof(in));
#ifdef FW_MOVE_TO
  /* -DFW_MOVE_TO=1: a MOVE_TO to fw_move_to_target (defined beside fw_task) instead of START */
  for (i = 0; i < 16u; ++i) {
    in.target[i] = fw_move_to_target[i];
  }
  in.command = CTRL_CMD_MOVE_TO;
  limit = FW_MOVE_TO_MAX_TICKS;
#else
  in.command = CTRL_CMD_START;
  limit = controller.n_ticks + FW_EXTRA_TICKS + 2u;
#endif
  selected_tick = ctrl_tick;
  for (i = 0; i <= limit; ++i) {
    uint32_t d, cycles;
    in.locked = (fw_lock_tick >= 0 && (int32_t)i >= fw_lock_tick) ? fw_lock_mask : 0u;
    d = timed_tick(&controller, &in, &out);
    /* cycles spent: SysTick counts, scaled when a count stands for several instructions */
    cycles = d * insns_per_count; /* d < 2^24 (SysTick), so no overflow below 256 per count */
    in.command = CTRL_CMD_NONE;
    in.missed_ticks = cycles > period ? cycles / period : 0u;
    if (after < 0) {
      sum += d;
      max = d > max ? d : max;
      min = d < min ? d : min;
      ++ticks;
    }
#if FW_PRINT_ROWS
    (void)fw_csv_row(line, sizeof(line), &out);
    sh_puts(line);
#endif
    if (after < 0 && out.state != CTRL_STATE_RUNNING && out.state != CTRL_STATE_DEGRADED) {
      after = (int32_t)i;
    }
    if (after >= 0 && (int32_t)i - after >= FW_EXTRA_TICKS) {
      break;
    }
  }
  selected_tick = stub_tick;
  for (i = 0; i < ticks; ++i) {
    stub += timed_tick(&controller, &in, &out);
  }

  sh_puts("# init ");
  sh_puts(ctrl_fault_name(init));
  sh_puts("\n# state ");
  sh_puts(ctrl_state_name(out.state));
  sh_puts("\n# fault ");
  sh_puts(ctrl_fault_name(out.fault));
  sh_puts("\n");
  put_kv("ticks", ticks);
  put_kv("n_ticks", controller.n_ticks);
  put_kv("tick_systicks_sum", sum);
  put_kv("tick_systicks_max", max);
  put_kv("tick_systicks_min", min);
  put_kv("stub_systicks_sum", stub);
  put_kv("calib_insns", calib_insns);
  put_kv("calib_ticks", calib_ticks);
  put_kv("period_cycles", period);
  put_kv("stack_peak_bytes", stack_peak_bytes());
  put_kv("sizeof_ctrl", (uint32_t)sizeof(ctrl));
  put_kv("sizeof_config", (uint32_t)sizeof(ctrl_config));
  put_kv("real_bytes", (uint32_t)sizeof(ctrl_real));
  sh_puts("# end\n");
  return 0;
}
