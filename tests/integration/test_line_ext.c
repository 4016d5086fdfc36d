/* SPDX-License-Identifier: MIT */
/*
 * The extension seam of a line (lines/line_ext.h) on a real line thread
 * over vcan0: a test extension attached at start-up observes the core's
 * events, takes over a
 * range of mailbox commands, is woken through a cross-line ring
 * (lines/xring.h) fed by another thread, takes what was pushed without
 * waking it before the events of its next wake-up, gets the line to sleep
 * no longer than its own deadline, and is detached at the end.
 */
#include <errno.h>
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>
#include <sys/eventfd.h>
#include <time.h>
#include <unistd.h>

#include "unity.h"

#include "core/co.h"
#include "core/nmt.h"
#include "core/sdo.h"
#include "lines/line.h"
#include "lines/socketcan.h"
#include "lines/xring.h"
#include "mailbox/cogw.h"
#include "mailbox/proto.h"

#define EXT_PERIOD_US 10000u /* the extension's own deadline */
#define HANDOFF_ID 0x123u    /* frames the extension sends per hand-off */

/* Everything the line thread writes and the test reads is atomic. */
static struct {
	atomic_int attached, detached;
	atomic_uint events, nmt_events;
	atomic_uint commands;
	atomic_uint wakes, handoffs, taken_before;
	atomic_uint polls_due;
	uint64_t next_due; /* line thread only */
	xring *inbox;      /* ring from the test thread to the line */
} ext;

static int ext_attach(void *ctx, line *l)
{
	TEST_ASSERT_EQUAL_PTR(&ext, ctx);
	(void)l;
	atomic_store(&ext.attached, 1);
	return 0;
}

static void ext_detach(void *ctx, line *l)
{
	(void)ctx;
	(void)l;
	atomic_store(&ext.detached, 1);
}

static void ext_on_core_event(void *ctx, line *l, const co_event *ev)
{
	(void)ctx;
	(void)l;
	atomic_fetch_add(&ext.events, 1);
	if (ev->kind == CO_EV_NMT_STATE)
		atomic_fetch_add(&ext.nmt_events, 1);
}

/* LINE_STATUS answered by the extension instead of the line: node_id 0x42
 * tells the test who answered, rx_frames how many hand-offs it had taken
 * by then. */
static void ext_on_command(void *ctx, line *l, const mbx_request *req)
{
	(void)ctx;
	mbx_line_status st = { .node_id = 0x42, .rx_frames = atomic_load(&ext.handoffs) };
	atomic_fetch_add(&ext.commands, 1);
	mbx_server_respond(line_mbx(l), &req->reply, 0, 0, &st, sizeof st);
}

/* Each message from the ring goes out as one frame HANDOFF_ID. */
static void take_handoffs(line *l)
{
	uint8_t msg[8];
	int n;
	while ((n = xring_pop(ext.inbox, msg, sizeof msg)) > 0) {
		co_frame f;
		co_frame_init(&f, HANDOFF_ID, (uint8_t)n);
		memcpy(f.data, msg, (size_t)n);
		co_node_send(line_node(l), &f);
		atomic_fetch_add(&ext.handoffs, 1);
	}
}

static void ext_on_wake(void *ctx, line *l)
{
	(void)ctx;
	atomic_fetch_add(&ext.wakes, 1);
	take_handoffs(l);
}

static void ext_before_events(void *ctx, line *l)
{
	(void)ctx;
	if (xring_count(ext.inbox)) {
		atomic_fetch_add(&ext.taken_before, 1);
		take_handoffs(l);
	}
}

static uint64_t ext_poll(void *ctx, line *l, uint64_t now_us)
{
	(void)ctx;
	(void)l;
	if (now_us >= ext.next_due) {
		if (ext.next_due)
			atomic_fetch_add(&ext.polls_due, 1);
		ext.next_due = now_us + EXT_PERIOD_US;
	}
	return ext.next_due;
}

static const line_ext_ops test_ops = {
	.name = "test",
	.attach = ext_attach,
	.detach = ext_detach,
	.on_core_event = ext_on_core_event,
	.cmd_first = MBX_CMD_LINE_STATUS,
	.cmd_last = MBX_CMD_LINE_STATUS,
	.on_command = ext_on_command,
	.on_wake = ext_on_wake,
	.before_events = ext_before_events,
	.poll = ext_poll,
};

