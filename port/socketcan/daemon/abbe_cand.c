/* abbe-cand: the abbe compensator on a CANopen bus of CiA 402 drives.
 *
 *   abbe-cand -c CONFIG [-i IFACE | --fd N] [--ready-fd N] [-v]
 *   abbe-cand -c CONFIG --replay IN.log [-o OUT.log]
 *   abbe-cand -c CONFIG --check
 *
 * Live: opens a CAN_RAW socket on the configured interface (or uses an
 * already open fd carrying struct can_frame records), loads the model and
 * runs one compensator cycle per SYNC. SIGHUP (or a RELOAD command frame)
 * reloads the model file; SIGUSR1 prints the counters; SIGTERM/SIGINT, or the
 * peer closing the fd, ends it. Replay: reads a candump -l log and writes the
 * frames it would have sent, in the same format. docs/can.md has the details.
 *
 * Exit status: 0 ok, 1 run-time failure (I/O), 2 bad input (usage,
 * configuration, model, log line).
 */
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <limits.h>
#include <sys/select.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "abbe_can.h"
#include "abbe_can_config.h"
#include "abbe_can_driver.h"
#include "abbe_can_linux.h"
#include "abbe_can_log.h"

#define PROG "abbe-cand"
#define EXIT_RUNTIME 1
#define EXIT_INPUT 2

static abbe_can_node_t g_node; /* ~33 KiB: static, not on the stack */

static volatile sig_atomic_t g_stop, g_reload, g_dump;

static void on_signal(int sig)
{
    if (sig == SIGHUP) {
        g_reload = 1;
    } else if (sig == SIGUSR1) {
        g_dump = 1;
    } else {
        g_stop = 1;
    }
}

