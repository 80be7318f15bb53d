/* The real SocketCAN path: abbe_can_socket_open() on a (virtual) CAN
 * interface, a second raw socket as the bus peer, a few cycles through the
 * kernel, and the receive filters (unknown ids never reach the node).
 *
 * Needs a kernel with SocketCAN and an interface that is up:
 *   modprobe vcan && ip link add vcan0 type vcan && ip link set vcan0 up
 * ($ABBE_CAN_TEST_IF names another one). Without them the test prints why and
 * exits 77, which CTest reports as skipped. */
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <net/if.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>
#include <linux/can.h>
#include <linux/can/raw.h>

#include "abbe_can.h"
#include "abbe_can_driver.h"
#include "abbe_can_linux.h"
#include "can_test_util.h"

#define SKIP 77

static const char *ifname;
static int node_fd = -1, peer_fd = -1;
static abbe_can_node_t node;

static int open_peer(const char *name)
{
    int s = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (s < 0) {
        return -1;
    }
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = (int)if_nametoindex(name);
    if (bind(s, (struct sockaddr *)&addr, sizeof addr) < 0) {
        close(s);
        return -1;
    }
    return s;
}

/* Wait up to 1 s for the node's socket, then let it handle what arrived. */
static void pump(void)
{
    abbe_can_fd_t st;
    abbe_can_driver_t drv;
    abbe_can_fd_driver_init(&st, node_fd, &drv);
    fd_set r;
    FD_ZERO(&r);
    FD_SET(node_fd, &r);
    struct timeval tv = {1, 0};
    assert_true(select(node_fd + 1, &r, NULL, NULL, &tv) > 0);
    struct timespec ts = {0, 2000000};
    nanosleep(&ts, NULL); /* let the rest of a burst arrive */
    assert_true(abbe_can_node_poll(&node, &drv, 100u) > 0);
}

static int read_peer(abbe_can_frame_t *f)
{
    fd_set r;
    FD_ZERO(&r);
    FD_SET(peer_fd, &r);
    struct timeval tv = {1, 0};
    if (select(peer_fd + 1, &r, NULL, NULL, &tv) <= 0) {
        return -1;
    }
    return abbe_can_fd_read(peer_fd, f);
}

static void test_cycles_over_socketcan(void **state)
{
    (void)state;
    for (int k = 0; k < 5; k++) {
        abbe_can_frame_t f = ctu_frame(0x555u, 2, NULL); /* not in the filters */
        assert_int_equal(abbe_can_fd_write(peer_fd, &f), ABBE_CAN_OK);
        for (unsigned j = 0; j < 3; j++) {
            f = ctu_i32_frame(0x181u + j, 4, 0, 2000000 + 1000 * k);
            assert_int_equal(abbe_can_fd_write(peer_fd, &f), ABBE_CAN_OK);
        }
        f = ctu_frame(0x080u, 0, NULL);
        assert_int_equal(abbe_can_fd_write(peer_fd, &f), ABBE_CAN_OK);
        pump();
        unsigned got = 0;
        int status = 0;
        while (got != 7u || !status) {
            assert_int_equal(read_peer(&f), ABBE_CAN_OK);
            if (f.id >= 0x201u && f.id <= 0x203u) {
                got |= 1u << (f.id - 0x201u);
            } else if (f.id == 0x1F0u) {
                abbe_can_status_frame_t s;
                assert_int_equal(abbe_can_status_decode(&f, &s), ABBE_CAN_OK);
                assert_int_equal(s.fresh_mask, 7);
                status = 1;
            }
        }
    }
    abbe_can_counters_t c = abbe_can_node_counters(&node);
    assert_int_equal(c.syncs, 5);
    assert_int_equal(c.unknown_id, 0); /* filtered by the kernel */
    assert_int_equal(abbe_can_node_model_crc(&node) != 0, 1);
}

int main(void)
{
    ifname = getenv("ABBE_CAN_TEST_IF");
    if (ifname == NULL || ifname[0] == '\0') {
        ifname = "vcan0";
    }
    abbe_can_config_t cfg;
    abbe_can_config_defaults(&cfg);
    for (unsigned j = 0; j < 3; j++) {
        cfg.axis[j].node_id = (uint8_t)(j + 1u);
        cfg.axis[j].increments_per_mm = 10000.0;
    }
    assert_int_equal(abbe_can_node_init(&node, &cfg), ABBE_CAN_OK);
    char why[512];
    int st = abbe_can_socket_open(ifname, abbe_can_node_config(&node), &node_fd, why, sizeof why);
    if (st == ABBE_CAN_E_UNSUPPORTED) {
        printf("SKIP: %s\n", why);
        return SKIP;
    }
    if (st != ABBE_CAN_OK) {
        printf("SKIP: %s (set ABBE_CAN_TEST_IF to a CAN interface that is up)\n", why);
        return SKIP;
    }
    peer_fd = open_peer(ifname);
    if (peer_fd < 0) {
        printf("SKIP: cannot open a peer socket on %s: %s\n", ifname, strerror(errno));
        close(node_fd);
        return SKIP;
    }
    if (abbe_can_model_load_file(&node, CTU_EXAMPLE_MODEL, why, sizeof why) != ABBE_CAN_OK) {
        printf("%s\n", why);
        return 1;
    }
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_cycles_over_socketcan)};
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    close(peer_fd);
    close(node_fd);
    return rc;
}
