/* SPDX-License-Identifier: MIT */
/*
 * TIME producer/consumer and TIME_OF_DAY coding (CiA 301
 * §7.2.6). Golden value: 2024-01-01T12:00:00.123Z = day 14610
 * since 1984-01-01, 43200123 ms after midnight = 7B 2E 93 02 12 39.
 */
#include <errno.h>
#include <string.h>

#include "unity.h"

#include "core/nmt.h"
#include "core/sdo.h"
#include "core/time.h"
#include "tests/unit/support/test_bus.h"

#define NODE 5
#define GOLDEN_UNIX_MS 1704110400123LL
#define GOLDEN_HEX "7B 2E 93 02 12 39"

static tb_bus bus;
static tb_port *port;
static co_node *node;
static co_od *od;

void setUp(void)
{
	co_node_config cfg = { .node_id = NODE };

	tb_init(&bus);
	TEST_ASSERT_EQUAL(0, co_od_create(&od, 16));
	TEST_ASSERT_EQUAL(0, co_od_add_comm_defaults_time(od, 0));
	port = tb_add_node(&bus, &cfg, od);
	TEST_ASSERT_NOT_NULL(port);
	node = port->node;
	tb_advance(&bus, 0);
	tb_log_clear(&bus);
	tb_events_clear(port);
}

void tearDown(void)
{
	tb_fini(&bus);
}

static uint32_t odw32(uint16_t index, uint32_t v)
{
	co_od_entry *e = co_od_find(od, index, 0);
	co_od_access a = { .origin = CO_OD_ORIGIN_SDO };
	uint8_t b[4];

	co_put_le32(b, v);
	return co_od_write(e, b, 4, &a);
}

static void nmt(uint8_t cs)
{
	co_frame f = tb_frame(0x000, "00 00");
	f.data[0] = cs;
	f.data[1] = NODE;
	tb_send(&bus, &f);
}

/* ---- coding ------------------------------------------------------------------ */

static void test_golden_encode_decode(void)
{
	co_time_of_day t, back;
	uint8_t b[6];
	co_frame g = tb_frame(0x100, GOLDEN_HEX);

	TEST_ASSERT_EQUAL(0, co_time_from_unix_ms(GOLDEN_UNIX_MS, &t));
	TEST_ASSERT_EQUAL(14610, t.days);
	TEST_ASSERT_EQUAL(43200123, t.ms);
	TEST_ASSERT_EQUAL(0, co_time_encode(&t, b));
	TEST_ASSERT_EQUAL_HEX8_ARRAY(g.data, b, 6);
	TEST_ASSERT_EQUAL(0, co_time_decode(b, 6, &back));
	TEST_ASSERT_EQUAL(t.days, back.days);
	TEST_ASSERT_EQUAL(t.ms, back.ms);
	TEST_ASSERT_EQUAL_INT64(GOLDEN_UNIX_MS, co_time_to_unix_ms(&back));
}

static void test_round_trip_many(void)
{
	/* every ~37 hours + odd ms across the whole range */
	for (int64_t ms = CO_TIME_EPOCH_UNIX_S * 1000; ms < 5000000000000LL; ms += 133333337LL) {
		co_time_of_day t, back;
		uint8_t b[6];
		TEST_ASSERT_EQUAL(0, co_time_from_unix_ms(ms, &t));
		TEST_ASSERT_EQUAL(0, co_time_encode(&t, b));
		TEST_ASSERT_EQUAL(0, co_time_decode(b, 6, &back));
		TEST_ASSERT_EQUAL_INT64(ms, co_time_to_unix_ms(&back));
	}
}

static void test_range_and_invalid(void)
{
	co_time_of_day t;
	uint8_t b[6];
	const uint8_t reserved_set[6] = { 0x7B, 0x2E, 0x93, 0xF2, 0x12, 0x39 };
	const uint8_t one_day[6] = { 0x00, 0x5C, 0x26, 0x05, 0x00, 0x00 };

	TEST_ASSERT_EQUAL(0, co_time_from_unix_ms(CO_TIME_EPOCH_UNIX_S * 1000, &t));
	TEST_ASSERT_EQUAL(0, t.days);
	TEST_ASSERT_EQUAL(0, t.ms);
	TEST_ASSERT_EQUAL(-ERANGE, co_time_from_unix_ms(CO_TIME_EPOCH_UNIX_S * 1000 - 1, &t));
	/* last representable millisecond, day 65535 */
	TEST_ASSERT_EQUAL(0, co_time_from_unix_ms(CO_TIME_EPOCH_UNIX_S * 1000 +
							  65536LL * CO_TIME_MS_PER_DAY - 1,
						  &t));
	TEST_ASSERT_EQUAL(65535, t.days);
	TEST_ASSERT_EQUAL(CO_TIME_MS_PER_DAY - 1, t.ms);
	TEST_ASSERT_EQUAL(-ERANGE,
			  co_time_from_unix_ms(
				  CO_TIME_EPOCH_UNIX_S * 1000 + 65536LL * CO_TIME_MS_PER_DAY, &t));
	/* reserved bits 28..31 ignored */
	TEST_ASSERT_EQUAL(0, co_time_decode(reserved_set, 6, &t));
	TEST_ASSERT_EQUAL(43200123, t.ms);
	TEST_ASSERT_EQUAL(14610, t.days);
	/* 86400000 ms is not a time of day */
	TEST_ASSERT_EQUAL(-EINVAL, co_time_decode(one_day, 6, &t));
	TEST_ASSERT_EQUAL(-EINVAL, co_time_decode(reserved_set, 5, &t));
	t.ms = CO_TIME_MS_PER_DAY;
	TEST_ASSERT_EQUAL(-EINVAL, co_time_encode(&t, b));
}

