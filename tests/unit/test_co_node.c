/* SPDX-License-Identifier: MIT */
/*
 * The core instance: creation rules, receive dispatch (11-bit table, 29-bit
 * table, chains, counters, move/disable), deadlines, independence of two
 * instances in one process.
 */
#include <errno.h>
#include <string.h>

#include "unity.h"

#include "core/co.h"
#include "core/sdo_server.h"
#include "tests/unit/support/test_bus.h"
#include "tests/unit/support/test_od_fixture.h"

static co_od *od;
static co_node *node;
static co_frame sent[16];
static int n_sent;
static int fail_send;
static co_event events[16];
static int n_events;

static int send_cb(void *ctx, const co_frame *f)
{
	(void)ctx;
	if (fail_send)
		return -ENOBUFS;
	if (n_sent < 16)
		sent[n_sent++] = *f;
	return 0;
}

static void event_cb(void *ctx, const co_event *ev)
{
	(void)ctx;
	if (n_events < 16)
		events[n_events++] = *ev;
}

void setUp(void)
{
	co_node_config cfg = { .node_id = 3,
			       .send = send_cb,
			       .event = event_cb,
			       .rx_max = 0,
			       .rx_ext_max = 2,
			       .report_unhandled = true };

	n_sent = n_events = fail_send = 0;
	TEST_ASSERT_EQUAL(0, co_od_create(&od, 4));
	cfg.od = od;
	TEST_ASSERT_EQUAL(0, co_node_create(&node, &cfg));
}

void tearDown(void)
{
	co_node_destroy(node);
	co_od_destroy(od);
}

struct rx_log {
	int calls;
	int order[8];
	int n;
	int id;
};

static void rx_cb(co_node *n, void *arg, const co_frame *f, uint64_t now_us)
{
	struct rx_log *l = arg;
	(void)n;
	(void)f;
	(void)now_us;
	l->calls++;
}

static int order_pos;
static void rx_order(co_node *n, void *arg, const co_frame *f, uint64_t now_us)
{
	struct rx_log *l = arg;
	(void)n;
	(void)f;
	(void)now_us;
	l->order[l->n++] = order_pos++;
}

static void test_create_rejects_bad_config(void)
{
	co_node *x;
	co_node_config cfg = { .node_id = 0, .od = od, .send = send_cb };

	TEST_ASSERT_EQUAL(-EINVAL, co_node_create(&x, &cfg));
	cfg.node_id = 128;
	TEST_ASSERT_EQUAL(-EINVAL, co_node_create(&x, &cfg));
	cfg.node_id = 1;
	cfg.send = NULL;
	TEST_ASSERT_EQUAL(-EINVAL, co_node_create(&x, &cfg));
	cfg.send = send_cb;
	cfg.od = NULL;
	TEST_ASSERT_EQUAL(-EINVAL, co_node_create(&x, &cfg));
	cfg.od = od;
	cfg.sdo_client_count = 129;
	TEST_ASSERT_EQUAL(-EINVAL, co_node_create(&x, &cfg));
	co_node_destroy(NULL);
	co_od_destroy(NULL);
	/* LSS-unconfigured node: allowed, SDO server 1 stays invalid. */
	co_od *od2;
	co_od_create(&od2, 4);
	co_node_config c2 = { .node_id = 255, .od = od2, .send = send_cb };
	TEST_ASSERT_EQUAL(0, co_node_create(&x, &c2));
	TEST_ASSERT_EQUAL(255, co_node_id(x));
	co_node_destroy(x);
	co_od_destroy(od2);
}

