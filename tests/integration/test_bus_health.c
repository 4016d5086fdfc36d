/* SPDX-License-Identifier: MIT */
/*
 * Bus health in the real daemon on vcan (docs/troubleshooting.md):
 *   - a stray heartbeat `77F#05` on the daemon's own node-ID (127), once,
 *     on a line with a manager and on one without: both report the
 *     conflict (COMM_FAULT event, EMCY 8150h on the bus, LINE_HEALTH
 *     counters); the manager goes fatal and, after the quiet time without
 *     another such frame, boots the network again by itself; the EMCY
 *     0000h ends the episode; a second frame is a second episode; the
 *     counters are reset by a client;
 *   - error frames injected on the bus (the kernel delivers an error
 *     frame a socket sends on vcan like a driver's): error passive (EMCY
 *     8120h), bus-off, the driver's restart (EMCY 8140h, then 0000h), a
 *     missing ACK (EMCY 8110h, msef 02);
 *   - a transmit path that cannot deliver: a token bucket of 1 kbit/s on
 *     the interface (tc) while a client sends frames: the transmit queue
 *     fills, frames are dropped (tx-lost, tx-pressure episodes, counters),
 *     and both episodes end once the path is free again.
 * Run: tests/vcan/run -n 2 -- build/san/tests/integration/test_bus_health
 */
#include <linux/can.h>
#include <linux/can/error.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/manager.h"
#include "mailbox/cogw.h"
#include "mailbox/cogw_health.h"
#include "tests/integration/support/daemon.h"
#include "tests/integration/support/proc.h"
#include "unity.h"

#define INSTANCE "healtht"
#define OWN 127
#define EMCY_COB (0x80 + OWN)
#define CONFIG                                                                            \
	"{\"version\": 1, \"mailbox\": {\"instance\": \"" INSTANCE "\"}, \"lines\": ["    \
	"{\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": 127, "             \
	" \"id_conflict_quiet_ms\": 1500, \"fault_quiet_ms\": 400, \"heartbeat_ms\": 0, " \
	" \"manager\": {\"retry_ms\": 500}, \"nodes\": []},"                              \
	"{\"interface\": \"vcan1\", \"bitrate\": 1000000, \"node_id\": 127, "             \
	" \"id_conflict_quiet_ms\": 1500, \"fault_quiet_ms\": 400, \"heartbeat_ms\": 0}]}"

static daemon_run dmn;
static cogw *h;
static int fd0 = -1, fd1 = -1;
/* Every COMM_FAULT event received, counted by line, fault and begin/end,
 * so that a wait finds an event that came while it waited for another. */
static unsigned seen[2][MBX_FAULT_COUNT][2];
static mbx_ev_comm_fault last_seen[2][MBX_FAULT_COUNT][2];

void setUp(void)
{
	memset(&dmn, 0, sizeof dmn);
	memset(seen, 0, sizeof seen);
	h = NULL;
	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn, &(daemon_opts){ .config_json = CONFIG,
								    .instance = INSTANCE,
								    .n_lines = 2 }));
	TEST_ASSERT_EQUAL_INT(0, cogw_open(&h, INSTANCE));
	fd0 = can_open_raw("vcan0");
	fd1 = can_open_raw("vcan1");
	TEST_ASSERT_TRUE(fd0 >= 0 && fd1 >= 0);
}

void tearDown(void)
{
	if (system("tc qdisc del dev vcan1 root 2>/dev/null")) {
		/* none was left: the usual case */
	}
	if (fd0 >= 0)
		close(fd0);
	if (fd1 >= 0)
		close(fd1);
	fd0 = fd1 = -1;
	if (h)
		cogw_close(h);
	daemon_cleanup(&dmn);
	daemon_unlink_queues(INSTANCE);
}

static int wait_mgr_state(uint8_t state, int timeout_ms)
{
	mbx_mgr_status st;
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	for (;;) {
		if (cogw_mgr_status(h, 0, &st, 3000) == 0 && st.state == state)
			return 0;
		if (mono_ms() > until)
			return -1;
		sleep_ms(50);
	}
}

/* Wait until `count` events of `fault` on `line` with `active` came in
 * all; the last one's copy in *out. */
