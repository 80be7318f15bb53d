/* abbe CAN port: candump -l log lines (portable, no stdio). */
#include <string.h>

#include "abbe_can_log.h"

static int hexval(char c)
{
    if (c >= '0' && c <= '9') {
        return c - '0';
    }
    if (c >= 'a' && c <= 'f') {
        return c - 'a' + 10;
    }
    if (c >= 'A' && c <= 'F') {
        return c - 'A' + 10;
    }
    return -1;
}

static int is_space(char c)
{
    return c == ' ' || c == '\t';
}

static int is_eol(char c)
{
    return c == '\0' || c == '\n' || c == '\r';
}

/* "(SEC.FRAC)" -> sec, usec; returns the position after ')' or NULL. */
static const char *parse_time(const char *p, uint64_t *sec, uint32_t *usec)
{
    if (*p != '(') {
        return NULL;
    }
    p++;
    uint64_t s = 0;
    int digits = 0;
    while (*p >= '0' && *p <= '9') {
        if (s > (UINT64_MAX - 9u) / 10u) {
            return NULL;
        }
        s = s * 10u + (uint64_t)(*p - '0');
        p++;
        digits++;
    }
    if (digits == 0 || *p != '.') {
        return NULL;
    }
    p++;
    uint32_t us = 0;
    int frac = 0;
    while (*p >= '0' && *p <= '9') {
        if (frac < 6) {
            us = us * 10u + (uint32_t)(*p - '0');
        }
        p++;
        frac++;
    }
    if (frac == 0 || *p != ')') {
        return NULL;
    }
    for (int k = frac; k < 6; k++) {
        us *= 10u;
    }
    *sec = s;
    *usec = us;
    return p + 1;
}

static const char *parse_frame(const char *p, abbe_can_frame_t *f)
{
    uint32_t id = 0;
    int n = 0;
    while (hexval(p[n]) >= 0) {
        if (n == 8) {
            return NULL;
        }
        id = (id << 4) | (uint32_t)hexval(p[n]);
        n++;
    }
    if (p[n] != '#' || (n != 3 && n != 8)) {
        return NULL;
    }
    memset(f, 0, sizeof *f);
    if (n == 3) {
        if (id > ABBE_CAN_SFF_MASK) {
            return NULL;
        }
        f->id = id;
    } else if (id & ABBE_CAN_ERR_FLAG) {
        /* candump prints error frames with the flag inside an 8-digit id */
        f->id = id & (ABBE_CAN_ERR_FLAG | ABBE_CAN_EFF_MASK);
    } else {
        f->id = (id & ABBE_CAN_EFF_MASK) | ABBE_CAN_EFF_FLAG;
    }
    p += n + 1;
    if (*p == '#') {
        return NULL; /* CAN FD ("##"): the caller reports it before parsing */
    }
    if (*p == 'R' || *p == 'r') {
        f->id |= ABBE_CAN_RTR_FLAG;
        p++;
        int v = hexval(*p);
        if (v >= 0 && v <= 8) {
            f->dlc = (uint8_t)v;
            p++;
        }
    } else {
        uint8_t len = 0;
        while (hexval(p[0]) >= 0) {
            if (hexval(p[1]) < 0 || len == ABBE_CAN_MAX_DLEN) {
                return NULL;
            }
            f->data[len++] = (uint8_t)((hexval(p[0]) << 4) | hexval(p[1]));
            p += 2;
            if (*p == '.') {
                p++;
            }
        }
        f->dlc = len;
    }
    if (*p == '_') { /* len8_dlc (DLC 9..15 of an 8-byte frame): accepted, not kept */
        if (hexval(p[1]) < 0) {
            return NULL;
        }
        p += 2;
    }
    return p;
}

