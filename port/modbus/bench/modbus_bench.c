/* abbe-modbusd benchmark: request round trip on loopback, table upload time,
 * and a paced position/correction exchange (default 1 kHz) checked cycle by
 * cycle against a local compensator. Reports numbers, asserts no timing:
 * it fails only on transport errors, wrong corrections, a server that does
 * not exit cleanly (valgrind's error exit code included) or resident memory
 * that grows during the exchange.
 *
 *   modbus_bench [--duration S] [--rate HZ] [--rtt N] [--uploads N]
 *                [--valgrind] [--server PATH]
 */
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "abbe/modbus_port.h"
#include "golden_data.h"
#include "harness.h"
#include "scenario.h"

static double now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e6 + (double)ts.tv_nsec / 1e3;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double pct(double *v, int n, double p)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    int i = (int)(p * (n - 1) + 0.5);
    return v[i < 0 ? 0 : (i >= n ? n - 1 : i)];
}

static long rss_kb(pid_t pid)
{
    char path[64], line[256];
    long kb = -1;
    snprintf(path, sizeof path, "/proc/%d/status", (int)pid);
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        return -1;
    }
    while (fgets(line, sizeof line, f) != NULL) {
        if (strncmp(line, "VmRSS:", 6) == 0) {
            kb = strtol(line + 6, NULL, 10);
        }
    }
    fclose(f);
    return kb;
}