static void logmsg(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fputs(PROG ": ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

static void usage(FILE *fp)
{
    fprintf(fp,
            "usage: " PROG " -c CONFIG [-i IFACE | --fd N] [--ready-fd N] [-v]\n"
            "       " PROG " -c CONFIG --replay IN.log [-o OUT.log]\n"
            "       " PROG " -c CONFIG --check\n"
            "\n"
            "  -c, --config FILE   configuration (docs/can.md)\n"
            "  -i, --interface IF  SocketCAN interface (overrides bus.interface)\n"
            "      --fd N          use the open fd N (struct can_frame records) instead of a socket\n"
            "      --ready-fd N    write \"ready\\n\" to fd N once running, then close it\n"
            "      --replay FILE   replay a candump -l log offline; write the frames sent\n"
            "  -o, --out FILE      replay output (default: standard output)\n"
            "      --check         check the configuration and model, print the frame map\n"
            "  -v, --verbose       log every ignored frame\n"
            "      --version       print the version\n");
}

static void print_counters(const abbe_can_node_t *node)
{
    abbe_can_counters_t c = abbe_can_node_counters(node);
    abbe_comp_stats_t s = abbe_can_node_comp_stats(node);
    logmsg("counters: cycles %lu, rx %lu (positions %lu, commands %lu, temperatures %lu), tx %lu (errors %lu), "
           "stale cycles %lu; ignored %lu (bad DLC %lu, unknown id %lu, RTR %lu, error frames %lu, bad command %lu, "
           "bad value %lu, malformed %lu); models loaded %lu, refused %lu, swaps %lu; limit trips %lu; model 0x%08lx",
           (unsigned long)c.syncs, (unsigned long)c.frames_rx, (unsigned long)c.positions,
           (unsigned long)c.commands, (unsigned long)c.temperatures, (unsigned long)c.frames_tx,
           (unsigned long)c.tx_errors, (unsigned long)c.stale_cycles, (unsigned long)abbe_can_node_ignored(node),
           (unsigned long)c.bad_dlc, (unsigned long)c.unknown_id, (unsigned long)c.rtr,
           (unsigned long)c.error_frames, (unsigned long)c.bad_command, (unsigned long)c.bad_value,
           (unsigned long)c.malformed, (unsigned long)c.model_loads_ok,
           (unsigned long)c.model_loads_failed, (unsigned long)s.model_swaps, (unsigned long)s.limit_trips,
           (unsigned long)abbe_can_node_model_crc(node));
}

/* Load the configured model file; 0 on success. */
static int reload_model(abbe_can_node_t *node, const char *path)
{
    char why[ABBE_CAN_PATH_MAX + 256];
    int st = abbe_can_model_load_file(node, path, why, sizeof why);
    logmsg("%s", why);
    return st;
}

static const char *state_name(abbe_comp_state_t s)
{
    return s == ABBE_COMP_ON ? "ON" : (s == ABBE_COMP_FAULT ? "FAULT" : "OFF");
}

/* Log what changed since the last call: compensator state, stale input,
 * limit fault, model swap, newly ignored frames. Called after every frame, so
 * a line names the cycle it happened in: "cycle N", N counted from 0 at the
 * first SYNC, the cycle whose status frame carries Seq = N mod 256. */
typedef struct {
    abbe_comp_state_t state;
    uint32_t flags;
    uint32_t ignored;
    uint32_t syncs;
    uint32_t crc;
    uint32_t next_report; /* without -v: report ignored frames at 1, 10, 100, ... */
    int verbose;
    int temp_stale;
} monitor_t;

/* "X 20.50, Y 20.10, Z 21.00 degC" */
static void temps_text(const abbe_can_node_t *node, char *buf, size_t size)
{
    char part[ABBE_AXES][24];
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        long m = (long)abbe_can_node_temp_mdegc(node, j);
        long a = m < 0 ? -m : m;
        snprintf(part[j], sizeof part[j], "%c %s%ld.%02ld", "XYZ"[j], m < 0 ? "-" : "", a / 1000, (a % 1000) / 10);
    }
    snprintf(buf, size, "%s, %s, %s degC", part[0], part[1], part[2]);
}

/* A temperature age for the log: "never" or the number. */
static const char *age_text(uint32_t age, char *buf, size_t size)
{
    if (age == UINT32_MAX) {
        return "never";
    }
    snprintf(buf, size, "%lu", (unsigned long)age);
    return buf;
}

static void monitor_cycle(monitor_t *m, const abbe_can_node_t *node, const abbe_comp_output_t *out, uint32_t syncs)
{
    m->syncs = syncs;
    uint32_t cycle = syncs - 1u; /* the cycle just run */
    if (out->state != m->state) {
        logmsg("cycle %lu: compensator %s -> %s", (unsigned long)cycle, state_name(m->state),
               state_name(out->state));
        m->state = out->state;
    }
    uint32_t rise = out->flags & ~m->flags, fall = m->flags & ~out->flags;
    if (rise & ABBE_FLAG_STALE) {
        logmsg("cycle %lu: stale input (position ages X %lu, Y %lu, Z %lu cycles): fading out",
               (unsigned long)cycle, (unsigned long)abbe_can_node_age(node, 0),
               (unsigned long)abbe_can_node_age(node, 1), (unsigned long)abbe_can_node_age(node, 2));
    }
    if (fall & ABBE_FLAG_STALE) {
        logmsg("cycle %lu: positions fresh again: fading in", (unsigned long)cycle);
    }
    if (rise & ABBE_FLAG_LIMIT) {
        logmsg("cycle %lu: correction over the error limit (targets %ld %ld %ld nm): fault latched",
               (unsigned long)cycle, (long)out->target_nm[0], (long)out->target_nm[1], (long)out->target_nm[2]);
    }
    if (rise & ABBE_FLAG_AXIS_FAULT) {
        logmsg("cycle %lu: a drive reports a fault (statusword bit 3): its correction fades out",
               (unsigned long)cycle);
    }
    int temp_stale = abbe_can_node_temp_stale(node);
    if (temp_stale != m->temp_stale) {
        char t[96], a[ABBE_AXES + 1][16];
        temps_text(node, t, sizeof t);
        if (temp_stale) {
            logmsg("cycle %lu: temperatures stale (cycles since the last temperature frame %s; since the last "
                   "reading X %s, Y %s, Z %s): the thermal term holds %s",
                   (unsigned long)cycle, age_text(abbe_can_node_temp_age(node, ABBE_AXES), a[3], sizeof a[3]),
                   age_text(abbe_can_node_temp_age(node, 0), a[0], sizeof a[0]),
                   age_text(abbe_can_node_temp_age(node, 1), a[1], sizeof a[1]),
                   age_text(abbe_can_node_temp_age(node, 2), a[2], sizeof a[2]), t);
        } else {
            logmsg("cycle %lu: temperatures current: %s", (unsigned long)cycle, t);
        }
        m->temp_stale = temp_stale;
    }
    uint32_t crc = abbe_can_node_model_crc(node);
    if (crc != m->crc) {
        logmsg("cycle %lu: model 0x%08lx in use", (unsigned long)cycle, (unsigned long)crc);
        m->crc = crc;
    }
    m->flags = out->flags & (ABBE_FLAG_STALE | ABBE_FLAG_LIMIT | ABBE_FLAG_AXIS_FAULT);
}

static void monitor(monitor_t *m, const abbe_can_node_t *node)
{
    const abbe_comp_output_t *out = abbe_can_node_output(node);
    abbe_can_counters_t c = abbe_can_node_counters(node);
    if (c.syncs != m->syncs) {
        monitor_cycle(m, node, out, c.syncs);
    }
    uint32_t ignored = abbe_can_node_ignored(node);
    if (ignored != m->ignored) {
        if (m->verbose || ignored >= m->next_report) {
            while (m->next_report <= ignored && m->next_report < UINT32_MAX / 10u) {
                m->next_report *= 10u;
            }
            logmsg("ignored frames: %lu (bad DLC %lu, unknown id %lu, RTR %lu, error frames %lu, bad command %lu, "
                   "bad value %lu, malformed %lu)",
                   (unsigned long)ignored, (unsigned long)c.bad_dlc, (unsigned long)c.unknown_id,
                   (unsigned long)c.rtr, (unsigned long)c.error_frames, (unsigned long)c.bad_command,
                   (unsigned long)c.bad_value, (unsigned long)c.malformed);
        }
        m->ignored = ignored;
    }
}

static void monitor_init(monitor_t *m, int verbose)
{
    memset(m, 0, sizeof *m);
    m->verbose = verbose;
    m->state = ABBE_COMP_OFF;
    m->next_report = 1;
}

static int parse_fd(const char *s, int *fd)
{
    char *end = NULL;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno != 0 || end == s || *end != '\0' || v < 0 || v > INT_MAX) {
        return 0;
    }
    *fd = (int)v;
    return 1;
}