static int wait_fault_n(unsigned line, uint8_t fault, bool active, unsigned count, int timeout_ms,
			mbx_ev_comm_fault *out)
{
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	cogw_msg m;
	for (;;) {
		if (seen[line][fault][active] >= count) {
			*out = last_seen[line][fault][active];
			return 0;
		}
		if (mono_ms() > until)
			return -1;
		if (cogw_recv(h, &m, 100) != 0)
			continue;
		if (m.code == MBX_EV_COMM_FAULT && m.line < 2 && m.len == sizeof *out) {
			mbx_ev_comm_fault e;
			memcpy(&e, m.data, sizeof e);
			if (e.fault < MBX_FAULT_COUNT) {
				seen[m.line][e.fault][e.active ? 1 : 0]++;
				last_seen[m.line][e.fault][e.active ? 1 : 0] = e;
			}
		}
		cogw_msg_release(&m);
	}
}

/* The first such event (each test starts a new daemon: counts from 0). */
static int wait_fault(unsigned line, uint8_t fault, bool active, int timeout_ms,
		      mbx_ev_comm_fault *out)
{
	return wait_fault_n(line, fault, active, 1, timeout_ms, out);
}

/* Wait for our node's EMCY with this code (and msef[0]) on a bus. */
static void expect_emcy(int fd, uint16_t code, uint8_t reg, uint8_t msef0, const char *what)
{
	uint8_t d[8];
	uint64_t until = mono_ms() + 3000;
	while (mono_ms() < until) {
		int n = can_wait_id(fd, EMCY_COB, d, 500);
		if (n == 8 && d[0] == (uint8_t)code && d[1] == (uint8_t)(code >> 8) &&
		    d[2] == reg && d[3] == msef0)
			return;
	}
	TEST_FAIL_MESSAGE(what);
}

/* Run cogwctl with ARGS; its stdout into out. Returns the exit status. */
static int cogwctl(const char *args, char *out, size_t cap)
{
	char cmd[256];
	snprintf(cmd, sizeof cmd, "build/san/bin/cogwctl --instance " INSTANCE " %s", args);
	return run_capture(cmd, out, cap);
}

static void test_stray_frame_on_own_node_id_both_lines_recover(void)
{
	mbx_ev_comm_fault ev;
	mbx_line_health hl;

	TEST_ASSERT_EQUAL_INT(0, wait_mgr_state(CO_MGR_OPERATIONAL, 15000));
	for (unsigned l = 0; l < 2; l++)
		TEST_ASSERT_EQUAL_INT(
			0, cogw_subscribe(h, l, MBX_EVC_CAN | MBX_EVC_MANAGER, NULL, 0, 3000));

	for (unsigned round = 1; round <= 2; round++) {
		uint8_t state = round == 1 ? 0x05 : 0x7F;
		/* one frame, once, on each line */
		TEST_ASSERT_EQUAL_INT(0, can_send_std(fd0, 0x700 + OWN, &state, 1));
		TEST_ASSERT_EQUAL_INT(0, can_send_std(fd1, 0x700 + OWN, &state, 1));
		expect_emcy(fd0, 0x8150, 0x11, state, "no EMCY 8150h on line 0");
		expect_emcy(fd1, 0x8150, 0x11, state, "no EMCY 8150h on line 1");
		TEST_ASSERT_EQUAL_INT(
			0, wait_fault_n(0, MBX_FAULT_ID_COLLISION, true, round, 3000, &ev));
		TEST_ASSERT_EQUAL_UINT32(round, ev.episodes);
		TEST_ASSERT_EQUAL_HEX8(state, ev.info);
		TEST_ASSERT_EQUAL_INT(0, wait_mgr_state(CO_MGR_FATAL, 3000));
		TEST_ASSERT_EQUAL_INT(0, cogw_line_health(h, 1, &hl, 3000));
		TEST_ASSERT_EQUAL_UINT8(1, hl.fault[MBX_FAULT_ID_COLLISION].active);
		TEST_ASSERT_EQUAL_UINT32(round, hl.fault[MBX_FAULT_ID_COLLISION].episodes);

		/* silence for the quiet time: over by itself, on both lines */
		TEST_ASSERT_EQUAL_INT(
			0, wait_fault_n(1, MBX_FAULT_ID_COLLISION, false, round, 5000, &ev));
		expect_emcy(fd1, 0x0000, 0x00, 0, "no EMCY 0000h on line 1");
		TEST_ASSERT_EQUAL_INT(0, wait_mgr_state(CO_MGR_OPERATIONAL, 10000));
		TEST_ASSERT_EQUAL_INT(0, cogw_line_health(h, 0, &hl, 3000));
		TEST_ASSERT_EQUAL_UINT8(0, hl.fault[MBX_FAULT_ID_COLLISION].active);
		TEST_ASSERT_EQUAL_UINT32(round, hl.fault[MBX_FAULT_ID_COLLISION].occurrences);
	}
	/* the manager counted both conflicts */
	mbx_mgr_status st;
	TEST_ASSERT_EQUAL_INT(0, cogw_mgr_status(h, 0, &st, 3000));
	TEST_ASSERT_EQUAL_UINT32(2, st.duplicates);
	/* the CLI shows them, a client resets them */
	static char out[16384];
	TEST_ASSERT_EQUAL_INT(0, cogwctl("health 0 --json", out, sizeof out));
	TEST_ASSERT_NOT_NULL_MESSAGE(
		strstr(out, "\"id-collision\":{\"active\":false,\"episodes\":2,\"occurrences\":2"),
		out);
	TEST_ASSERT_EQUAL_INT(0, cogwctl("status 1", out, sizeof out));
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(out, "health: no fault; 2 fault episodes counted"),
				     out);
	TEST_ASSERT_EQUAL_INT(0, cogwctl("health 0 reset", out, sizeof out));
	TEST_ASSERT_EQUAL_INT(0, cogw_line_health(h, 0, &hl, 3000));
	TEST_ASSERT_EQUAL_UINT32(0, hl.fault[MBX_FAULT_ID_COLLISION].episodes);
	TEST_ASSERT_EQUAL_UINT32(0, hl.fault[MBX_FAULT_ID_COLLISION].occurrences);
}

