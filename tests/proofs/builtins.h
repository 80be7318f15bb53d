/* The GCC builtins the library uses, as Frama-C sees them (included before
 * every analysed file by scripts/prove.sh). The contracts are GCC's documented
 * semantics: __builtin_clz(x) is undefined for x == 0 (a precondition the
 * analysis checks at each call) and counts leading zero bits, 0..31. */
#ifndef ABBE_PROOF_BUILTINS_H
#define ABBE_PROOF_BUILTINS_H
/*@ requires nonzero: x != 0;
    assigns \result \from x;
    ensures range: 0 <= \result <= 31;
    ensures definition: x >> (31 - \result) == 1;
 */
int __builtin_clz(unsigned int x);
/*@ assigns \result \from p;
    ensures \result == p; */
void *__builtin_assume_aligned(const void *p, unsigned long align);
#endif