static void print_map(const abbe_can_config_t *cfg)
{
    printf("interface %s\nmodel %s\nSYNC 0x%03lX\n", cfg->interface, cfg->model_path,
           (unsigned long)cfg->sync_cob_id);
    printf("status %s 0x%03lX\ninfo every %u cycles 0x%03lX\ncommand %s 0x%03lX\n",
           cfg->status_enable ? "on" : "off", (unsigned long)cfg->status_cob_id, (unsigned)cfg->info_period_cycles,
           (unsigned long)cfg->info_cob_id, cfg->command_enable ? "on" : "off",
           (unsigned long)cfg->command_cob_id);
    printf("temperature %s 0x%03lX stale after %u cycles\n", cfg->temp_enable ? "on" : "off",
           (unsigned long)cfg->temp_cob_id, (unsigned)cfg->temp_stale_cycles);
    printf("thermal %s 0x%03lX..0x%03lX cycle %lu us\n", cfg->thermal_enable ? "on" : "off",
           (unsigned long)cfg->thermal_cob_id, (unsigned long)(cfg->thermal_cob_id + ABBE_CAN_THERMAL_FRAMES - 1u),
           (unsigned long)cfg->cycle_us);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const abbe_can_axis_config_t *a = &cfg->axis[j];
        printf("axis %c node %u: TPDO 0x%03lX dlc %u position@%u statusword@%d -> RPDO 0x%03lX dlc %u offset@%u; "
               "%.6g increments/mm sign %+d temp_c %.2f\n",
               "XYZ"[j], (unsigned)a->node_id, (unsigned long)a->tpdo_cob_id, (unsigned)a->tpdo_dlc,
               (unsigned)a->position_byte, (int)a->statusword_byte, (unsigned long)a->rpdo_cob_id,
               (unsigned)a->rpdo_dlc, (unsigned)a->offset_byte, a->increments_per_mm, (int)a->sign,
               (double)a->temp_mdegc / 1000.0);
    }
}

