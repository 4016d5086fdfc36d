/* SPDX-License-Identifier: MIT */
/*
 * SYNC producer/consumer (CiA 301 §7.2.5 and the
 * 1005h/1006h/1007h/1019h rules). One node (id 5), the test is the rest
 * of the bus and owns the clock.
 */
#include <errno.h>
#include <string.h>

#include "unity.h"

#include "core/emcy.h"
#include "core/nmt.h"
#include "core/pdo.h"
#include "core/sync.h"
#include "tests/unit/support/test_bus.h"

#define NODE 5

static tb_bus bus;
static tb_port *port;
static co_node *node;
static co_od *od;

void setUp(void)
{
	co_node_config cfg = { .node_id = NODE };
	const uint32_t map[] = { CO_PDO_MAP(0x2000, 0, 16) };
	co_pdo_desc t = {
		.dir = CO_PDO_TX, .nr = 1, .cob_id = 0x185, .tt = 1, .n_map = 1, .map = map
	};

	tb_init(&bus);
	TEST_ASSERT_EQUAL(0, co_od_create(&od, 64));
	TEST_ASSERT_EQUAL(0,
			  co_od_add_num(od, 0x2000, 0, CO_T_UNSIGNED16, CO_ACC_RWR, 0xBEEF, NULL));
	TEST_ASSERT_EQUAL(0, co_od_add_comm_defaults_emcy(od, NODE, 4, 0, 0));
	TEST_ASSERT_EQUAL(0, co_od_add_comm_defaults_sync(od, 0, 0, 0));
	TEST_ASSERT_EQUAL(0, co_od_add_pdo(od, &t));
	port = tb_add_node(&bus, &cfg, od);
	TEST_ASSERT_NOT_NULL(port);
	node = port->node;
	tb_advance(&bus, 0);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(node));
	tb_log_clear(&bus);
	tb_events_clear(port);
}

void tearDown(void)
{
	tb_fini(&bus);
}

static uint32_t odw(uint16_t index, uint8_t sub, uint64_t v)
{
	return tb_od_write(&bus, node, index, sub, v);
}

static unsigned count_id(uint32_t id)
{
	unsigned n = 0;

	for (size_t i = 0; i < tb_log_count(&bus); i++)
		if (tb_log_at(&bus, i)->id == id && bus.log_from[i] == port->idx)
			n++;
	return n;
}

static const co_frame *nth_id(uint32_t id, unsigned k)
{
	for (size_t i = 0; i < tb_log_count(&bus); i++)
		if (tb_log_at(&bus, i)->id == id && bus.log_from[i] == port->idx && k-- == 0)
			return tb_log_at(&bus, i);
	return NULL;
}

static void nmt(uint8_t cs)
{
	co_frame f = tb_frame(0x000, "00 00");
	f.data[0] = cs;
	f.data[1] = NODE;
	tb_send(&bus, &f);
}

/* ---- producer ----------------------------------------------------------------- */

static void test_producer_every_period(void)
{
	const co_event *ev;

	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1005, 0, CO_SYNC_PRODUCER | 0x80));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1006, 0, 10000));
	TEST_ASSERT_TRUE(co_sync_is_producer(node));
	tb_advance(&bus, 9999);
	TEST_ASSERT_EQUAL(0, count_id(0x80));
	tb_advance(&bus, 1);
	TEST_ASSERT_EQUAL(1, count_id(0x80));
	TEST_ASSERT_EQUAL(0, nth_id(0x80, 0)->len); /* 1019h = 0: no counter */
	tb_advance(&bus, 90000);
	TEST_ASSERT_EQUAL(10, count_id(0x80));
	TEST_ASSERT_EQUAL(10, tb_event_count(port, CO_EV_SYNC));
	ev = tb_last_event(port, CO_EV_SYNC);
	TEST_ASSERT_EQUAL(1, ev->u.sync.produced);
	TEST_ASSERT_EQUAL(0, ev->u.sync.counter);
	TEST_ASSERT_EQUAL_UINT64(bus.now, ev->now_us);
	TEST_ASSERT_EQUAL_UINT64(bus.now + 10000, co_node_next_deadline_us(node));
}

static void test_period_zero_or_no_bit30_means_no_sync(void)
{
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1005, 0, CO_SYNC_PRODUCER | 0x80));
	tb_advance(&bus, 1000000);
	TEST_ASSERT_EQUAL(0, count_id(0x80));
	TEST_ASSERT_FALSE(co_sync_is_producer(node));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1005, 0, 0x80));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1006, 0, 10000));
	tb_advance(&bus, 1000000);
	TEST_ASSERT_EQUAL(0, count_id(0x80));
	/* a running producer stops when 1006h goes back to 0 */
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1005, 0, CO_SYNC_PRODUCER | 0x80));
	tb_advance(&bus, 30000);
	TEST_ASSERT_EQUAL(3, count_id(0x80));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1006, 0, 0));
	tb_advance(&bus, 1000000);
	TEST_ASSERT_EQUAL(3, count_id(0x80));
}