/* ---- service ------------------------------------------------------------------ */

static void test_producer(void)
{
	co_time_of_day t;

	TEST_ASSERT_EQUAL(0, co_time_from_unix_ms(GOLDEN_UNIX_MS, &t));
	TEST_ASSERT_EQUAL(-EPERM, co_time_send(node, &t, bus.now)); /* 1012h = 100h */
	TEST_ASSERT_EQUAL_HEX32(0, odw32(0x1012, CO_TIME_PRODUCER | 0x100));
	TEST_ASSERT_EQUAL(0, tb_event_count(port, CO_EV_TIME));
	TEST_ASSERT_EQUAL(0, co_time_send(node, &t, bus.now + 7));
	tb_pump(&bus);
	TB_ASSERT_LAST(&bus, 0, 0x100, GOLDEN_HEX);
	TEST_ASSERT_EQUAL(1, co_time_get_stats(node)->tx);
	/* the producer reports what it sent, as the SYNC producer does */
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_TIME));
	TEST_ASSERT_EQUAL(1, tb_last_event(port, CO_EV_TIME)->u.time.produced);
	TEST_ASSERT_EQUAL(43200123, tb_last_event(port, CO_EV_TIME)->u.time.ms);
	TEST_ASSERT_EQUAL(14610, tb_last_event(port, CO_EV_TIME)->u.time.days);
	TEST_ASSERT_EQUAL_UINT64(bus.now + 7, tb_last_event(port, CO_EV_TIME)->now_us);
	nmt(CO_NMT_CS_STOP);
	TEST_ASSERT_EQUAL(-EAGAIN, co_time_send(node, &t, bus.now));
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_TIME));
	nmt(CO_NMT_CS_START); /* OPERATIONAL: allowed too */
	TEST_ASSERT_EQUAL(0, co_time_send(node, &t, bus.now));
}

static void test_consumer(void)
{
	co_time_of_day t;
	const co_event *ev;

	tb_send_hex(&bus, 0x100, GOLDEN_HEX); /* not consuming yet */
	TEST_ASSERT_EQUAL(0, tb_event_count(port, CO_EV_TIME));
	TEST_ASSERT_EQUAL(-ENODATA, co_time_last(node, &t));

	TEST_ASSERT_EQUAL_HEX32(0, odw32(0x1012, CO_TIME_CONSUMER | 0x100));
	tb_send_hex(&bus, 0x100, GOLDEN_HEX);
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_TIME));
	ev = tb_last_event(port, CO_EV_TIME);
	TEST_ASSERT_EQUAL(43200123, ev->u.time.ms);
	TEST_ASSERT_EQUAL(14610, ev->u.time.days);
	TEST_ASSERT_EQUAL(0, ev->u.time.produced);
	TEST_ASSERT_EQUAL(0, co_time_last(node, &t));
	TEST_ASSERT_EQUAL_INT64(GOLDEN_UNIX_MS, co_time_to_unix_ms(&t));

	tb_send_hex(&bus, 0x100, "7B 2E 93 02 12"); /* short */
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_TIME));
	TEST_ASSERT_EQUAL(1, co_time_get_stats(node)->rx_invalid);

	/* no new CAN-ID while consuming; allowed once consumption stops */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, odw32(0x1012, CO_TIME_CONSUMER | 0x101));
	TEST_ASSERT_EQUAL_HEX32(0, odw32(0x1012, 0x101));
	TEST_ASSERT_EQUAL_HEX32(0, odw32(0x1012, CO_TIME_CONSUMER | 0x101));
	tb_send_hex(&bus, 0x100, GOLDEN_HEX);
	TEST_ASSERT_EQUAL(1, tb_event_count(port, CO_EV_TIME));
	tb_send_hex(&bus, 0x101, GOLDEN_HEX);
	TEST_ASSERT_EQUAL(2, tb_event_count(port, CO_EV_TIME));

	nmt(CO_NMT_CS_STOP);
	tb_send_hex(&bus, 0x101, GOLDEN_HEX);
	TEST_ASSERT_EQUAL(2, tb_event_count(port, CO_EV_TIME));
	TEST_ASSERT_EQUAL(1, co_time_get_stats(node)->rx_ignored);
}

static void test_two_nodes_producer_to_consumer(void)
{
	co_node_config cfg = { .node_id = 6 };
	co_od *od2;
	tb_port *p2;
	co_time_of_day t = { .ms = 1, .days = 2 };

	TEST_ASSERT_EQUAL(0, co_od_create(&od2, 16));
	TEST_ASSERT_EQUAL(0, co_od_add_comm_defaults_time(od2, CO_TIME_CONSUMER | 0x100));
	p2 = tb_add_node(&bus, &cfg, od2);
	TEST_ASSERT_NOT_NULL(p2);
	tb_advance(&bus, 0);
	TEST_ASSERT_EQUAL_HEX32(0, odw32(0x1012, CO_TIME_PRODUCER | 0x100));
	TEST_ASSERT_EQUAL(0, co_time_send(node, &t, bus.now));
	tb_pump(&bus);
	TEST_ASSERT_EQUAL(1, tb_event_count(p2, CO_EV_TIME));
	TEST_ASSERT_EQUAL(1, tb_last_event(p2, CO_EV_TIME)->u.time.ms);
	TEST_ASSERT_EQUAL(2, tb_last_event(p2, CO_EV_TIME)->u.time.days);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_golden_encode_decode);
	RUN_TEST(test_round_trip_many);
	RUN_TEST(test_range_and_invalid);
	RUN_TEST(test_producer);
	RUN_TEST(test_consumer);
	RUN_TEST(test_two_nodes_producer_to_consumer);
	return UNITY_END();
}
