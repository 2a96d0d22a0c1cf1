/* Minimal Arm semihosting (and its RISC-V form, the same operations), see semihost.h. */
#include "semihost.h"

#define SYS_WRITE0 0x04
#define SYS_EXIT 0x18
#define SYS_EXIT_EXTENDED 0x20
#define ADP_STOPPED_APPLICATION_EXIT 0x20026u
#define ADP_STOPPED_RUNTIME_ERROR 0x20023u

#if defined(__riscv)
/* RISC-V semihosting: ebreak between the two marker instructions, uncompressed and in one
 * page (the 16-byte alignment keeps the 12 bytes together), operation in a0, argument in a1. */
static int semihost_call(int op, const void *arg) {
  register int a0 __asm__("a0") = op;
  register const void *a1 __asm__("a1") = arg;
  __asm__ volatile(".option push\n\t.option norvc\n\t.balign 16\n\t"
                   "slli x0, x0, 0x1f\n\tebreak\n\tsrai x0, x0, 7\n\t.option pop"
                   : "+r"(a0) : "r"(a1) : "memory");
  return a0;
}
#else
static int semihost_call(int op, const void *arg) {
  register int r0 __asm__("r0") = op;
  register const void *r1 __asm__("r1") = arg;
  __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
  return r0;
}
#endif

void sh_puts(const char *s) { (void)semihost_call(SYS_WRITE0, s); }

void sh_put_u32(uint32_t value) {
  char buf[11];
  int i = 10;
  buf[i] = '\0';
  do {
    buf[--i] = (char)('0' + value % 10u);
    value /= 10u;
  } while (value != 0u);
  sh_puts(&buf[i]);
}

void sh_put_i32(int32_t value) {
  if (value < 0) {
    sh_puts("-");
    sh_put_u32((uint32_t)(-(value + 1)) + 1u);
  } else {
    sh_put_u32((uint32_t)value);
  }
}

void sh_put_kv(const char *key, uint32_t value) {
  sh_puts(key);
  sh_puts(" ");
  sh_put_u32(value);
  sh_puts("\n");
}

void sh_exit(int status) {
  /* SYS_EXIT_EXTENDED (semihosting v2) carries the status; QEMU >= 4 implements it. Fall back
   * to SYS_EXIT (status 0 or 1 only) if the host ignored it, then park the core. */
  uint32_t block[2];
  block[0] = ADP_STOPPED_APPLICATION_EXIT;
  block[1] = (uint32_t)status;
  (void)semihost_call(SYS_EXIT_EXTENDED, block);
  (void)semihost_call(SYS_EXIT, (const void *)(uintptr_t)(status == 0 ? ADP_STOPPED_APPLICATION_EXIT : ADP_STOPPED_RUNTIME_ERROR));
  for (;;) {
    __asm__ volatile("wfi");
  }
}

/* newlib's exit()/abort() end in _exit: route it to the host. */
void _exit(int status) __attribute__((noreturn));
void _exit(int status) { sh_exit(status); }
