/* Bare-metal start-up for the MPS2 boards under QEMU: vector table, reset
 * handler (.data copy, .bss zero, FPU enable on FP targets, stack painting),
 * fault handlers that report over semihosting, and the few C library
 * functions the compiler may call (memcpy, memset, memmove, memcmp, and the
 * Arm run-time ABI's __aeabi_mem* that clang calls instead), so the images
 * link with -nostdlib: no newlib, no heap, no stdio. */
#include <stddef.h>
#include <stdint.h>

#include "semihost.h"

extern uint32_t __data_start__, __data_end__, __data_load__;
extern uint32_t __bss_start__, __bss_end__;
extern uint32_t __stack_limit__, __stack_top__;

int main(void);
void abbe_reset_handler(void) __attribute__((noreturn));
void abbe_fault_handler(void) __attribute__((noreturn));

#define STACK_PAINT 0xA5A5A5A5u

void abbe_reset_handler(void)
{
    uint32_t *dst = &__data_start__;
    const uint32_t *src = &__data_load__;
    while (dst < &__data_end__) {
        *dst++ = *src++;
    }
    for (dst = &__bss_start__; dst < &__bss_end__; dst++) {
        *dst = 0u;
    }
    /* Paint the stack below the current frame for the high-water mark. */
    {
        uint32_t *sp;
        __asm__ volatile("mov %0, sp" : "=r"(sp));
        for (dst = &__stack_limit__; dst < sp - 16; dst++) {
            *dst = STACK_PAINT;
        }
    }
#if defined(__ARM_FP)
    /* CPACR: full access to CP10 and CP11 (the FPU) before any FP instruction. */
    *(volatile uint32_t *)0xE000ED88u |= (0xFu << 20);
    __asm__ volatile("dsb\n\tisb" ::: "memory");
#endif
    sh_exit(main());
}

uint32_t sh_stack_high_water(void)
{
    const uint32_t *p = &__stack_limit__;
    while (p < &__stack_top__ && *p == STACK_PAINT) {
        p++;
    }
    return (uint32_t)((uintptr_t)&__stack_top__ - (uintptr_t)p);
}

void abbe_fault_handler(void)
{
    uint32_t ipsr;
    __asm__ volatile("mrs %0, ipsr" : "=r"(ipsr));
    sh_puts("FATAL: exception ");
    sh_put_u32(ipsr & 0x1FFu);
    sh_puts(" (3 = HardFault, 4 = MemManage, 5 = BusFault, 6 = UsageFault)\n");
    sh_exit(99);
}

typedef void (*vector_t)(void);

/* Initial stack pointer, reset, then the fixed Cortex-M exceptions. */
__attribute__((section(".isr_vector"), used)) const vector_t abbe_vectors[16] = {
    (vector_t)(uintptr_t)&__stack_top__,
    abbe_reset_handler,
    abbe_fault_handler, /* NMI */
    abbe_fault_handler, /* HardFault */
    abbe_fault_handler, /* MemManage */
    abbe_fault_handler, /* BusFault */
    abbe_fault_handler, /* UsageFault */
    0, 0, 0, 0,
    abbe_fault_handler, /* SVCall */
    abbe_fault_handler, /* DebugMonitor */
    0,
    abbe_fault_handler, /* PendSV */
    abbe_fault_handler, /* SysTick */
};

/* The compiler may emit calls to these even in freestanding code. */
void *memcpy(void *dst, const void *src, size_t n)
{
    uint8_t *d = dst;
    const uint8_t *s = src;
    while (n-- != 0u) {
        *d++ = *s++;
    }
    return dst;
}

void *memmove(void *dst, const void *src, size_t n)
{
    uint8_t *d = dst;
    const uint8_t *s = src;
    if (d < s) {
        while (n-- != 0u) {
            *d++ = *s++;
        }
    } else {
        while (n-- != 0u) {
            d[n] = s[n];
        }
    }
    return dst;
}

void *memset(void *dst, int c, size_t n)
{
    uint8_t *d = dst;
    while (n-- != 0u) {
        *d++ = (uint8_t)c;
    }
    return dst;
}

int memcmp(const void *a, const void *b, size_t n)
{
    const uint8_t *x = a;
    const uint8_t *y = b;
    for (size_t i = 0u; i < n; i++) {
        if (x[i] != y[i]) {
            return (int)x[i] - (int)y[i];
        }
    }
    return 0;
}

/* The Arm run-time ABI's names for the same (RTABI section 4.3.4; newlib's
 * libc has them): clang/LLVM calls these where GCC calls memset and memcpy,
 * e.g. __aeabi_memclr8 for clearing an 8-byte aligned struct. Note the
 * argument order of __aeabi_memset (n before c). */
void __aeabi_memcpy(void *dst, const void *src, size_t n);
void __aeabi_memcpy4(void *dst, const void *src, size_t n);
void __aeabi_memcpy8(void *dst, const void *src, size_t n);
void __aeabi_memmove(void *dst, const void *src, size_t n);
void __aeabi_memmove4(void *dst, const void *src, size_t n);
void __aeabi_memmove8(void *dst, const void *src, size_t n);
void __aeabi_memset(void *dst, size_t n, int c);
void __aeabi_memset4(void *dst, size_t n, int c);
void __aeabi_memset8(void *dst, size_t n, int c);
void __aeabi_memclr(void *dst, size_t n);
void __aeabi_memclr4(void *dst, size_t n);
void __aeabi_memclr8(void *dst, size_t n);

void __aeabi_memcpy(void *dst, const void *src, size_t n) { memcpy(dst, src, n); }
void __aeabi_memcpy4(void *dst, const void *src, size_t n) { memcpy(dst, src, n); }
void __aeabi_memcpy8(void *dst, const void *src, size_t n) { memcpy(dst, src, n); }
void __aeabi_memmove(void *dst, const void *src, size_t n) { memmove(dst, src, n); }
void __aeabi_memmove4(void *dst, const void *src, size_t n) { memmove(dst, src, n); }
void __aeabi_memmove8(void *dst, const void *src, size_t n) { memmove(dst, src, n); }
void __aeabi_memset(void *dst, size_t n, int c) { memset(dst, c, n); }
void __aeabi_memset4(void *dst, size_t n, int c) { memset(dst, c, n); }
void __aeabi_memset8(void *dst, size_t n, int c) { memset(dst, c, n); }
void __aeabi_memclr(void *dst, size_t n) { memset(dst, 0, n); }
void __aeabi_memclr4(void *dst, size_t n) { memset(dst, 0, n); }
void __aeabi_memclr8(void *dst, size_t n) { memset(dst, 0, n); }