int abbe_can_log_parse(const char *line, abbe_can_log_entry_t *entry)
{
    if (line == NULL || entry == NULL) {
        return ABBE_CAN_E_ARG;
    }
    const char *p = parse_time(line, &entry->sec, &entry->usec);
    if (p == NULL || !is_space(*p)) {
        return ABBE_CAN_E_PARSE;
    }
    while (is_space(*p)) {
        p++;
    }
    size_t n = 0;
    while (!is_space(p[n]) && !is_eol(p[n])) {
        n++;
    }
    if (n == 0 || n >= ABBE_CAN_IFNAME_MAX || !is_space(p[n])) {
        return ABBE_CAN_E_PARSE;
    }
    memcpy(entry->ifname, p, n);
    entry->ifname[n] = '\0';
    p += n;
    while (is_space(*p)) {
        p++;
    }
    const char *hash = p;
    while (hexval(*hash) >= 0) {
        hash++;
    }
    if (hash[0] == '#' && hash[1] == '#') {
        return ABBE_CAN_E_UNSUPPORTED;
    }
    p = parse_frame(p, &entry->frame);
    if (p == NULL) {
        return ABBE_CAN_E_PARSE;
    }
    while (is_space(*p)) {
        p++;
    }
    if ((*p == 'R' || *p == 'T') && (is_space(p[1]) || is_eol(p[1]))) { /* direction flag */
        p++;
        while (is_space(*p)) {
            p++;
        }
    }
    while (*p == '\r' || *p == '\n') {
        p++;
    }
    return *p == '\0' ? ABBE_CAN_OK : ABBE_CAN_E_PARSE;
}

static const char HEX[] = "0123456789ABCDEF";

int abbe_can_log_format(const abbe_can_log_entry_t *entry, char *buf, size_t size)
{
    if (entry == NULL || buf == NULL) {
        return ABBE_CAN_E_ARG;
    }
    char tmp[96];
    size_t n = 0;
    char digits[21];
    int nd = 0;
    uint64_t s = entry->sec;
    do {
        digits[nd++] = (char)('0' + (int)(s % 10u));
        s /= 10u;
    } while (s != 0u);
    tmp[n++] = '(';
    while (nd > 0) {
        tmp[n++] = digits[--nd];
    }
    tmp[n++] = '.';
    uint32_t us = entry->usec % 1000000u;
    for (uint32_t div = 100000u; div > 0u; div /= 10u) {
        tmp[n++] = (char)('0' + (int)((us / div) % 10u));
    }
    tmp[n++] = ')';
    tmp[n++] = ' ';
    size_t iflen = strlen(entry->ifname);
    if (iflen == 0 || iflen >= ABBE_CAN_IFNAME_MAX) {
        return ABBE_CAN_E_ARG;
    }
    memcpy(&tmp[n], entry->ifname, iflen);
    n += iflen;
    tmp[n++] = ' ';
    const abbe_can_frame_t *f = &entry->frame;
    uint32_t id;
    int width;
    if (f->id & (ABBE_CAN_ERR_FLAG | ABBE_CAN_EFF_FLAG)) {
        id = f->id & (ABBE_CAN_ERR_FLAG | ABBE_CAN_EFF_MASK);
        width = 8;
    } else {
        id = f->id & ABBE_CAN_SFF_MASK;
        width = 3;
    }
    for (int k = width - 1; k >= 0; k--) {
        tmp[n++] = HEX[(id >> (4 * k)) & 0xFu];
    }
    tmp[n++] = '#';
    uint8_t len = f->dlc > ABBE_CAN_MAX_DLEN ? (uint8_t)ABBE_CAN_MAX_DLEN : f->dlc;
    if (f->id & ABBE_CAN_RTR_FLAG) {
        tmp[n++] = 'R';
        if (len > 0u) {
            tmp[n++] = HEX[len];
        }
    } else {
        for (unsigned i = 0; i < len; i++) {
            tmp[n++] = HEX[f->data[i] >> 4];
            tmp[n++] = HEX[f->data[i] & 0xFu];
        }
    }
    tmp[n++] = '\n';
    if (n + 1u > size) {
        return ABBE_CAN_E_ARG;
    }
    memcpy(buf, tmp, n);
    buf[n] = '\0';
    return (int)n;
}