static void test_dispatch_11bit_chain_counters(void)
{
	struct rx_log a = { 0 }, b = { 0 };
	co_frame f = tb_frame(0x123, "01 02");
	int ha = co_rx_register(node, 0x123, 0, rx_order, &a);
	int hb = co_rx_register(node, 0x123, 0, rx_order, &b);

	TEST_ASSERT_TRUE(ha >= 0 && hb >= 0);
	order_pos = 0;
	TEST_ASSERT_EQUAL(0, co_node_recv(node, &f, 10));
	TEST_ASSERT_EQUAL(1, a.n);
	TEST_ASSERT_EQUAL(1, b.n);
	TEST_ASSERT_EQUAL(0, a.order[0]); /* registration order */
	TEST_ASSERT_EQUAL(1, b.order[0]);
	TEST_ASSERT_EQUAL_UINT64(1, co_rx_hits(node, ha));
	TEST_ASSERT_EQUAL(0, co_rx_unregister(node, ha));
	co_node_recv(node, &f, 10);
	TEST_ASSERT_EQUAL(1, a.n);
	TEST_ASSERT_EQUAL(2, b.n);
	TEST_ASSERT_EQUAL(-EINVAL, co_rx_unregister(node, ha));
	/* Move and disable. */
	TEST_ASSERT_EQUAL(0, co_rx_move(node, hb, 0x124, 0));
	co_node_recv(node, &f, 10);
	TEST_ASSERT_EQUAL(2, b.n);
	f.id = 0x124;
	co_node_recv(node, &f, 10);
	TEST_ASSERT_EQUAL(3, b.n);
	TEST_ASSERT_EQUAL(0, co_rx_disable(node, hb));
	co_node_recv(node, &f, 10);
	TEST_ASSERT_EQUAL(3, b.n);
	TEST_ASSERT_EQUAL_UINT64(3, co_rx_hits(node, hb));
	const co_node_stats *st = co_node_get_stats(node);
	TEST_ASSERT_EQUAL_UINT64(5, st->rx_frames);
	TEST_ASSERT_EQUAL_UINT64(2, st->rx_unhandled);
	TEST_ASSERT_EQUAL(CO_EV_RX_UNHANDLED, events[n_events - 1].kind);
	TEST_ASSERT_EQUAL_UINT32(0x124, events[n_events - 1].u.frame.id);
	TEST_ASSERT_EQUAL_STRING("rx-unhandled", co_event_kind_to_string(CO_EV_RX_UNHANDLED));
}

/* Every event kind has its own name (logs and the mailbox's event texts). */
static void test_every_event_kind_named(void)
{
	for (int k = 0; k < CO_EV_KIND_COUNT; k++)
		for (int j = 0; j < k; j++)
			TEST_ASSERT_NOT_EQUAL(0, strcmp(co_event_kind_to_string((co_event_kind)j),
							co_event_kind_to_string((co_event_kind)k)));
	for (int k = 0; k < CO_EV_KIND_COUNT; k++)
		TEST_ASSERT_NOT_EQUAL(0, strcmp("?", co_event_kind_to_string((co_event_kind)k)));
	TEST_ASSERT_EQUAL_STRING("?", co_event_kind_to_string(CO_EV_KIND_COUNT));
}

static void test_dispatch_29bit_and_invalid_frames(void)
{
	struct rx_log a = { 0 }, b = { 0 }, c = { 0 };
	co_frame f = tb_frame(0x123, "01");

	TEST_ASSERT_TRUE(co_rx_register(node, 0x123, CO_FRAME_EXT, rx_cb, &a) >= 0);
	TEST_ASSERT_TRUE(co_rx_register(node, 0x1FFFFFFF, CO_FRAME_EXT, rx_cb, &b) >= 0);
	TEST_ASSERT_EQUAL(-ENOSPC, co_rx_register(node, 0x5, CO_FRAME_EXT, rx_cb, &c));
	TEST_ASSERT_EQUAL(-EINVAL, co_rx_register(node, 0x800, 0, rx_cb, &c));
	TEST_ASSERT_EQUAL(-EINVAL, co_rx_register(node, 0x20000000, CO_FRAME_EXT, rx_cb, &c));
	co_node_recv(node, &f, 1); /* 11-bit 0x123: not the 29-bit receiver */
	TEST_ASSERT_EQUAL(0, a.calls);
	f.flags = CO_FRAME_EXT;
	co_node_recv(node, &f, 1);
	TEST_ASSERT_EQUAL(1, a.calls);
	f.id = 0x1FFFFFFF;
	co_node_recv(node, &f, 1);
	TEST_ASSERT_EQUAL(1, b.calls);
	f.len = 9;
	TEST_ASSERT_EQUAL(-EINVAL, co_node_recv(node, &f, 1));
	f.len = 8;
	f.flags = CO_FRAME_FD;
	TEST_ASSERT_EQUAL(-EINVAL, co_node_recv(node, &f, 1));
	f.flags = 0;
	f.id = 0x800;
	TEST_ASSERT_EQUAL(-EINVAL, co_node_recv(node, &f, 1));
	TEST_ASSERT_EQUAL_UINT64(3, co_node_get_stats(node)->rx_invalid);
}

