/* abbe CAN port: TOML numbers of the configuration file (can_toml_number.c).
 * Not installed. */
#ifndef ABBE_CAN_TOML_NUMBER_H
#define ABBE_CAN_TOML_NUMBER_H

/* s a whole TOML integer (decimal with sign, or 0x hex)? 1: *out set;
 * 0: not an integer; -1: an integer beyond 64 bits. */
int abbe_can_toml_int(const char *s, long long *out);

/* s a whole TOML number (an integer, or a float with a fraction or an
 * exponent)? 1: *out set (finite, |v| < 1e300); 0: not a number; -1: out of
 * that range. */
int abbe_can_toml_number(const char *s, double *out);

#endif /* ABBE_CAN_TOML_NUMBER_H */
