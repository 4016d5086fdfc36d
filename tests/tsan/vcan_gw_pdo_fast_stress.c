/* SPDX-License-Identifier: MIT */
/*
 * PDO forwarding's fast path under ThreadSanitizer (build/tsan), on real
 * line threads over vcan (run in the VM with the integration tests): the
 * real lines/ (the port's filter of the fast TPDOs), gateway/ (gw_pdo.c's
 * forwarding, fast_tpdo.c's gate, the rings) and core/ (the TPDO gate).
 *
 * Two gateway lines: line 0 on vcan0 with an RPDO (181h) mapping B000h,
 * line 1 on vcan1 with an event-driven TPDO (1FFh) mapping it. An injector
 * thread sends RPDOs with increasing values on vcan0 (paced, with bursts of
 * 8); a receiver thread reads the TPDOs on vcan1; meanwhile the
 * main thread reconfigures line 1's TPDO through the mailbox (invalid,
 * inhibit time 0 or 1 ms, valid again) and stops and starts line 1's node
 * by NMT, so that line 1 republishes, closes and reopens the gate while
 * line 0 sends through it.
 * Checked:
 * - no data race (TSan fails the run on one): line 0 reads only what line 1
 *   published, line 1's core is touched by line 1 alone;
 * - the TPDOs on vcan1 carry increasing values (no value older than one
 *   sent before it), and once the injection and the toggling end, the
 *   last value arrives;
 * - line 0 sent some of line 1's TPDOs itself, and line 1 some itself.
 */
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "unity.h"

#include "core/co.h"
#include "core/nmt.h"
#include "core/od.h"
#include "core/pdo.h"
#include "gateway/gateway.h"
#include "lines/line.h"
#include "mailbox/cogw.h"
#include "mailbox/proto.h"

#define LINES 2u
#define INJECT 4000u /* one every ~0.5 ms, bursts of 8 in between */
#define TOGGLES 400u

static const char *const ifname[LINES] = { "vcan0", "vcan1" };

static gw *g;
static line *lines[LINES];
static co_od *od[LINES];
static char instance[32];
static atomic_bool injecting;
static atomic_uint received, out_of_order;
static atomic_uint last_seen;

void setUp(void) {}

static void stop_all(void)
{
	for (unsigned i = 0; i < LINES; i++) {
		line_destroy(lines[i]);
		lines[i] = NULL;
	}
	gw_destroy(g);
	g = NULL;
	for (unsigned i = 0; i < LINES; i++) {
		if (od[i])
			co_od_destroy(od[i]);
		od[i] = NULL;
	}
}

void tearDown(void)
{
	stop_all();
}

static int raw_socket(const char *ifn)
{
	struct sockaddr_can a = { .can_family = AF_CAN, .can_ifindex = (int)if_nametoindex(ifn) };
	int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);

	TEST_ASSERT_TRUE(fd >= 0);
	TEST_ASSERT_EQUAL(0, bind(fd, (struct sockaddr *)&a, sizeof a));
	return fd;
}

static int send_frame(int fd, uint32_t id, const uint8_t *d, uint8_t len)
{
	struct can_frame f = { .can_id = id, .len = len };

	memcpy(f.data, d, len);
	return write(fd, &f, sizeof f) == (ssize_t)sizeof f ? 0 : -1;
}

static void nmt(int fd, uint8_t cs)
{
	uint8_t d[2] = { cs, 127 };

	TEST_ASSERT_EQUAL(0, send_frame(fd, 0x000, d, 2));
}

