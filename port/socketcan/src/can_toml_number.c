/* abbe CAN port: the TOML number syntax of the configuration file (host):
 * integers (decimal, 0x hex) and floats, '_' between digits, no inf / nan.
 * Split from the parser (can_config_parse.c), which only asks "is this text
 * a number, and which". */
#include <errno.h>
#include <stdlib.h>

#include "can_toml_number.h"

/* TOML number syntax (a digit run allows single '_' between digits):
 *   decimal integer  [+-]? (0 | [1-9] digits)
 *   hex integer      0x hexdigits              (no sign)
 *   float            decimal integer (. digits)? ([eE] [+-]? digits)?, with a
 *                    fraction or an exponent; inf and nan are not accepted.
 * Each function checks the syntax, then converts the text without the '_'. */

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
static const char *digit_run(const char *p, int hex)
{
    if (!(hex ? is_hex(*p) : is_digit(*p))) {
        return NULL;
    }
    while (hex ? is_hex(*p) : is_digit(*p)) {
        p++;
        if (*p == '_') {
            p++;
            if (!(hex ? is_hex(*p) : is_digit(*p))) {
                return NULL;
            }
        }
    }
    return p;
}

/* The decimal integer part: sign, no leading zero. */
static const char *decimal_int(const char *p)
{
    if (*p == '+' || *p == '-') {
        p++;
    }
    if (p[0] == '0') {
        return (is_digit(p[1]) || p[1] == '_') ? NULL : p + 1;
    }
    return digit_run(p, 0);
}

/* s without '_' into buf (the syntax was checked: it fits). */
static void strip(const char *s, char *buf, size_t cap)
{
    size_t n = 0;
    for (; *s != '\0' && n + 1u < cap; s++) {
        if (*s != '_') {
            buf[n++] = *s;
        }
    }
    buf[n] = '\0';
}

/* 1: *out set; 0: not an integer; -1: an integer beyond 64 bits. */
int abbe_can_toml_int(const char *s, long long *out)
{
    char buf[64];
    char *end = NULL;
    errno = 0;
    long long v;
    if (s[0] == '0' && s[1] == 'x') {
        const char *e = digit_run(s + 2, 1);
        if (e == NULL || *e != '\0') {
            return 0;
        }
        strip(s + 2, buf, sizeof buf);
        unsigned long long u = strtoull(buf, &end, 16);
        if (errno != 0 || u > (unsigned long long)0x7FFFFFFFFFFFFFFFLL) {
            return -1;
        }
        v = (long long)u;
    } else {
        const char *e = decimal_int(s);
        if (e == NULL || *e != '\0') {
            return 0;
        }
        strip(s, buf, sizeof buf);
        v = strtoll(buf, &end, 10);
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
    long long i;
    int st = abbe_can_toml_int(s, &i);
    if (st != 0) {
        *out = (double)i;
        return st;
    }
    const char *p = decimal_int(s);
    if (p == NULL) {
        return 0;
    }
    int has_fraction = 0, has_exponent = 0;
    if (*p == '.') {
        p = digit_run(p + 1, 0);
        if (p == NULL) {
            return 0;
        }
        has_fraction = 1;
    }
    if (*p == 'e' || *p == 'E') {
        p++;
        if (*p == '+' || *p == '-') {
            p++;
        }
        p = digit_run(p, 0);
        if (p == NULL) {
            return 0;
        }
        has_exponent = 1;
    }
    if (*p != '\0' || !(has_fraction || has_exponent)) {
        return 0;
    }
    char buf[64];
    strip(s, buf, sizeof buf);
    char *end = NULL;
    errno = 0;
    double v = strtod(buf, &end);
    if (end == buf || *end != '\0') {
        return 0;
    }
    if (!(v > -1e300 && v < 1e300)) {
        return -1; /* overflow to infinity */
    }
    *out = v; /* an underflow to 0 or a subnormal is that value */
    return 1;
}
