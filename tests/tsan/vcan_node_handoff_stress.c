/* SPDX-License-Identifier: MIT */
/*
 * A reload's node changes handed to a real line thread under
 * ThreadSanitizer (build/tsan), on vcan0 (run in the VM with the
 * integration tests): lines/line_nodes.c's hand-off (line_request_node,
 * line_request_consumer: one slot, an atomic state, the main thread
 * waiting for the line's answer) while the line thread is kept busy by
 * mailbox clients reading the very 1016h entries the changes write.
 *
 * The line's extension stands for the manager: its node_set op keeps what
 * it was given in state only the line thread touches (its poll reads it
 * too) and writes the node's 1016h entry (line_consumer_set) from the
 * heartbeat time and the first byte of the concise DCF, which the main
 * thread overwrites right after each call returns.
 * Checked:
 * - no data race (TSan fails the run on one);
 * - every change was applied exactly once, in order, and its answer is the
 *   extension's (odd nodes refused with -EBUSY, counted on both sides);
 * - the 1016h entries read back over the mailbox at the end are the last
 *   ones written, for changes and plain heartbeat consumers alike;
 * - a line without an extension that keeps a network list answers
 *   -EOPNOTSUPP.
 */
#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "unity.h"

#include "core/co.h"
#include "core/heartbeat.h"
#include "core/od.h"
#include "lines/line.h"
#include "mailbox/cogw.h"
#include "mailbox/proto.h"

#define NODES 100u
#define CHANGES 3000u
#define READERS 2u

static line *l;
static co_od *od;
static char instance[32], qname[MBX_QNAME_MAX];
static atomic_bool stop_readers;
static atomic_uint reads_ok, reads_failed;

/* The extension's state: the line thread's alone (read after line_destroy,
 * which joins it). */
static struct {
	unsigned applied, refused, polls;
	uint16_t hb[128];
	uint8_t first_byte[128];
	unsigned order_errors;
	unsigned last_seq;
} ext;

static int ext_node_set(void *ctx, line *ln, const line_node_set *set)
{
	unsigned seq = set->req.identity[0];
	(void)ctx;
	if (seq != ext.last_seq + 1)
		ext.order_errors++;
	ext.last_seq = seq;
	if (set->req.node % 2) {
		ext.refused++;
		return -EBUSY;
	}
	ext.applied++;
	ext.hb[set->req.node] = set->req.heartbeat_ms;
	ext.first_byte[set->req.node] = set->cdcf_len ? set->cdcf[0] : 0;
	return line_consumer_set(ln, set->req.node, set->req.heartbeat_ms);
}

static uint64_t ext_poll(void *ctx, line *ln, uint64_t now_us)
{
	(void)ctx;
	(void)ln;
	(void)now_us;
	ext.polls += ext.hb[2] != 0; /* the line thread reads what node_set wrote */
	return UINT64_MAX;
}

static const line_ext_ops ext_ops = {
	.name = "nodes-test",
	.node_set = ext_node_set,
	.poll = ext_poll,
};

static void start(bool with_ext)
{
	snprintf(instance, sizeof instance, "ndst%d", (int)getpid());
	TEST_ASSERT_EQUAL(0, mbx_queue_name(qname, sizeof qname, instance, 0));
	TEST_ASSERT_EQUAL(0, co_od_create(&od, 16));
	TEST_ASSERT_EQUAL(0, co_od_add_comm_defaults_hb(od, 127, 0));
	line_params p = {
		.index = 0,
		.name = "nodes",
		.network_id = 1,
		.can = { .ifname = "vcan0", .bitrate = 1000000 },
		.node = { .node_id = 127, .od = od },
		.mbx = { .queue_name = qname,
			 .unlink_existing = true,
			 .default_access = MBX_ACCESS_WRITE },
		.rt_cpu = -1,
		.main_wakefd = -1,
	};
	if (with_ext)
		p.ext[0] = (line_ext){ .ops = &ext_ops, .ctx = NULL, .wake_fd = -1 };
	TEST_ASSERT_EQUAL_INT(0, line_create(&l, &p));
	TEST_ASSERT_EQUAL_INT(0, line_start(l));
	for (int i = 0; i < 500 && !line_is_up(l); i++)
		usleep(10000);
	TEST_ASSERT_TRUE(line_is_up(l));
}

static void stop(void)
{
	line_destroy(l);
	l = NULL;
	if (od)
		co_od_destroy(od);
	od = NULL;
}

void setUp(void)
{
	memset(&ext, 0, sizeof ext);
}

void tearDown(void)
{
	stop();
}

