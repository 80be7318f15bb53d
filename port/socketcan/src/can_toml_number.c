/* abbe CAN port: the TOML number syntax of the configuration file (host):
 * integers (decimal, 0x hex) and floats, '_' between digits, no inf / nan.
 * Split from the parser (can_config_parse.c), which only asks "is this text
 * a number, and which". */
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "can_toml_number.h"

/* TOML number syntax (a digit run allows single '_' between digits):
 *   decimal integer  [+-]? (0 | [1-9] digits)
 *   hex integer      0x hexdigits              (no sign)
 *   float            decimal integer (. digits)? ([eE] [+-]? digits)?, with a
 *                    fraction or an exponent; inf and nan are not accepted.
 * Each function checks the syntax, then converts the text without the '_'.
 * Every scan also stops at end (the text's '\0', where it would stop anyway):
 * the bound never binds, it makes each read's bound evident to the proof
 * (tests/proofs/can_config.c). */

static int is_digit(char c)
{
    return c >= '0' && c <= '9';
}

static int is_hex(char c)
{
    return is_digit(c) || (c >= 'a' && c <= 'f') || (c >= 'A' && c <= 'F');
}

/* A run of digits (hex or decimal) with single '_' between them; returns the
 * position after it, or NULL if there is none or an '_' is misplaced. */
static const char *digit_run(const char *p, const char *end, int hex)
{
    if (p >= end || !(hex ? is_hex(*p) : is_digit(*p))) {
        return NULL;
    }
    while (p < end && (hex ? is_hex(*p) : is_digit(*p))) {
        p++;
        if (p < end && *p == '_') {
            p++;
            if (!(hex ? is_hex(*p) : is_digit(*p))) {
                return NULL;
            }
        }
    }
    return p;
}

/* The decimal integer part: sign, no leading zero. */
static const char *decimal_int(const char *p, const char *end)
{
    if (p < end && (*p == '+' || *p == '-')) {
        p++;
    }
    if (p < end && p[0] == '0') {
        return (is_digit(p[1]) || p[1] == '_') ? NULL : p + 1;
    }
    return digit_run(p, end, 0);
}

/* s without '_' into buf (the syntax was checked: it fits). */
#define NUMBER_MAX 64u /* a number's text, '\0' included (read_value: < 64 characters) */

static void strip(const char *s, const char *end, char buf[NUMBER_MAX])
{
    size_t n = 0;
    for (; s < end && *s != '\0' && n < NUMBER_MAX - 1u; s++) {
        if (*s != '_') {
            buf[n++] = *s;
        }
    }
    buf[n] = '\0';
}

/* 1: *out set; 0: not an integer; -1: an integer beyond 64 bits. */
int abbe_can_toml_int(const char *s, long long *out)
{
    char buf[NUMBER_MAX] = {0};
    const char *end = s + strlen(s);
    errno = 0;
    long long v;
    if (s[0] == '0' && s[1] == 'x') {
        const char *e = digit_run(s + 2, end, 1);
        if (e == NULL || *e != '\0') {
            return 0;
        }
        strip(s + 2, end, buf);
        unsigned long long u = strtoull(buf, NULL, 16);
        if (errno != 0 || u > (unsigned long long)0x7FFFFFFFFFFFFFFFLL) {
            return -1;
        }
        v = (long long)u;
    } else {
        const char *e = decimal_int(s, end);
        if (e == NULL || *e != '\0') {
            return 0;
        }
        strip(s, end, buf);
        v = strtoll(buf, NULL, 10);
        if (errno != 0) {
            return -1;
        }
    }
    *out = v;
    return 1;
}

/* 1: *out set (finite, |v| < 1e300); 0: not a number; -1: out of that range. */
int abbe_can_toml_number(const char *s, double *out)
{
    long long i = 0;
    int st = abbe_can_toml_int(s, &i);
    if (st != 0) {
        *out = (double)i;
        return st;
    }
    const char *end = s + strlen(s);
    const char *p = decimal_int(s, end);
    if (p == NULL) {
        return 0;
    }
    int has_fraction = 0, has_exponent = 0;
    if (p < end && *p == '.') {
        p = digit_run(p + 1, end, 0);
        if (p == NULL) {
            return 0;
        }
        has_fraction = 1;
    }
    if (p < end && (*p == 'e' || *p == 'E')) {
        p++;
        if (p < end && (*p == '+' || *p == '-')) {
            p++;
        }
        p = digit_run(p, end, 0);
        if (p == NULL) {
            return 0;
        }
        has_exponent = 1;
    }
    if (*p != '\0' || !(has_fraction || has_exponent)) {
        return 0;
    }
    char buf[NUMBER_MAX] = {0};
    strip(s, end, buf);
    /* the syntax above is a subset of strtod's (the C locale: nothing here
     * calls setlocale), so it reads the whole text */
    double v = strtod(buf, NULL);
    /* |v| < 1e300 on the bits (binary64 magnitudes order as integers, NaN
     * above the infinities), the value rebuilt from the magnitude: the proof
     * follows a magnitude below 1e300's bits to a finite double */
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    uint64_t magnitude = bits & 0x7FFFFFFFFFFFFFFFull;
    if (magnitude >= 0x7E37E43C8800759Cull) { /* the bits of 1e300 */
        return -1; /* overflow to infinity */
    }
    double m;
    memcpy(&m, &magnitude, sizeof m);
    *out = (bits >> 63) != 0u ? -m : m; /* an underflow to 0 or a subnormal is that value */
    return 1;
}
