/* can_bench: the bus side of abbe-cand for latency and soak runs.
 *
 *   can_bench [--seconds S | --cycles N] [--rate HZ] [--warmup N] -- CMD [ARGS...]
 *
 * Runs CMD (abbe-cand, possibly under valgrind) with one end of a
 * socketpair(AF_UNIX, SOCK_SEQPACKET) as fd 3 and a ready pipe as fd 4,
 * appending "--fd 3 --ready-fd 4" to its arguments. Then, per cycle, it sends
 * the three drives' position TPDOs (a circle in XY, default frame map: nodes
 * 1, 2, 3) and a SYNC, and reads the three offset RPDOs and the status frame.
 *
 * Reported: cycles, missed cycles (no complete answer within 1 s), status
 * sequence gaps, overruns (a cycle started more than one period late),
 * SYNC-to-last-offset latency (median, p99, max, excluding the warm-up), the
 * daemon's VmRSS after the warm-up and at the end, VmHWM, and its exit status.
 * Exit 0 if no cycle was missed, the sequence had no gap and the daemon
 * exited 0; timing never fails the run.
 */
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "abbe_can.h"
#include "abbe_can_linux.h"

#define SYNC_ID 0x080u
#define STATUS_ID 0x1F0u
#define INCR_PER_MM 10000.0
#define PI 3.14159265358979323846

static uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static long rss_kb(pid_t pid, const char *key)
{
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%ld/status", (long)pid);
    FILE *fp = fopen(path, "r");
    long v = -1;
    if (fp == NULL) {
        return -1;
    }
    size_t klen = strlen(key);
    while (fgets(line, sizeof line, fp) != NULL) {
        if (strncmp(line, key, klen) == 0 && line[klen] == ':') {
            v = strtol(line + klen + 1, NULL, 10);
            break;
        }
    }
    fclose(fp);
    return v;
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : (x > y ? 1 : 0);
}

static int send_frame(int fd, uint32_t id, uint8_t dlc, const uint8_t *data)
{
    abbe_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.dlc = dlc;
    if (dlc > 0u) {
        memcpy(f.data, data, dlc);
    }
    return abbe_can_fd_write(fd, &f);
}

/* Read until the 3 offsets and the status frame of this cycle arrived.
 * *t_last: time the last offset was read. 0 ok, -1 timeout, -2 closed. */
static int read_answer(int fd, uint64_t *t_last, uint8_t *seq)
{
    unsigned got = 0;
    int status = 0;
    uint64_t deadline = now_ns() + 1000000000u;
    while (got != 0x7u || !status) {
        abbe_can_frame_t f;
        int st = abbe_can_fd_read(fd, &f);
        if (st == ABBE_CAN_E_AGAIN) {
            uint64_t t = now_ns();
            if (t >= deadline) {
                return -1;
            }
            struct pollfd p = {fd, POLLIN, 0};
            (void)poll(&p, 1, (int)((deadline - t) / 1000000u) + 1);
            continue;
        }
        if (st != ABBE_CAN_OK) {
            return -2;
        }
        if (f.id >= 0x201u && f.id <= 0x203u) {
            got |= 1u << (f.id - 0x201u);
            if (got == 0x7u) {
                *t_last = now_ns();
            }
        } else if (f.id == STATUS_ID && f.dlc == 8u) {
            *seq = f.data[3];
            status = 1;
        }
    }
    return 0;
}

