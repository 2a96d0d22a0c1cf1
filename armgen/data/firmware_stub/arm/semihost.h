/*
 * Minimal Arm semihosting (BKPT 0xAB) for bare-metal Cortex-M programs: console output and
 * exit with a status code. Works under `qemu-system-arm -semihosting-config enable=on,target=native`
 * and under a debugger with semihosting enabled; on a board without a debugger attached the
 * BKPT escalates to HardFault, so production firmware must not call these.
 */
#ifndef ARMGEN_SEMIHOST_H
#define ARMGEN_SEMIHOST_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Write a NUL-terminated string to the host console (SYS_WRITE0). */
void sh_puts(const char *s);
/* Write an unsigned / signed decimal integer (no printf needed). */
void sh_put_u32(uint32_t value);
void sh_put_i32(int32_t value);
/* Write "<key> <value>\n": the line format benchmarks parse. */
void sh_put_kv(const char *key, uint32_t value);
/* End the program; `status` becomes QEMU's exit status (SYS_EXIT_EXTENDED). */
void sh_exit(int status) __attribute__((noreturn));

#ifdef __cplusplus
}
#endif

#endif /* ARMGEN_SEMIHOST_H */