/* ---- replay ---------------------------------------------------------------- */

static int replay(abbe_can_node_t *node, const char *model_path, const char *in_path, const char *out_path)
{
    FILE *in = fopen(in_path, "r");
    if (in == NULL) {
        logmsg("%s: cannot open: %s", in_path, strerror(errno));
        return EXIT_INPUT;
    }
    char tmp_path[ABBE_CAN_PATH_MAX + 16];
    FILE *out = stdout;
    if (out_path != NULL) {
        snprintf(tmp_path, sizeof tmp_path, "%s.tmp%ld", out_path, (long)getpid());
        out = fopen(tmp_path, "w");
        if (out == NULL) {
            logmsg("%s: cannot create: %s", tmp_path, strerror(errno));
            fclose(in);
            return EXIT_RUNTIME;
        }
    }
    monitor_t mon;
    monitor_init(&mon, 0);
    char line[512];
    unsigned long lineno = 0, frames_in = 0, frames_out = 0, fd_lines = 0;
    int rc = 0;
    while (fgets(line, (int)sizeof line, in) != NULL) {
        lineno++;
        size_t n = strlen(line);
        if (n + 1u == sizeof line && line[n - 1u] != '\n') {
            logmsg("%s:%lu: line too long for a candump -l line", in_path, lineno);
            rc = EXIT_INPUT;
            break;
        }
        const char *p = line;
        while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') {
            p++;
        }
        if (*p == '\0') {
            continue;
        }
        abbe_can_log_entry_t e;
        int st = abbe_can_log_parse(line, &e);
        if (st == ABBE_CAN_E_UNSUPPORTED) {
            if (fd_lines++ == 0u) {
                logmsg("%s:%lu: CAN FD frame skipped (classic CAN only; further ones counted)", in_path, lineno);
            }
            continue;
        }
        if (st != ABBE_CAN_OK) {
            logmsg("%s:%lu: not a candump -l line: expected '(SECONDS.MICROS) IFACE ID#DATA'", in_path, lineno);
            rc = EXIT_INPUT;
            break;
        }
        frames_in++;
        abbe_can_frame_t tx[ABBE_CAN_MAX_TX];
        size_t n_tx = 0;
        (void)abbe_can_node_rx(node, &e.frame, tx, &n_tx);
        monitor(&mon, node);
        for (size_t i = 0; i < n_tx; i++) {
            abbe_can_log_entry_t o = e;
            o.frame = tx[i];
            char buf[128];
            int len = abbe_can_log_format(&o, buf, sizeof buf);
            if (len > 0) {
                fputs(buf, out);
                frames_out++;
            }
        }
        if (abbe_can_node_take_reload_request(node)) {
            (void)reload_model(node, model_path);
        }
    }
    if (rc == 0 && ferror(in)) {
        logmsg("%s: read error", in_path);
        rc = EXIT_RUNTIME;
    }
    fclose(in);
    if (fflush(out) != 0 || (out != stdout && fclose(out) != 0)) {
        logmsg("cannot write the replay output: %s", strerror(errno));
        rc = rc ? rc : EXIT_RUNTIME;
        out = stdout;
    }
    if (out_path != NULL) {
        if (rc == 0 && rename(tmp_path, out_path) != 0) {
            logmsg("%s: cannot rename into place: %s", out_path, strerror(errno));
            rc = EXIT_RUNTIME;
        }
        if (rc != 0) {
            (void)remove(tmp_path);
        }
    }
    if (rc == 0) {
        logmsg("replay: %lu lines, %lu frames in, %lu CAN FD lines skipped, %lu frames out", lineno, frames_in,
               fd_lines, frames_out);
        print_counters(node);
    }
    return rc;
}