static void send_error_frame(int fd, uint32_t cls, uint8_t ctrl)
{
	struct can_frame f;
	memset(&f, 0, sizeof f);
	f.can_id = CAN_ERR_FLAG | cls;
	f.can_dlc = CAN_ERR_DLC;
	f.data[1] = ctrl;
	f.data[6] = 130; /* transmit error counter (CAN_ERR_CNT) */
	f.data[7] = 12;
	TEST_ASSERT_EQUAL_INT((int)sizeof f, (int)write(fd, &f, sizeof f));
}

static void test_injected_error_frames(void)
{
	mbx_ev_comm_fault ev;
	mbx_line_health hl;

	TEST_ASSERT_EQUAL_INT(0, cogw_subscribe(h, 1, MBX_EVC_CAN, NULL, 0, 3000));
	/* error passive: EMCY 8120h */
	send_error_frame(fd1, CAN_ERR_CRTL | CAN_ERR_CNT, CAN_ERR_CRTL_TX_PASSIVE);
	TEST_ASSERT_EQUAL_INT(0, wait_fault(1, MBX_FAULT_PASSIVE, true, 3000, &ev));
	TEST_ASSERT_EQUAL_UINT8(MBX_CAN_PASSIVE, ev.can_state);
	expect_emcy(fd1, 0x8120, 0x11, 0, "no EMCY 8120h");
	/* bus-off, then the driver's restart: 8140h, then the error reset */
	send_error_frame(fd1, CAN_ERR_BUSOFF, 0);
	TEST_ASSERT_EQUAL_INT(0, wait_fault(1, MBX_FAULT_BUS_OFF, true, 3000, &ev));
	send_error_frame(fd1, CAN_ERR_RESTARTED, 0);
	TEST_ASSERT_EQUAL_INT(0, wait_fault(1, MBX_FAULT_BUS_OFF, false, 3000, &ev));
	expect_emcy(fd1, 0x8140, 0x11, 0, "no EMCY 8140h");
	expect_emcy(fd1, 0x0000, 0x00, 0, "no EMCY 0000h after the restart");
	TEST_ASSERT_EQUAL_INT(0, cogw_line_health(h, 1, &hl, 3000));
	TEST_ASSERT_EQUAL_UINT8(MBX_CAN_ACTIVE, hl.can_state);
	TEST_ASSERT_EQUAL_UINT32(1, hl.restarts);
	TEST_ASSERT_EQUAL_UINT32(1, hl.fault[MBX_FAULT_BUS_OFF].episodes);
	TEST_ASSERT_EQUAL_UINT32(1, hl.fault[MBX_FAULT_PASSIVE].episodes);
	TEST_ASSERT_EQUAL_UINT8(0, hl.fault[MBX_FAULT_PASSIVE].active);
	TEST_ASSERT_EQUAL_UINT8(130, hl.tec);
	/* frames nobody acknowledges: 8110h (msef 02), over after 400 ms */
	for (unsigned i = 0; i < 5; i++)
		send_error_frame(fd1, CAN_ERR_ACK, 0);
	TEST_ASSERT_EQUAL_INT(0, wait_fault(1, MBX_FAULT_TX_LOST, true, 3000, &ev));
	expect_emcy(fd1, 0x8110, 0x11, 2, "no EMCY 8110h");
	TEST_ASSERT_EQUAL_INT(0, wait_fault(1, MBX_FAULT_TX_LOST, false, 3000, &ev));
	TEST_ASSERT_EQUAL_UINT32(5, ev.occurrences);
	/* line 0 saw none of it */
	TEST_ASSERT_EQUAL_INT(0, cogw_line_health(h, 0, &hl, 3000));
	for (unsigned i = 0; i < MBX_FAULT_COUNT; i++)
		TEST_ASSERT_EQUAL_UINT32(0, hl.fault[i].episodes);
}