static void test_receiver_pool_limit(void)
{
	struct rx_log a = { 0 };
	int n = 0, last = -1, h;

	/* rx_max = 512 (default), shared with the services' own receivers. */
	while ((h = co_rx_register(node, (uint32_t)(0x100 + n), 0, rx_cb, &a)) >= 0) {
		last = h;
		n++;
	}
	TEST_ASSERT_EQUAL(-ENOSPC, h);
	TEST_ASSERT_TRUE(n > 0 && n < 512);
	TEST_ASSERT_EQUAL(0, co_rx_unregister(node, last));
	TEST_ASSERT_EQUAL(last, co_rx_register(node, 0x7FF, 0, rx_cb, &a));
}

static void test_send_failure_counted_and_reported(void)
{
	co_frame f = tb_frame(0x603, "40 00 10 00 00 00 00 00");

	co_od_add_num(od, 0x1000, 0, CO_T_UNSIGNED32, CO_ACC_RO, 0x191, NULL);
	fail_send = 1;
	co_node_recv(node, &f, 5);
	TEST_ASSERT_EQUAL_UINT64(1, co_node_get_stats(node)->tx_failed);
	TEST_ASSERT_EQUAL(CO_EV_TX_FAILED, events[n_events - 2].kind);
	TEST_ASSERT_EQUAL_UINT32(0x583, events[n_events - 2].u.frame.id);
	fail_send = 0;
	uint64_t before = co_node_get_stats(node)->tx_frames;
	co_node_recv(node, &f, 5);
	TEST_ASSERT_EQUAL_UINT32(0x583, sent[n_sent - 1].id);
	TEST_ASSERT_EQUAL_UINT64(before + 1, co_node_get_stats(node)->tx_frames);
}

static void test_deadline_none_when_idle(void)
{
	/* With only SDO in this OD there is nothing to wait for... */
	uint64_t d = co_node_tick(node, 100);
	TEST_ASSERT_EQUAL_UINT64(d, co_node_next_deadline_us(node));
	co_node_deadline_lower(node, 50);
	TEST_ASSERT_EQUAL_UINT64(50, co_node_next_deadline_us(node));
	co_node_deadline_lower(node, 70);
	TEST_ASSERT_EQUAL_UINT64(50, co_node_next_deadline_us(node));
	TEST_ASSERT_EQUAL_PTR(od, co_node_od(node));
}

/* Two lines in one process: same node-id, same COB-IDs, separate state. */
static void test_two_instances_are_independent(void)
{
	tb_bus a, b;
	co_node_config ca = { .node_id = 1 }, cb = { .node_id = 1 };
	tb_port *pa, *pb;

	tb_init(&a);
	tb_init(&b);
	pa = tb_add_node(&a, &ca, fx_od_new());
	pb = tb_add_node(&b, &cb, fx_od_new());
	tb_send_hex(&a, 0x601, "2B 17 10 00 A0 0F 00 00");
	tb_send_hex(&a, 0x601, "21 02 24 00 0A 00 00 00"); /* leaves a transfer open */
	uint16_t va, vb;
	co_od_get_u16(pa->od, 0x1017, 0, &va);
	co_od_get_u16(pb->od, 0x1017, 0, &vb);
	TEST_ASSERT_EQUAL_UINT16(4000, va);
	TEST_ASSERT_EQUAL_UINT16(1000, vb);
	TEST_ASSERT_TRUE(sdo_server_busy(pa->node, 0));
	TEST_ASSERT_EQUAL_STRING("download segment", sdo_server_state_to_string(pa->node, 0));
	TEST_ASSERT_FALSE(sdo_server_busy(pb->node, 0));
	TEST_ASSERT_EQUAL_STRING("idle", sdo_server_state_to_string(pb->node, 0));
	TEST_ASSERT_EQUAL_STRING("?", sdo_server_state_to_string(pb->node, 9));
	tb_advance(&a, 2000000);
	TEST_ASSERT_FALSE(sdo_server_busy(pa->node, 0));
	tb_send_hex(&b, 0x601, "40 17 10 00 00 00 00 00");
	TB_ASSERT_LAST(&b, 0, 0x581, "4B 17 10 00 E8 03 00 00");
	tb_fini(&a);
	tb_fini(&b);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_create_rejects_bad_config);
	RUN_TEST(test_dispatch_11bit_chain_counters);
	RUN_TEST(test_every_event_kind_named);
	RUN_TEST(test_dispatch_29bit_and_invalid_frames);
	RUN_TEST(test_receiver_pool_limit);
	RUN_TEST(test_send_failure_counted_and_reported);
	RUN_TEST(test_deadline_none_when_idle);
	RUN_TEST(test_two_instances_are_independent);
	return UNITY_END();
}