static void *reader(void *arg)
{
	cogw *h = NULL;
	unsigned sub = 1 + (unsigned)(uintptr_t)arg;
	if (cogw_open(&h, instance) != 0) {
		atomic_fetch_add(&reads_failed, 1);
		return NULL;
	}
	while (!atomic_load(&stop_readers)) {
		uint32_t v = 0;
		size_t len = 0;
		if (cogw_od_read(h, 0, 0x1016, (uint8_t)sub, &v, sizeof v, &len, 5000, NULL) == 0)
			atomic_fetch_add(&reads_ok, 1);
		else
			atomic_fetch_add(&reads_failed, 1);
		sub = sub % 127 + 1;
	}
	cogw_close(h);
	return NULL;
}

/* The 1016h time of node over the mailbox (0 = none). */
static uint16_t consumed_ms(cogw *h, uint8_t node)
{
	for (unsigned sub = 1; sub <= 127; sub++) {
		uint32_t v = 0;
		size_t len = 0;
		TEST_ASSERT_EQUAL_INT(0, cogw_od_read(h, 0, 0x1016, (uint8_t)sub, &v, sizeof v,
						      &len, 5000, NULL));
		if (((v >> 16) & 0xFF) == node && (v & 0xFFFF))
			return (uint16_t)v;
	}
	return 0;
}

static void test_node_changes_handed_to_a_busy_line(void)
{
	pthread_t t[READERS];
	uint16_t want[128] = { 0 };
	uint8_t want_byte[128] = { 0 };
	unsigned refused = 0;
	uint8_t cdcf[16];

	start(true);
	atomic_store(&stop_readers, false);
	for (unsigned i = 0; i < READERS; i++)
		TEST_ASSERT_EQUAL(0,
				  pthread_create(&t[i], NULL, reader, (void *)(uintptr_t)(i * 50)));
	for (unsigned i = 1; i <= CHANGES; i++) {
		uint8_t node = (uint8_t)(1 + i % NODES);
		line_node_set set = { .req = { .node = node,
					       .op = MBX_NODE_CHANGE,
					       .heartbeat_ms = (uint16_t)(100 + i % 900),
					       .identity = { i } },
				      .cdcf = cdcf,
				      .cdcf_len = sizeof cdcf };
		memset(cdcf, (int)(i & 0xFF), sizeof cdcf);
		int rc = line_request_node(l, &set);
		memset(cdcf, 0xEE, sizeof cdcf); /* the line copied what it needed */
		if (node % 2) {
			TEST_ASSERT_EQUAL_INT(-EBUSY, rc);
			refused++;
		} else {
			TEST_ASSERT_EQUAL_INT(0, rc);
			want[node] = set.req.heartbeat_ms;
			want_byte[node] = (uint8_t)i;
		}
	}
	/* plain heartbeat consumers of the odd nodes, the line's own */
	for (uint8_t node = 1; node <= NODES; node += 2) {
		TEST_ASSERT_EQUAL_INT(0, line_request_consumer(l, node, (uint16_t)(1000 + node)));
		want[node] = (uint16_t)(1000 + node);
	}
	TEST_ASSERT_EQUAL_INT(0, line_request_consumer(l, 2, 0)); /* and one removed */
	want[2] = 0;
	atomic_store(&stop_readers, true);
	for (unsigned i = 0; i < READERS; i++)
		pthread_join(t[i], NULL);
	TEST_ASSERT_GREATER_THAN_UINT(0, atomic_load(&reads_ok));
	TEST_ASSERT_EQUAL_UINT(0, atomic_load(&reads_failed));

	cogw *h = NULL;
	TEST_ASSERT_EQUAL_INT(0, cogw_open(&h, instance));
	for (uint8_t node = 1; node <= NODES; node++)
		TEST_ASSERT_EQUAL_UINT16_MESSAGE(want[node], consumed_ms(h, node), "1016h entry");
	cogw_close(h);
	stop();
	TEST_ASSERT_EQUAL_UINT(CHANGES - refused, ext.applied);
	TEST_ASSERT_EQUAL_UINT(refused, ext.refused);
	TEST_ASSERT_EQUAL_UINT(0, ext.order_errors);
	TEST_ASSERT_EQUAL_UINT(CHANGES, ext.last_seq);
	/* the concise DCF was read during the call, never after it */
	for (uint8_t node = 2; node <= NODES; node += 2)
		TEST_ASSERT_EQUAL_HEX8(want_byte[node], ext.first_byte[node]);
}

static void test_no_network_list_no_change(void)
{
	line_node_set set = { .req = { .node = 5, .op = MBX_NODE_ADD, .assignment = 5 } };
	start(false);
	TEST_ASSERT_EQUAL_INT(-EOPNOTSUPP, line_request_node(l, &set));
	/* a heartbeat consumer is the line's own: it works without */
	TEST_ASSERT_EQUAL_INT(0, line_request_consumer(l, 5, 700));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_node_changes_handed_to_a_busy_line);
	RUN_TEST(test_no_network_list_no_change);
	return UNITY_END();
}
