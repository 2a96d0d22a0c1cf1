/*
 * Reset code for QEMU's RISC-V `virt` board (riscv/virt.ld), machine mode, bare metal: the
 * RISC-V counterpart of arm/startup.c.
 *
 * _start sets the global and stack pointers and calls reset(), which enables the FPU
 * (mstatus.FS: off after reset, the first F instruction would trap), points mtvec at the trap
 * handler, copies .data from its load address, zeroes .bss, runs static constructors, calls
 * main() and hands its return value to _exit() (arm/semihost.c routes it to the host). A trap
 * prints its cause over semihosting and exits with status 128 + mcause, so a crashing program
 * under QEMU ends instead of hanging.
 */
#include <stdint.h>

#include "semihost.h"

extern uint32_t __data_load[], __data_start[], __data_end[];
extern uint32_t __bss_start[], __bss_end[];
extern void (*__init_array_start[])(void);
extern void (*__init_array_end[])(void);

int main(void);
void _exit(int status) __attribute__((noreturn));
void reset(void) __attribute__((noreturn, used, optimize("no-tree-loop-distribute-patterns")));
void trap(void) __attribute__((noreturn, used, aligned(4)));

#define MSTATUS_FS_INITIAL 0x2000u

/* gp without relaxation (it is what relaxation would use), sp at the top of RAM. */
__asm__(".section .text.start, \"ax\", @progbits\n"
        ".globl _start\n"
        "_start:\n"
        ".option push\n"
        ".option norelax\n"
        "  la gp, __global_pointer$\n"
        ".option pop\n"
        "  la sp, __stack_top\n"
        "  j reset\n");

void reset(void) {
  uint32_t *src, *dst;
  void (**fn)(void);
  __asm__ volatile("csrs mstatus, %0" ::"r"(MSTATUS_FS_INITIAL));
  __asm__ volatile("csrw mtvec, %0" ::"r"((uintptr_t)trap));
  for (src = __data_load, dst = __data_start; dst < __data_end;) {
    *dst++ = *src++;
  }
  for (dst = __bss_start; dst < __bss_end;) {
    *dst++ = 0u;
  }
  for (fn = __init_array_start; fn < __init_array_end; ++fn) {
    (*fn)();
  }
  _exit(main());
}

/* Any trap (none is enabled, so an exception): report mcause and stop. */
void trap(void) {
  uint32_t cause;
  __asm__ volatile("csrr %0, mcause" : "=r"(cause));
  sh_puts("unexpected trap, mcause ");
  sh_put_u32(cause);
  sh_puts("\n");
  _exit((int)(128u + (cause & 0xFFu)));
}