static co_od *od;
static line *ln;
static can_port *watch;
static int wakefd = -1;
static char instance[32], qname[MBX_QNAME_MAX];

void setUp(void)
{
	memset(&ext, 0, sizeof ext);
	snprintf(instance, sizeof instance, "ext%d", (int)getpid());
	TEST_ASSERT_EQUAL(0, mbx_queue_name(qname, sizeof qname, instance, 0));
	wakefd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
	TEST_ASSERT_TRUE(wakefd >= 0);
	TEST_ASSERT_EQUAL(0, xring_create(&ext.inbox, 16, 8, wakefd));
	TEST_ASSERT_EQUAL(0, co_od_create(&od, 16));

	can_port_config wc = { .ifname = "vcan0", .bitrate = 1000000, .tx_queue_len = 16 };
	const char *why = NULL;
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, can_port_open(&watch, &wc, &why),
				      why ? why : "watch port");

	line_params p = {
		.index = 0,
		.name = "ext0",
		.can = { .ifname = "vcan0", .bitrate = 1000000 },
		.node = { .node_id = 0x7F, .od = od },
		.mbx = { .queue_name = qname,
			 .unlink_existing = true,
			 .default_access = MBX_ACCESS_WRITE },
		.rt_cpu = -1,
		.main_wakefd = -1,
		.ext = { { .ops = &test_ops, .ctx = &ext, .wake_fd = wakefd } },
	};
	TEST_ASSERT_EQUAL_INT(0, line_create(&ln, &p));
	TEST_ASSERT_EQUAL_INT(1, atomic_load(&ext.attached));
	TEST_ASSERT_EQUAL_INT(0, line_start(ln));
	for (int i = 0; i < 200 && !line_is_up(ln); i++)
		usleep(10000);
	TEST_ASSERT_TRUE(line_is_up(ln));
}

void tearDown(void)
{
	line_destroy(ln);
	TEST_ASSERT_EQUAL_INT(1, atomic_load(&ext.detached));
	can_port_close(watch);
	xring_destroy(ext.inbox);
	co_od_destroy(od);
	close(wakefd);
}

static void test_events_observed(void)
{
	usleep(300000);
	/* The node booted (NMT state change) and the extension saw it. */
	TEST_ASSERT_TRUE(atomic_load(&ext.nmt_events) >= 1);
	TEST_ASSERT_TRUE(atomic_load(&ext.events) >= atomic_load(&ext.nmt_events));
}

static void test_extension_deadline_drives_the_loop(void)
{
	usleep(300000);
	/* 300 ms at a 10 ms deadline; the other timers (the check-in
	 * every 250 ms) wake the line a
	 * handful of times: only the extension's deadline explains this
	 * many due polls. */
	TEST_ASSERT_TRUE_MESSAGE(atomic_load(&ext.polls_due) >= 15, "extension deadline ignored");
}

static void test_command_range_goes_to_the_extension(void)
{
	cogw *h = NULL;
	cogw_options o = { .instance = instance, .timeout_ms = 10000 };
	TEST_ASSERT_EQUAL_INT(0, cogw_open_opts(&h, &o));
	mbx_line_status st;
	memset(&st, 0, sizeof st);
	TEST_ASSERT_EQUAL_INT(0, cogw_line_status(h, 0, &st, 0));
	TEST_ASSERT_EQUAL_UINT8(0x42, st.node_id);
	TEST_ASSERT_EQUAL_UINT(1, atomic_load(&ext.commands));
	/* Commands outside the range stay the line's own. */
	uint8_t v[4];
	size_t got = 0;
	uint32_t abort = 0;
	int rc = cogw_od_read(h, 0, 0x1000, 0, v, sizeof v, &got, 0, &abort);
	TEST_ASSERT_TRUE(rc != 0); /* the line's own answer: this OD is empty */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_NO_OBJ, abort);
	TEST_ASSERT_EQUAL_UINT(1, atomic_load(&ext.commands));
	cogw_close(h);
}

