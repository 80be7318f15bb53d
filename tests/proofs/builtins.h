/* The GCC builtins the library uses, as Frama-C sees them (included before
 * every analysed file by scripts/prove.sh). The contracts are GCC's documented
 * semantics: __builtin_clz(x) is undefined for x == 0 (a precondition the
 * analysis checks at each call) and counts leading zero bits, 0..31. */
#ifndef ABBE_PROOF_BUILTINS_H
#define ABBE_PROOF_BUILTINS_H
#if defined(PROOF_CLZ_AS_CODE)
/* The evaluator harnesses load one concrete table: a definition rather than
 * the contract keeps the loader's Chebyshev scaling (cheb_shift, cheb_mul)
 * exact, so the evaluation is analysed with the values the table gives. The
 * same semantics: undefined for 0 (asserted), else the leading zero bits. */
static inline int abbe_proof_clz(unsigned int x)
{
    //@ assert nonzero: x != 0;
    int n = 0;
    if (x <= 0x0000FFFFu) { n += 16; x <<= 16; }
    if (x <= 0x00FFFFFFu) { n += 8; x <<= 8; }
    if (x <= 0x0FFFFFFFu) { n += 4; x <<= 4; }
    if (x <= 0x3FFFFFFFu) { n += 2; x <<= 2; }
    if (x <= 0x7FFFFFFFu) { n += 1; }
    return n;
}
#define __builtin_clz abbe_proof_clz
#else
/*@ requires nonzero: x != 0;
    assigns \result \from x;
    ensures range: 0 <= \result <= 31;
    ensures definition: x >> (31 - \result) == 1;
 */
int __builtin_clz(unsigned int x);
#endif
/* __builtin_add_overflow as GCC documents it, for the one use the library
 * makes of it (int operands and result, thermal_q.c th_sat_add): the sum
 * computed whole, stored wrapped to 32 bits, 1 when it did not fit. */
static inline int abbe_proof_add_overflow(int a, int b, int *r)
{
    long long sum = (long long)a + b;
    if (sum > 2147483647LL) {
        *r = (int)(sum - 4294967296LL);
        return 1;
    }
    if (sum < -2147483647LL - 1LL) {
        *r = (int)(sum + 4294967296LL);
        return 1;
    }
    *r = (int)sum;
    return 0;
}
#define __builtin_add_overflow(a, b, r) abbe_proof_add_overflow((a), (b), (r))
/*@ assigns \result \from p;
    ensures \result == p; */
void *__builtin_assume_aligned(const void *p, unsigned long align);
#endif