static void test_counter_wraps_at_1019h(void)
{
	const char *expect[] = { "01", "02", "03", "01", "02", "03", "01" };

	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1019, 0, 3));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1005, 0, CO_SYNC_PRODUCER | 0x80));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1006, 0, 10000));
	tb_advance(&bus, 70000);
	TEST_ASSERT_EQUAL(7, count_id(0x80));
	for (unsigned i = 0; i < 7; i++)
		TEST_ASSERT_TRUE(tb_frame_is(nth_id(0x80, i), 0x80, expect[i]));
	TEST_ASSERT_EQUAL(1, co_sync_counter(node));
	TEST_ASSERT_EQUAL(1, tb_last_event(port, CO_EV_SYNC)->u.sync.counter);
}

static void test_object_rules(void)
{
	/* 1019h: 1 and >240 invalid; only while 1006h = 0 */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, odw(0x1019, 0, 1));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, odw(0x1019, 0, 241));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1019, 0, 240));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1006, 0, 1000));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_DEV_STATE, odw(0x1019, 0, 10));
	TEST_ASSERT_EQUAL(240, co_sync_overflow(node));
	/* 1005h: no new CAN-ID while producing */
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1005, 0, CO_SYNC_PRODUCER | 0x80));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, odw(0x1005, 0, CO_SYNC_PRODUCER | 0x81));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1005, 0, 0x81)); /* stop producing */
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1005, 0, CO_SYNC_PRODUCER | 0x81));
	/* an 11-bit COB-ID with bits above 10 */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, odw(0x1005, 0, 0x881));
	tb_advance(&bus, 1000);
	TEST_ASSERT_EQUAL(1, count_id(0x81));
}

static void test_late_tick_skips_instead_of_bursting(void)
{
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1005, 0, CO_SYNC_PRODUCER | 0x80));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1006, 0, 10000));
	/* the line thread wakes up 35 ms late */
	bus.now += 35000;
	co_node_tick(node, bus.now);
	tb_pump(&bus);
	TEST_ASSERT_EQUAL(1, count_id(0x80));
	/* due at +10, +20, +30 ms: one sent at +35, two skipped */
	TEST_ASSERT_EQUAL(2, co_sync_get_stats(node)->skipped);
	TEST_ASSERT_EQUAL_UINT64(bus.now + 10000, co_node_next_deadline_us(node));
}

static void test_producer_stops_in_stopped(void)
{
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1005, 0, CO_SYNC_PRODUCER | 0x80));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1006, 0, 10000));
	tb_advance(&bus, 20000);
	TEST_ASSERT_EQUAL(2, count_id(0x80));
	nmt(CO_NMT_CS_STOP);
	tb_advance(&bus, 100000);
	TEST_ASSERT_EQUAL(2, count_id(0x80));
	nmt(CO_NMT_CS_START);
	tb_advance(&bus, 10000);
	TEST_ASSERT_EQUAL(3, count_id(0x80));
}

static void test_produced_sync_drives_own_tpdos(void)
{
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1005, 0, CO_SYNC_PRODUCER | 0x80));
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1006, 0, 10000));
	nmt(CO_NMT_CS_START);
	tb_log_clear(&bus);
	tb_advance(&bus, 30000);
	TEST_ASSERT_EQUAL(3, count_id(0x80));
	TEST_ASSERT_EQUAL(3, count_id(0x185));
	/* order on the bus: SYNC, then the TPDO it triggered */
	TEST_ASSERT_EQUAL_HEX32(0x80, tb_log_at(&bus, 0)->id);
	TEST_ASSERT_TRUE(tb_frame_is(tb_log_at(&bus, 1), 0x185, "EF BE"));
}

/* ---- consumer ----------------------------------------------------------------- */