int main(int argc, char **argv)
{
    double seconds = 5.0, rate = 1000.0;
    long cycles = -1, warmup = 100;
    int cmd = -1;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--") == 0) {
            cmd = i + 1;
            break;
        }
        if (i + 1 >= argc) {
            fprintf(stderr, "can_bench: option %s needs a value\n", argv[i]);
            return 2;
        }
        if (strcmp(argv[i], "--seconds") == 0) {
            seconds = atof(argv[++i]);
        } else if (strcmp(argv[i], "--cycles") == 0) {
            cycles = atol(argv[++i]);
        } else if (strcmp(argv[i], "--rate") == 0) {
            rate = atof(argv[++i]);
        } else if (strcmp(argv[i], "--warmup") == 0) {
            warmup = atol(argv[++i]);
        } else {
            fprintf(stderr, "can_bench: unknown option %s\n", argv[i]);
            return 2;
        }
    }
    if (cmd < 0 || cmd >= argc) {
        fprintf(stderr, "usage: can_bench [--seconds S | --cycles N] [--rate HZ] [--warmup N] -- CMD [ARGS...]\n");
        return 2;
    }
    if (cycles < 0) {
        cycles = (long)(seconds * (rate > 0.0 ? rate : 1000.0));
    }
    if (cycles <= warmup) {
        warmup = 0;
    }

    int sv[2], ready[2];
    if (socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv) != 0 || pipe(ready) != 0) {
        perror("can_bench: socketpair/pipe");
        return 1;
    }
    signal(SIGPIPE, SIG_IGN);
    pid_t pid = fork();
    if (pid < 0) {
        perror("can_bench: fork");
        return 1;
    }
    if (pid == 0) {
        close(sv[0]);
        close(ready[0]);
        if (dup2(sv[1], 3) < 0 || dup2(ready[1], 4) < 0) {
            _exit(127);
        }
        if (sv[1] != 3 && sv[1] != 4) {
            close(sv[1]);
        }
        if (ready[1] != 3 && ready[1] != 4) {
            close(ready[1]);
        }
        int n = argc - cmd;
        char **args = calloc((size_t)n + 5u, sizeof *args);
        if (args == NULL) {
            _exit(127);
        }
        for (int i = 0; i < n; i++) {
            args[i] = argv[cmd + i];
        }
        args[n] = (char *)"--fd";
        args[n + 1] = (char *)"3";
        args[n + 2] = (char *)"--ready-fd";
        args[n + 3] = (char *)"4";
        execvp(args[0], args);
        perror("can_bench: exec");
        _exit(127);
    }
    close(sv[1]);
    close(ready[1]);
    int fd = sv[0];
    char rbuf[16];
    struct pollfd rp = {ready[0], POLLIN, 0};
    if (poll(&rp, 1, 60000) <= 0 || read(ready[0], rbuf, sizeof rbuf) <= 0) {
        fprintf(stderr, "can_bench: the daemon did not signal ready\n");
        kill(pid, SIGTERM);
        waitpid(pid, NULL, 0);
        return 1;
    }
    close(ready[0]);
    if (abbe_can_fd_nonblock(fd) != ABBE_CAN_OK) {
        perror("can_bench: nonblock");
        return 1;
    }

    uint32_t *lat = malloc(sizeof *lat * (size_t)cycles);
    if (lat == NULL) {
        return 1;
    }
    long n_lat = 0, missed = 0, gaps = 0, overruns = 0, done = 0;
    long rss_start = -1;
    int have_seq = 0;
    uint8_t last_seq = 0;
    uint64_t period = rate > 0.0 ? (uint64_t)(1e9 / rate) : 0u;
    uint64_t t_start = now_ns(), next = t_start;
    const long per_rev = 4000; /* 4 s per revolution at 1 kHz */
    for (long k = 0; k < cycles; k++) {
        if (period > 0u) {
            next += period;
            uint64_t t = now_ns();
            if (t > next + period) {
                overruns++;
                next = t; /* do not try to catch up: that would burst */
            } else if (t < next) {
                struct timespec ts = {(time_t)(next / 1000000000u), (long)(next % 1000000000u)};
                while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR) {
                }
            }
        }
        double a = 2.0 * PI * (double)(k % per_rev) / (double)per_rev;
        double pos_mm[3] = {250.0 + 100.0 * cos(a), -200.0 + 100.0 * sin(a), -150.0};
        for (unsigned j = 0; j < 3; j++) {
            uint8_t d[4];
            abbe_can_put_i32(d, (int32_t)lround(pos_mm[j] * INCR_PER_MM));
            if (send_frame(fd, 0x181u + j, 4u, d) != ABBE_CAN_OK) {
                fprintf(stderr, "can_bench: send failed at cycle %ld\n", k);
                goto out;
            }
        }
        uint64_t t0 = now_ns(), t1 = 0;
        if (send_frame(fd, SYNC_ID, 0u, NULL) != ABBE_CAN_OK) {
            fprintf(stderr, "can_bench: send failed at cycle %ld\n", k);
            goto out;
        }
        uint8_t seq = 0;
        int st = read_answer(fd, &t1, &seq);
        if (st == -2) {
            fprintf(stderr, "can_bench: daemon closed the bus at cycle %ld\n", k);
            goto out;
        }
        done++;
        if (st == -1) {
            missed++;
            have_seq = 0;
            continue;
        }
        if (have_seq && seq != (uint8_t)(last_seq + 1u)) {
            gaps++;
        }
        last_seq = seq;
        have_seq = 1;
        if (k >= warmup) {
            lat[n_lat++] = (uint32_t)(t1 - t0);
        }
        if (k == warmup) {
            rss_start = rss_kb(pid, "VmRSS");
        }
    }
out:;
    double elapsed = (double)(now_ns() - t_start) / 1e9;
    long rss_end = rss_kb(pid, "VmRSS"), hwm = rss_kb(pid, "VmHWM");
    close(fd);
    int wst = 0;
    waitpid(pid, &wst, 0);
    int child = WIFEXITED(wst) ? WEXITSTATUS(wst) : 128 + (WIFSIGNALED(wst) ? WTERMSIG(wst) : 0);
    qsort(lat, (size_t)n_lat, sizeof *lat, cmp_u32);
    double med = n_lat ? lat[n_lat / 2] / 1e3 : 0.0;
    double p99 = n_lat ? lat[(n_lat * 99) / 100] / 1e3 : 0.0;
    double mx = n_lat ? lat[n_lat - 1] / 1e3 : 0.0;
    printf("cycles %ld of %ld in %.1f s (rate %s), missed %ld, status seq gaps %ld, overruns %ld\n", done, cycles,
           elapsed, rate > 0.0 ? "paced" : "back-to-back", missed, gaps, overruns);
    printf("latency SYNC->last offset (us, %ld samples): median %.1f p99 %.1f max %.1f\n", n_lat, med, p99, mx);
    printf("daemon VmRSS after warm-up %ld kB, at end %ld kB, VmHWM %ld kB; exit status %d\n", rss_start, rss_end,
           hwm, child);
    free(lat);
    return (missed == 0 && gaps == 0 && done == cycles && child == 0) ? 0 : 1;
}