static co_od *make_od(bool rpdo)
{
	const uint32_t map[] = { CO_PDO_MAP(0xB000, 0, 32) };
	co_pdo_desc d = { .dir = rpdo ? CO_PDO_RX : CO_PDO_TX,
			  .nr = 1,
			  .cob_id = rpdo ? 0x181u : 0x1FFu,
			  .tt = 255,
			  .n_map = 1,
			  .map = map };
	co_od *o;

	TEST_ASSERT_EQUAL(0, co_od_create(&o, 64));
	TEST_ASSERT_EQUAL(0, co_od_add_num(o, 0xB000, 0, CO_T_UNSIGNED32,
					   CO_ACC_RW | CO_ACC_RPDO | CO_ACC_TPDO, 0, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_pdo(o, &d));
	return o;
}

static void start_all(void)
{
	static char qname[LINES][MBX_QNAME_MAX];
	gw_params gp = { .n_lines = LINES };

	snprintf(instance, sizeof instance, "gwpf%d", (int)getpid());
	for (unsigned i = 0; i < LINES; i++) {
		od[i] = make_od(i == 0);
		gp.line[i].network_id = (uint16_t)(i + 1);
	}
	gp.image_od = od[0];
	TEST_ASSERT_EQUAL_INT(0, gw_create(&g, &gp));
	/* all lines created (attached) before any starts, as cogwd does */
	for (unsigned i = 0; i < LINES; i++) {
		char name[8];
		line_ext x;
		snprintf(name, sizeof name, "pf%u", i);
		TEST_ASSERT_EQUAL(0, mbx_queue_name(qname[i], MBX_QNAME_MAX, instance, (uint8_t)i));
		gw_line_ext(g, i, &x);
		line_params p = {
			.index = (uint8_t)i,
			.name = name,
			.network_id = (uint16_t)(i + 1),
			.can = { .ifname = ifname[i], .bitrate = 1000000 },
			.node = { .node_id = 127, .od = od[i] },
			.mbx = { .queue_name = qname[i],
				 .unlink_existing = true,
				 .default_access = MBX_ACCESS_WRITE },
			.rt_cpu = -1,
			.main_wakefd = -1,
		};
		p.ext[0] = x;
		TEST_ASSERT_EQUAL_INT(0, line_create(&lines[i], &p));
	}
	for (unsigned i = 0; i < LINES; i++) {
		TEST_ASSERT_EQUAL_INT(0, line_start(lines[i]));
		for (int k = 0; k < 500 && !line_is_up(lines[i]); k++)
			usleep(10000);
		TEST_ASSERT_TRUE(line_is_up(lines[i]));
	}
}

static void *inject(void *arg)
{
	int fd = *(int *)arg;

	for (uint32_t v = 1; v <= INJECT; v++) {
		uint8_t d[4] = { (uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), 0 };
		while (send_frame(fd, 0x181, d, 4) != 0)
			usleep(200);
		if (v % 8 != 0)
			usleep(500);
	}
	atomic_store(&injecting, false);
	return NULL;
}

static void *receive(void *arg)
{
	int fd = *(int *)arg;
	uint32_t prev = 0;

	for (;;) {
		struct pollfd p = { .fd = fd, .events = POLLIN };
		struct can_frame f;
		uint32_t v;

		if (poll(&p, 1, 3000) <= 0)
			break; /* quiet for 3 s after the end */
		if (read(fd, &f, sizeof f) != (ssize_t)sizeof f || f.can_id != 0x1FF || f.len != 4)
			continue;
		v = (uint32_t)f.data[0] | (uint32_t)f.data[1] << 8 | (uint32_t)f.data[2] << 16;
		/* a repeat of the newest value is allowed (an inhibit time's
		 * end sends the latest), an older one is not */
		if (v < prev && atomic_fetch_add(&out_of_order, 1) < 4)
			fprintf(stderr, "vcan_gw_pdo_fast_stress: %u after %u\n", v, prev);
		prev = v > prev ? v : prev;
		atomic_store(&last_seen, prev);
		atomic_fetch_add(&received, 1);
		if (prev == INJECT && !atomic_load(&injecting))
			break;
	}
	return NULL;
}

static void tpdo_config(cogw *h, uint32_t cob, uint16_t inhibit_100us)
{
	uint8_t c[4] = { (uint8_t)cob, (uint8_t)(cob >> 8), (uint8_t)(cob >> 16),
			 (uint8_t)(cob >> 24) };
	uint8_t i[2] = { (uint8_t)inhibit_100us, (uint8_t)(inhibit_100us >> 8) };
	uint32_t abort = 0;

	TEST_ASSERT_EQUAL_INT(0, cogw_od_write(h, 1, 0x1800, 1, c, 4, 20000, &abort));
	if (cob & CO_PDO_COB_INVALID)
		TEST_ASSERT_EQUAL_INT(0, cogw_od_write(h, 1, 0x1800, 3, i, 2, 20000, &abort));
}

static void test_fast_path_while_line_1_reconfigures(void)
{
	int tx0, tx1, rx1;
	pthread_t inj, rcv;
	cogw *h = NULL;
	cogw_options o = { .timeout_ms = 20000 };
	gw_line_counters c0, c1;
	char msg[160];

	start_all();
	o.instance = instance;
	TEST_ASSERT_EQUAL_INT(0, cogw_open_opts(&h, &o));
	tx0 = raw_socket("vcan0");
	tx1 = raw_socket("vcan1");
	rx1 = raw_socket("vcan1");
	nmt(tx0, CO_NMT_CS_START);
	nmt(tx1, CO_NMT_CS_START);
	usleep(200000);
	atomic_store(&injecting, true);
	pthread_create(&rcv, NULL, receive, &rx1);
	pthread_create(&inj, NULL, inject, &tx0);
	for (unsigned t = 0; t < TOGGLES && atomic_load(&injecting); t++) {
		usleep(20000);
		if (t % 4 == 3) {
			nmt(tx1, CO_NMT_CS_STOP);
			usleep(10000);
			nmt(tx1, CO_NMT_CS_START);
			continue;
		}
		tpdo_config(h, 0x800001FFu, (t & 1) ? 10 : 0);
		tpdo_config(h, 0x1FFu, 0);
	}
	pthread_join(inj, NULL);
	/* the last value once more, now that nothing moves: it must arrive */
	{
		uint8_t d[4] = { (uint8_t)INJECT, (uint8_t)(INJECT >> 8), (uint8_t)(INJECT >> 16),
				 0 };
		usleep(100000);
		TEST_ASSERT_EQUAL(0, send_frame(tx0, 0x181, d, 4));
	}
	pthread_join(rcv, NULL);
	gw_line_counters_get(g, 0, &c0);
	gw_line_counters_get(g, 1, &c1);
	snprintf(msg, sizeof msg,
		 "%u TPDOs received (%u older than one before), last %u; line 0 published %llu, "
		 "forwarded %llu, dropped %llu, sent %llu itself; line 1 applied %llu",
		 atomic_load(&received), atomic_load(&out_of_order), atomic_load(&last_seen),
		 (unsigned long long)c0.pdo_published, (unsigned long long)c0.pdo_forwarded,
		 (unsigned long long)c0.pdo_dropped, (unsigned long long)c0.pdo_fast,
		 (unsigned long long)c1.pdo_applied);
	TEST_MESSAGE(msg);
	TEST_ASSERT_EQUAL_UINT_MESSAGE(0, atomic_load(&out_of_order),
				       "a TPDO carried a value older than one before it");
	TEST_ASSERT_EQUAL_UINT_MESSAGE(INJECT, atomic_load(&last_seen),
				       "the last value never came");
	TEST_ASSERT_TRUE_MESSAGE(c0.pdo_fast > 0, "line 0 never sent line 1's TPDO itself");
	TEST_ASSERT_TRUE_MESSAGE(atomic_load(&received) > c0.pdo_fast,
				 "line 1 never sent its TPDO itself");
	cogw_close(h);
	close(tx0);
	close(tx1);
	close(rx1);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_fast_path_while_line_1_reconfigures);
	return UNITY_END();
}