static void test_handoff_through_a_ring_wakes_the_line(void)
{
	/* This thread is the ring's one producer (another line, in cogwd). */
	for (uint8_t i = 0; i < 5; i++) {
		uint8_t m[2] = { 0xA0, i };
		TEST_ASSERT_EQUAL_INT(0, xring_push(ext.inbox, m, sizeof m));
		usleep(20000);
	}
	unsigned seen = 0;
	for (int tries = 0; tries < 100 && seen < 5; tries++) {
		can_rx_item it[8];
		int n = can_port_recv(watch, it, 8, line_now_us());
		for (int i = 0; i < n; i++) {
			if (it[i].is_error || it[i].frame.id != HANDOFF_ID)
				continue;
			TEST_ASSERT_EQUAL_UINT8(2, it[i].frame.len);
			TEST_ASSERT_EQUAL_HEX8(0xA0, it[i].frame.data[0]);
			TEST_ASSERT_EQUAL_UINT8(seen, it[i].frame.data[1]);
			seen++;
		}
		if (n <= 0)
			usleep(10000);
	}
	TEST_ASSERT_EQUAL_UINT(5, seen);
	TEST_ASSERT_EQUAL_UINT(5, atomic_load(&ext.handoffs));
	TEST_ASSERT_TRUE(atomic_load(&ext.wakes) >= 1);
	xring_stats rs;
	xring_stats_get(ext.inbox, &rs);
	TEST_ASSERT_EQUAL_UINT64(5, rs.popped);
	TEST_ASSERT_EQUAL_UINT64(0, rs.dropped);
}

/* Pushed quietly: no wake-up of its own, but taken before the request that
 * wakes the line next is handled (the extension answers it with what it had
 * taken by then). */
static void test_quiet_handoff_is_taken_before_the_next_wake_up(void)
{
	cogw *h = NULL;
	cogw_options o = { .instance = instance, .timeout_ms = 10000 };
	TEST_ASSERT_EQUAL_INT(0, cogw_open_opts(&h, &o));
	usleep(50000);
	unsigned wakes = atomic_load(&ext.wakes);
	for (uint8_t i = 0; i < 3; i++) {
		uint8_t m[2] = { 0xB0, i };
		TEST_ASSERT_EQUAL_INT(0, xring_push_quiet(ext.inbox, m, sizeof m, 8));
	}
	mbx_line_status st;
	memset(&st, 0, sizeof st);
	TEST_ASSERT_EQUAL_INT(0, cogw_line_status(h, 0, &st, 0));
	TEST_ASSERT_EQUAL_UINT8(0x42, st.node_id);
	TEST_ASSERT_EQUAL_UINT64(3, st.rx_frames);
	TEST_ASSERT_EQUAL_UINT(wakes, atomic_load(&ext.wakes)); /* its eventfd never fired */
	TEST_ASSERT_TRUE(atomic_load(&ext.taken_before) >= 1);
	/* the next ordinary push wakes the line, although nothing woke it
	 * for the quiet ones */
	uint8_t m[2] = { 0xB0, 3 };
	TEST_ASSERT_EQUAL_INT(0, xring_push(ext.inbox, m, sizeof m));
	for (int i = 0; i < 100 && atomic_load(&ext.handoffs) < 4; i++)
		usleep(10000);
	TEST_ASSERT_EQUAL_UINT(4, atomic_load(&ext.handoffs));
	cogw_close(h);
}

static int failing_attach(void *ctx, line *l)
{
	(void)ctx;
	(void)l;
	return -ENOMEM;
}

static void test_failing_attach_fails_the_line(void)
{
	static const line_ext_ops bad = { .name = "bad", .attach = failing_attach };
	char q2[MBX_QNAME_MAX];
	TEST_ASSERT_EQUAL(0, mbx_queue_name(q2, sizeof q2, instance, 1));
	line_params p = {
		.index = 1,
		.name = "ext1",
		.can = { .ifname = "vcan1", .bitrate = 1000000 },
		.node = { .node_id = 0x7E, .od = od },
		.mbx = { .queue_name = q2, .unlink_existing = true },
		.rt_cpu = -1,
		.main_wakefd = -1,
		.ext = { { .ops = &bad, .wake_fd = -1 } },
	};
	line *l2 = NULL;
	TEST_ASSERT_EQUAL_INT(-ENOMEM, line_create(&l2, &p));
	TEST_ASSERT_NULL(l2);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_events_observed);
	RUN_TEST(test_extension_deadline_drives_the_loop);
	RUN_TEST(test_command_range_goes_to_the_extension);
	RUN_TEST(test_handoff_through_a_ring_wakes_the_line);
	RUN_TEST(test_quiet_handoff_is_taken_before_the_next_wake_up);
	RUN_TEST(test_failing_attach_fails_the_line);
	return UNITY_END();
}