static void test_consumer_events_and_counter(void)
{
	const co_event *ev;

	tb_send_hex(&bus, 0x80, "");
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_SYNC));
	ev = tb_last_event(port, CO_EV_SYNC);
	TEST_ASSERT_EQUAL(0, ev->u.sync.produced);
	TEST_ASSERT_EQUAL(0, ev->u.sync.counter);
	/* without 1019h the counter byte is ignored */
	tb_send_hex(&bus, 0x80, "07");
	TEST_ASSERT_EQUAL(0, tb_last_event(port, CO_EV_SYNC)->u.sync.counter);

	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1019, 0, 4));
	tb_send_hex(&bus, 0x80, "03");
	TEST_ASSERT_EQUAL(3, tb_last_event(port, CO_EV_SYNC)->u.sync.counter);
	TEST_ASSERT_EQUAL(3, co_sync_counter(node));
	TEST_ASSERT_EQUAL_UINT64(bus.now, co_sync_last_us(node));

	/* wrong length with a counter expected: EMCY 8240h, once */
	tb_send_hex(&bus, 0x80, "");
	tb_send_hex(&bus, 0x80, "01 02");
	TEST_ASSERT_EQUAL(3, tb_event_count(port, CO_EV_SYNC));
	TEST_ASSERT_EQUAL(1, count_id(0x85));
	TEST_ASSERT_TRUE(tb_frame_is(nth_id(0x85, 0), 0x85, "40 82 11 00 00 00 00 00"));
	TEST_ASSERT_EQUAL(2, co_sync_get_stats(node)->rx_invalid);
	/* good again: the error is cleared */
	tb_send_hex(&bus, 0x80, "04");
	TEST_ASSERT_EQUAL(2, count_id(0x85));
	TEST_ASSERT_TRUE(tb_frame_is(nth_id(0x85, 1), 0x85, "00 00 00 00 00 00 00 00"));
}

struct obs_log {
	unsigned calls;
	uint8_t counter;
	size_t events_seen; /* CO_EV_SYNC events emitted before the call */
};

static void obs_record(co_node *n, void *ctx, uint8_t counter, uint64_t now_us)
{
	struct obs_log *log = ctx;

	TEST_ASSERT_EQUAL_PTR(node, n);
	TEST_ASSERT_EQUAL_UINT64(bus.now, now_us);
	log->calls++;
	log->counter = counter;
	log->events_seen = tb_event_count(port, CO_EV_SYNC);
}

/* The operation through which SYNC reaches PDO (and any later observer):
 * called after CO_EV_SYNC with the counter; the table is bounded. */
static void test_observer_op(void)
{
	struct obs_log log = { 0 };
	int rc, added = 1; /* the PDO service registered one at init */

	TEST_ASSERT_EQUAL(-EINVAL, co_sync_observer_add(node, NULL, &log));
	TEST_ASSERT_EQUAL(0, co_sync_observer_add(node, obs_record, &log));
	added++;
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1019, 0, 4));
	tb_send_hex(&bus, 0x80, "02");
	TEST_ASSERT_EQUAL(1, log.calls);
	TEST_ASSERT_EQUAL(2, log.counter);
	TEST_ASSERT_EQUAL(1, log.events_seen);
	while ((rc = co_sync_observer_add(node, obs_record, &log)) == 0)
		added++;
	TEST_ASSERT_EQUAL(-ENOSPC, rc);
	TEST_ASSERT_EQUAL(CO_SYNC_OBSERVERS_MAX, added);
}

static void test_consumer_follows_1005h_and_nmt(void)
{
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1005, 0, 0x90));
	tb_send_hex(&bus, 0x80, "");
	TEST_ASSERT_EQUAL(0, tb_event_count(port, CO_EV_SYNC));
	tb_send_hex(&bus, 0x90, "");
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_SYNC));
	nmt(CO_NMT_CS_STOP);
	tb_send_hex(&bus, 0x90, "");
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_SYNC));
	TEST_ASSERT_EQUAL(1, co_sync_get_stats(node)->rx_ignored);
}

static void test_window(void)
{
	TEST_ASSERT_TRUE(co_sync_in_window(node, bus.now)); /* no window */
	TEST_ASSERT_EQUAL_HEX32(0, odw(0x1007, 0, 500));
	TEST_ASSERT_FALSE(co_sync_in_window(node, bus.now)); /* no SYNC yet */
	tb_send_hex(&bus, 0x80, "");
	TEST_ASSERT_TRUE(co_sync_in_window(node, bus.now + 500));
	TEST_ASSERT_FALSE(co_sync_in_window(node, bus.now + 501));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_producer_every_period);
	RUN_TEST(test_period_zero_or_no_bit30_means_no_sync);
	RUN_TEST(test_counter_wraps_at_1019h);
	RUN_TEST(test_object_rules);
	RUN_TEST(test_late_tick_skips_instead_of_bursting);
	RUN_TEST(test_producer_stops_in_stopped);
	RUN_TEST(test_produced_sync_drives_own_tpdos);
	RUN_TEST(test_consumer_events_and_counter);
	RUN_TEST(test_observer_op);
	RUN_TEST(test_consumer_follows_1005h_and_nmt);
	RUN_TEST(test_window);
	return UNITY_END();
}