/* ---- live -------------------------------------------------------------------- */

static int run_live(abbe_can_node_t *node, int fd, const char *model_path, int ready_fd, int verbose)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    int sigs[] = {SIGHUP, SIGTERM, SIGINT, SIGUSR1};
    sigset_t block, run_mask;
    sigemptyset(&block);
    for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
        sigaction(sigs[i], &sa, NULL);
        sigaddset(&block, sigs[i]);
    }
    signal(SIGPIPE, SIG_IGN);
    /* Signals are only delivered inside pselect(): no race between checking the
     * flags and going to sleep. */
    sigprocmask(SIG_BLOCK, &block, &run_mask);
    for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
        sigdelset(&run_mask, sigs[i]);
    }

    abbe_can_fd_t fdst;
    abbe_can_driver_t drv;
    abbe_can_fd_driver_init(&fdst, fd, &drv);
    monitor_t mon;
    monitor_init(&mon, verbose);

    if (ready_fd >= 0) {
        ssize_t w = write(ready_fd, "ready\n", 6);
        (void)w;
        close(ready_fd);
    }
    logmsg("running: model %s, %s", model_path, "waiting for SYNC");

    int rc = 0, reload = 0;
    while (!g_stop) {
        if (g_reload) {
            g_reload = 0;
            logmsg("SIGHUP: reloading the model");
            reload = 1;
        }
        if (abbe_can_node_take_reload_request(node)) {
            logmsg("RELOAD command: reloading the model");
            reload = 1;
        }
        /* A model already queued takes effect at the next SYNC; the reload
         * waits for that cycle boundary rather than being refused. */
        if (reload && !abbe_can_node_model_pending(node)) {
            (void)reload_model(node, model_path);
            reload = 0;
        }
        if (g_dump) {
            g_dump = 0;
            print_counters(node);
        }
        fd_set rfds;
        FD_ZERO(&rfds);
        FD_SET(fd, &rfds);
        int r = pselect(fd + 1, &rfds, NULL, NULL, NULL, &run_mask);
        if (r < 0) {
            if (errno == EINTR) {
                continue;
            }
            logmsg("pselect: %s", strerror(errno));
            rc = EXIT_RUNTIME;
            break;
        }
        if (r > 0) {
            /* One frame at a time, each followed by the monitor, so that a
             * burst of SYNCs is logged cycle by cycle; at most 64 before the
             * signals are looked at again. */
            int st = 0;
            for (unsigned k = 0; k < 64u; k++) {
                st = abbe_can_node_poll(node, &drv, 1u);
                monitor(&mon, node);
                if (st <= 0 || abbe_can_node_take_reload_request(node)) {
                    if (st > 0) {
                        logmsg("RELOAD command: reloading the model");
                        reload = 1; /* before the next SYNC is handled */
                    }
                    break;
                }
            }
            if (st == ABBE_CAN_E_CLOSED) {
                logmsg("bus closed by the peer");
                break;
            }
            if (st < 0) {
                logmsg("receive failed: %s", strerror(errno));
                rc = EXIT_RUNTIME;
                break;
            }
        }
    }
    if (g_stop) {
        logmsg("stopping on signal");
    }
    print_counters(node);
    return rc;
}