static void test_transmit_path_that_cannot_deliver(void)
{
	mbx_ev_comm_fault ev;
	mbx_line_health hl;
	mbx_raw_frame fr[MBX_RAW_SEND_MAX];

	TEST_ASSERT_EQUAL_INT(0, cogw_subscribe(h, 1, MBX_EVC_CAN, NULL, 0, 3000));
	TEST_ASSERT_EQUAL_INT(
		0, system("tc qdisc add dev vcan1 root tbf rate 1kbit burst 16 limit 16"));
	memset(fr, 0, sizeof fr);
	for (unsigned i = 0; i < MBX_RAW_SEND_MAX; i++) {
		fr[i].id = 0x300 + i;
		fr[i].len = 8;
	}
	/* 20 x 32 frames: more than the port's queue (256) and the qdisc */
	unsigned refused = 0;
	for (unsigned r = 0; r < 20; r++)
		if (cogw_raw_send(h, 1, fr, MBX_RAW_SEND_MAX, 3000) != 0)
			refused++;
	TEST_ASSERT_EQUAL_INT(0, wait_fault(1, MBX_FAULT_TX_PRESSURE, true, 5000, &ev));
	TEST_ASSERT_EQUAL_INT(0, cogw_line_health(h, 1, &hl, 3000));
	TEST_ASSERT_TRUE(hl.fault[MBX_FAULT_TX_LOST].episodes >= 1);
	TEST_ASSERT_TRUE(hl.tx_dropped > 0);
	TEST_ASSERT_TRUE(refused > 0); /* RAW_SEND says BUSY when a frame was refused */
	printf("transmit path blocked: %u of 20 RAW_SEND refused, %llu frames dropped, queue "
	       "high-water %llu\n",
	       refused, (unsigned long long)hl.tx_dropped, (unsigned long long)hl.tx_queued_max);
	/* the path is free again: the queue drains, both episodes end */
	TEST_ASSERT_EQUAL_INT(0, system("tc qdisc del dev vcan1 root"));
	TEST_ASSERT_EQUAL_INT(0, wait_fault(1, MBX_FAULT_TX_PRESSURE, false, 10000, &ev));
	TEST_ASSERT_EQUAL_INT(0, wait_fault(1, MBX_FAULT_TX_LOST, false, 10000, &ev));
	TEST_ASSERT_EQUAL_INT(0, cogw_line_health(h, 1, &hl, 3000));
	TEST_ASSERT_FALSE(hl.fault[MBX_FAULT_TX_LOST].active);
	TEST_ASSERT_EQUAL_UINT32(1, hl.fault[MBX_FAULT_TX_PRESSURE].episodes);
	/* and the line carries frames again */
	TEST_ASSERT_EQUAL_INT(0, cogw_raw_send(h, 1, fr, 1, 3000));
	uint8_t d[8];
	TEST_ASSERT_EQUAL_INT(8, can_wait_id(fd1, 0x300, d, 3000));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_stray_frame_on_own_node_id_both_lines_recover);
	RUN_TEST(test_injected_error_frames);
	RUN_TEST(test_transmit_path_that_cannot_deliver);
	return UNITY_END();
}
