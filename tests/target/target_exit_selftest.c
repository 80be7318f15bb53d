/* Harness self-test: prints over semihosting and exits with status 1.
 * Registered with WILL_FAIL, so it proves that a failing target program
 * fails its CTest (the exit status crosses QEMU) rather than passing silently. */
#include "semihost.h"

int main(void)
{
    sh_puts("target_exit_selftest: exiting with status 1 on purpose\n");
    return 1;
}
