/* Minimal Arm semihosting for the target tests (no newlib stdio, no heap).
 * Output goes through SYS_WRITE0, exit through SYS_EXIT_EXTENDED so QEMU
 * (-semihosting-config enable=on) exits with the status we pass. */
#ifndef ABBE_TARGET_SEMIHOST_H
#define ABBE_TARGET_SEMIHOST_H

#include <stdint.h>

void sh_puts(const char *s);              /* write a NUL-terminated string */
void sh_put_i32(int32_t v);               /* decimal */
void sh_put_i64(int64_t v);               /* decimal */
void sh_put_u32(uint32_t v);              /* decimal */
void sh_put_hex32(uint32_t v);            /* 0x%08x */
void sh_exit(int status) __attribute__((noreturn));

/* Stack painted by the reset handler: bytes of stack ever used so far. */
uint32_t sh_stack_high_water(void);

#endif /* ABBE_TARGET_SEMIHOST_H */