int main(int argc, char **argv)
{
    double duration_s = 2.0, rate_hz = 1000.0;
    int rtt_n = 2000, uploads = 10, valgrind = 0;
    const char *server = ABBE_MODBUSD;
    for (int i = 1; i < argc; i++) {
        const char *v = i + 1 < argc ? argv[i + 1] : "";
        if (strcmp(argv[i], "--duration") == 0) {
            duration_s = atof(v), i++;
        } else if (strcmp(argv[i], "--rate") == 0) {
            rate_hz = atof(v), i++;
        } else if (strcmp(argv[i], "--rtt") == 0) {
            rtt_n = atoi(v), i++;
        } else if (strcmp(argv[i], "--uploads") == 0) {
            uploads = atoi(v), i++;
        } else if (strcmp(argv[i], "--server") == 0) {
            server = v, i++;
        } else if (strcmp(argv[i], "--valgrind") == 0) {
            valgrind = 1;
        } else {
            fprintf(stderr, "usage: modbus_bench [--duration S] [--rate HZ] [--rtt N] "
                            "[--uploads N] [--valgrind] [--server PATH]\n");
            return 2;
        }
    }
    if (rtt_n < 10 || uploads < 1 || rate_hz <= 0.0 || duration_s <= 0.0) {
        fprintf(stderr, "modbus_bench: bad arguments\n");
        return 2;
    }

    const uint8_t *full = NULL;
    size_t full_size = 0;
    for (uint32_t i = 0; i < abbe_golden_table_count; i++) {
        if (strcmp(abbe_golden_tables[i].name, "full") == 0) {
            full = abbe_golden_tables[i].blob;
            full_size = abbe_golden_tables[i].blob_size;
        }
    }
    const char *vg[] = {"valgrind", "--quiet", "--leak-check=full", "--show-leak-kinds=all",
                        "--errors-for-leak-kinds=all", "--error-exitcode=99", NULL};
    const char *args[] = {server, "--tcp", "127.0.0.1:0", NULL};
    mbt_server_t srv;
    if (full == NULL || mbt_server_start(&srv, valgrind ? vg : NULL, args, 60000) != 0) {
        fprintf(stderr, "modbus_bench: cannot start %s\n", server);
        return 1;
    }
    modbus_t *ctx = mbt_tcp_client(srv.port);
    int failures = 0;
    if (ctx == NULL) {
        mbt_server_stop(&srv);
        return 1;
    }
    printf("abbe-modbusd benchmark (%s), TCP loopback port %d\n",
           valgrind ? "server under valgrind memcheck" : "native", srv.port);

    /* 1. request round trips */
    double *t = malloc(sizeof(double) * (size_t)rtt_n);
    uint16_t regs[MODBUS_MAX_READ_REGISTERS];
    for (int i = 0; i < rtt_n && t != NULL; i++) {
        double t0 = now_us();
        if (modbus_read_registers(ctx, ABBE_MB_REG_OUT_BASE, ABBE_MB_OUT_COUNT, regs) != ABBE_MB_OUT_COUNT) {
            failures++;
        }
        t[i] = now_us() - t0;
    }
    if (t != NULL) {
        printf("round trip FC03 (15 regs): median %.1f us, p99 %.1f us (n=%d)\n", pct(t, rtt_n, 0.5),
               pct(t, rtt_n, 0.99), rtt_n);
    }

    /* 2. table upload (the largest table format 1.0 allows) */
    double *u = malloc(sizeof(double) * (size_t)uploads);
    uint32_t crc = abbe_crc32(0, full, full_size);
    for (int i = 0; i < uploads && u != NULL; i++) {
        double t0 = now_us();
        if (mbt_upload(ctx, full, full_size, crc, MODBUS_MAX_WRITE_REGISTERS, 0) != 0) {
            failures++;
        }
        u[i] = now_us() - t0;
    }
    if (u != NULL) {
        size_t chunks = (full_size + 245u) / 246u;
        printf("upload %zu-byte table (%zu requests): median %.2f ms, p99 %.2f ms (n=%d)\n", full_size,
               chunks + 2u, pct(u, uploads, 0.5) / 1e3, pct(u, uploads, 0.99) / 1e3, uploads);
    }

    /* 3. paced exchange: FC23 writes the inputs (cycle trigger), reads outputs */
    abbe_comp_config_t cfg = scn_config();
    abbe_comp_t local;
    abbe_model_t slot;
    abbe_comp_init(&local, &cfg, NULL);
    abbe_comp_load_model(&local, &slot, full, full_size);
    abbe_comp_enable(&local);
    if (modbus_write_register(ctx, ABBE_MB_REG_CT_ENABLE, 0) != 1) {
        failures++;
    }
    for (int k = 0; k < 20000; k++) { /* fade out what earlier runs left */
        uint16_t c = 0;
        modbus_write_and_read_registers(ctx, ABBE_MB_REG_IN_CYCLE, 1, &c, ABBE_MB_REG_OUT_BASE,
                                        ABBE_MB_OUT_COUNT, regs);
        if (regs[0] == 0 && regs[1] == 0 && regs[2] == 0 && regs[3] == 0 && regs[4] == 0 && regs[5] == 0) {
            break;
        }
    }
    if (scn_configure(ctx, 0) != 0 || scn_upload(ctx, full, full_size, 0) != 0 ||
        modbus_write_register(ctx, ABBE_MB_REG_CT_ENABLE, 1) != 1) {
        failures++;
    }
    long n_cycles = (long)(duration_s * rate_hz);
    double period_ns = 1e9 / rate_hz, worst = 0.0;
    long errors = 0, mismatches = 0, overruns = 0;
    double *c = malloc(sizeof(double) * (size_t)n_cycles);
    long rss0 = -1, rss1 = -1;
    struct timespec next;
    clock_gettime(CLOCK_MONOTONIC, &next);
    for (long k = 0; k < n_cycles && c != NULL; k++) {
        abbe_comp_input_q_t in;
        abbe_comp_output_t out;
        uint16_t w[ABBE_MB_IN_COUNT];
        memset(&in, 0, sizeof in);
        /* a slow 3-axis Lissajous path through the travel, 20 degC */
        long ph = k % 20000;
        for (int j = 0; j < ABBE_AXES; j++) {
            long q = (ph * (j + 2)) % 20000;
            long tri = q < 10000 ? q : 20000 - q; /* 0..10000 */
            in.pos_nm[j] = (int32_t)((j == 0 ? 100000000 : -1400000000 + 500000000 * (j - 1)) + 100000 * tri);
            in.temp_mdegc[j] = 20000;
            mbt_put32(&w[2 * j], (uint32_t)in.pos_nm[j], 0);
            w[6 + j] = 0;
            w[9 + j] = 2000;
        }
        in.fresh = 1;
        w[12] = 0;
        w[13] = (uint16_t)k;
        double t0 = now_us();
        int rc = modbus_write_and_read_registers(ctx, ABBE_MB_REG_IN_BASE, ABBE_MB_IN_COUNT, w,
                                                 ABBE_MB_REG_OUT_BASE, ABBE_MB_OUT_COUNT, regs);
        c[k] = now_us() - t0;
        worst = c[k] > worst ? c[k] : worst;
        abbe_comp_step_q(&local, &in, &out);
        if (rc != ABBE_MB_OUT_COUNT) {
            errors++;
        } else {
            int bad = regs[ABBE_MB_REG_OUT_CYCLE - ABBE_MB_REG_OUT_BASE] != (uint16_t)k;
            for (int j = 0; j < ABBE_AXES; j++) {
                bad |= (int32_t)mbt_get32(&regs[2 * j], 0) != out.corr_nm[j];
            }
            mismatches += bad;
        }
        if (k == n_cycles / 10) {
            rss0 = rss_kb(srv.pid); /* after warm-up */
        }
        next.tv_nsec += (long)period_ns;
        while (next.tv_nsec >= 1000000000L) {
            next.tv_nsec -= 1000000000L;
            next.tv_sec++;
        }
        struct timespec now;
        clock_gettime(CLOCK_MONOTONIC, &now);
        if (now.tv_sec > next.tv_sec || (now.tv_sec == next.tv_sec && now.tv_nsec > next.tv_nsec)) {
            overruns++; /* the exchange took longer than one period: no catching up */
            next = now;
        } else {
            clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL); /* the pacing clock */
        }
    }
    rss1 = rss_kb(srv.pid);
    if (c != NULL) {
        printf("exchange at %.0f Hz for %.1f s: %ld cycles, %ld errors, %ld wrong corrections, "
               "%ld overran the period; FC23 round trip median %.1f us, p99 %.1f us, max %.1f us\n",
               rate_hz, duration_s, n_cycles, errors, mismatches, overruns, pct(c, (int)n_cycles, 0.5),
               pct(c, (int)n_cycles, 0.99), worst);
    }
    printf("server resident memory: %ld kB after warm-up, %ld kB at the end (%+ld kB)\n", rss0, rss1,
           rss1 - rss0);
    modbus_close(ctx);
    modbus_free(ctx);
    int status = mbt_server_stop(&srv);
    printf("server exit status %d%s\n", status,
           valgrind ? (status == 0 ? " (valgrind: no errors, no leaks)" : " (valgrind reported errors)") : "");
    free(t);
    free(u);
    free(c);
    /* Pages first touched late can add a little RSS; growth beyond 256 kB over
     * the run would mean allocation per request. */
    int grew = rss0 > 0 && rss1 - rss0 > 256;
    if (failures || errors || mismatches || status != 0 || grew) {
        printf("FAILED: %d setup failures, %ld errors, %ld mismatches, exit %d, memory grew %d\n", failures,
               errors, mismatches, status, grew);
        return 1;
    }
    printf("OK\n");
    return 0;
}