int main(int argc, char **argv)
{
    const char *config_path = NULL, *iface = NULL, *replay_path = NULL, *out_path = NULL;
    int fd = -1, ready_fd = -1, check = 0, verbose = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        int takes = 1;
        if (strcmp(a, "-c") == 0 || strcmp(a, "--config") == 0) {
            config_path = v;
        } else if (strcmp(a, "-i") == 0 || strcmp(a, "--interface") == 0) {
            iface = v;
        } else if (strcmp(a, "--fd") == 0) {
            if (v == NULL || !parse_fd(v, &fd)) {
                logmsg("--fd needs a file descriptor number");
                return EXIT_INPUT;
            }
        } else if (strcmp(a, "--ready-fd") == 0) {
            if (v == NULL || !parse_fd(v, &ready_fd)) {
                logmsg("--ready-fd needs a file descriptor number");
                return EXIT_INPUT;
            }
        } else if (strcmp(a, "--replay") == 0) {
            replay_path = v;
        } else if (strcmp(a, "-o") == 0 || strcmp(a, "--out") == 0) {
            out_path = v;
        } else {
            takes = 0;
            if (strcmp(a, "--check") == 0) {
                check = 1;
            } else if (strcmp(a, "-v") == 0 || strcmp(a, "--verbose") == 0) {
                verbose = 1;
            } else if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
                usage(stdout);
                return 0;
            } else if (strcmp(a, "--version") == 0) {
                printf(PROG " %s (table format %d.%d)\n", ABBE_VERSION_STRING, ABBE_TABLE_FORMAT_MAJOR,
                       ABBE_TABLE_FORMAT_MINOR);
                return 0;
            } else {
                logmsg("unknown option '%s'", a);
                usage(stderr);
                return EXIT_INPUT;
            }
        }
        if (takes) {
            if (v == NULL) {
                logmsg("option '%s' needs a value", a);
                return EXIT_INPUT;
            }
            i++;
        }
    }
    if (config_path == NULL) {
        logmsg("no configuration: use -c CONFIG");
        usage(stderr);
        return EXIT_INPUT;
    }
    if ((fd >= 0) + (replay_path != NULL) + check > 1 || (out_path != NULL && replay_path == NULL)) {
        logmsg("--fd, --replay and --check exclude each other; -o goes with --replay");
        return EXIT_INPUT;
    }

    static abbe_can_config_t cfg;
    abbe_can_config_error_t err;
    if (abbe_can_config_load(&cfg, config_path, &err) != ABBE_CAN_OK) {
        char msg[ABBE_CAN_PATH_MAX + 320];
        abbe_can_config_error_format(&err, msg, sizeof msg);
        fprintf(stderr, "%s\n", msg);
        return EXIT_INPUT;
    }
    if (iface != NULL) {
        if (strlen(iface) == 0u || strlen(iface) >= sizeof cfg.interface) {
            logmsg("interface name '%s' must have 1..15 characters", iface);
            return EXIT_INPUT;
        }
        memcpy(cfg.interface, iface, strlen(iface) + 1u);
    }
    abbe_can_node_t *node = &g_node;
    if (abbe_can_node_init(node, &cfg) != ABBE_CAN_OK) {
        logmsg("configuration rejected"); /* cannot happen: the loader checked it */
        return EXIT_INPUT;
    }
    if (reload_model(node, cfg.model_path) != ABBE_CAN_OK) {
        return EXIT_INPUT;
    }
    if (check) {
        print_map(abbe_can_node_config(node));
        return 0;
    }
    if (replay_path != NULL) {
        return replay(node, cfg.model_path, replay_path, out_path);
    }
    int own_fd = 0;
    if (fd >= 0) {
        if (fd >= FD_SETSIZE) {
            logmsg("--fd %d: must be below %d", fd, FD_SETSIZE);
            return EXIT_INPUT;
        }
        if (abbe_can_fd_nonblock(fd) != ABBE_CAN_OK) {
            logmsg("--fd %d: %s", fd, strerror(errno));
            return EXIT_RUNTIME;
        }
    } else {
        char why[256];
        if (abbe_can_socket_open(cfg.interface, abbe_can_node_config(node), &fd, why, sizeof why) != ABBE_CAN_OK) {
            logmsg("%s", why);
            return EXIT_RUNTIME;
        }
        own_fd = 1;
        logmsg("listening on %s", cfg.interface);
    }
    int rc = run_live(node, fd, cfg.model_path, ready_fd, verbose);
    if (own_fd) {
        close(fd);
    }
    return rc;
}
