/* SPDX-License-Identifier: MIT */
/*
 * The project's CiA 302-7 encodings (gateway/convention.h), the routing
 * table compiled from 1F2Ch (gateway/route.h) and the EMCY routing
 * decision from 1F2Fh (gateway/emcy_route.h).
 */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "unity.h"

#include "core/od.h"
#include "gateway/convention.h"
#include "gateway/emcy_route.h"
#include "gateway/route.h"

void setUp(void) {}
void tearDown(void) {}

static void hex_eq(const char *want, const uint8_t d[8])
{
	char got[32];

	for (int i = 0; i < 8; i++)
		snprintf(&got[i * 3], 4, i < 7 ? "%02X " : "%02X", d[i]);
	TEST_ASSERT_EQUAL_STRING(want, got);
}

static void test_netind_golden_frames(void)
{
	uint8_t d[8];
	gw_netind ni = { .net = 2, .node = 5 };

	gw_netind_encode(d, ni);
	hex_eq("E0 02 00 05 00 00 00 00", d);
	gw_netind_abort_encode(d, ni, GW_AB_NET_UNKNOWN);
	hex_eq("80 02 00 05 01 00 00 0A", d);
	gw_netind_abort_encode(d, (gw_netind){ .net = 127, .node = 127 }, GW_AB_NO_CLIENT);
	hex_eq("80 7F 00 7F 23 00 0A 06", d);
}

static void test_netind_decode_validates(void)
{
	uint8_t ok[8] = { 0xE0, 0x03, 0x00, 0x7F, 0, 0, 0, 0 };
	uint8_t d[8];
	gw_netind ni;

	TEST_ASSERT_TRUE(gw_netind_is(ok));
	TEST_ASSERT_EQUAL_HEX32(0, gw_netind_decode(ok, &ni));
	TEST_ASSERT_EQUAL(3, ni.net);
	TEST_ASSERT_EQUAL(127, ni.node);

	memcpy(d, ok, 8);
	d[0] = 0xE4; /* cs 7 with stray bits */
	TEST_ASSERT_TRUE(gw_netind_is(d));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_CMD, gw_netind_decode(d, &ni));
	memcpy(d, ok, 8);
	d[6] = 1;
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_CMD, gw_netind_decode(d, &ni));
	memcpy(d, ok, 8);
	d[1] = 0; /* network 0 */
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, gw_netind_decode(d, &ni));
	d[1] = 128;
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, gw_netind_decode(d, &ni));
	d[1] = 3;
	d[2] = 1; /* network 259 */
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, gw_netind_decode(d, &ni));
	TEST_ASSERT_EQUAL(259, ni.net); /* bytes kept for the abort frame */
	memcpy(d, ok, 8);
	d[3] = 0;
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NO_ANSWER, gw_netind_decode(d, &ni));
	d[3] = 128;
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NO_ANSWER, gw_netind_decode(d, &ni));
	d[0] = 0x40;
	TEST_ASSERT_FALSE(gw_netind_is(d));
}

static void test_route_entry_encoding(void)
{
	gw_route_entry e;

	TEST_ASSERT_EQUAL_HEX32(0x00000002, gw_route_entry_encode((gw_route_entry){ true, 1, 0 }));
	TEST_ASSERT_EQUAL_HEX32(0x00000A01, gw_route_entry_encode((gw_route_entry){ true, 0, 10 }));
	TEST_ASSERT_EQUAL_HEX32(0, gw_route_entry_encode((gw_route_entry){ false, 3, 9 }));

	TEST_ASSERT_EQUAL_HEX32(0, gw_route_entry_decode(0x00000A03, 3, &e));
	TEST_ASSERT_TRUE(e.reachable);
	TEST_ASSERT_EQUAL(2, e.line);
	TEST_ASSERT_EQUAL(10, e.router);
	TEST_ASSERT_EQUAL_HEX32(0, gw_route_entry_decode(0, 3, &e));
	TEST_ASSERT_FALSE(e.reachable);
	/* line 4 of a 3-line daemon, reserved bits, router 128, router alone */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, gw_route_entry_decode(0x00000004, 3, &e));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, gw_route_entry_decode(0x00010001, 3, &e));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, gw_route_entry_decode(0x00008001, 3, &e));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, gw_route_entry_decode(0x00000500, 3, &e));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, gw_route_entry_check(0x00000004, 3));
	TEST_ASSERT_EQUAL_HEX32(0, gw_route_entry_check(0x00000003, 3));
}

static void test_emcy_bits_and_forwarded_frame(void)
{
	uint8_t d[8];
	gw_emcy_fwd in = { .err_reg = 0x11, .src_net = 1, .src_node = 7, .code = 0x8130 };
	gw_emcy_fwd out;

	TEST_ASSERT_TRUE(gw_emcy_route_has(0x2, 2));
	TEST_ASSERT_FALSE(gw_emcy_route_has(0x2, 1));
	TEST_ASSERT_TRUE(gw_emcy_route_has(0x80000000u, 32));
	TEST_ASSERT_FALSE(gw_emcy_route_has(0xFFFFFFFFu, 33));
	TEST_ASSERT_FALSE(gw_emcy_route_has(0xFFFFFFFFu, 0));

	gw_emcy_fwd_encode(d, &in);
	hex_eq("00 F0 11 01 00 07 30 81", d);
	TEST_ASSERT_EQUAL(0, gw_emcy_fwd_decode(d, &out));
	TEST_ASSERT_EQUAL(in.err_reg, out.err_reg);
	TEST_ASSERT_EQUAL(in.src_net, out.src_net);
	TEST_ASSERT_EQUAL(in.src_node, out.src_node);
	TEST_ASSERT_EQUAL_HEX16(in.code, out.code);
	d[1] = 0x81;
	TEST_ASSERT_EQUAL(-EINVAL, gw_emcy_fwd_decode(d, &out));
}

/* Three lines; line 0's table: net 2 on line 1, net 3 on line 2, net 9
 * through router 0x20 on line 2, net 1 (our own) on line 0. */
static void three_line_table(gw_route_table *t)
{
	uint32_t raw[GW_NET_MAX + 1] = { 0 };

	raw[1] = 0x01;
	raw[2] = 0x02;
	raw[3] = 0x03;
	raw[9] = 0x2003;
	raw[10] = 0x07; /* line 7 does not exist: unreachable, counted */
	gw_route_table_init(t, 0, 3);
	gw_route_table_compile(t, raw);
}

static void test_route_resolve(void)
{
	gw_route_table t;
	gw_hop h;

	three_line_table(&t);
	TEST_ASSERT_EQUAL(1, t.compiles);
	TEST_ASSERT_EQUAL(1, t.bad_entries);
	TEST_ASSERT_EQUAL_HEX32(0, gw_route_resolve(&t, 2, 5, 0, &h));
	TEST_ASSERT_EQUAL(1, h.line);
	TEST_ASSERT_EQUAL(5, h.node);
	TEST_ASSERT_FALSE(h.via_router);
	TEST_ASSERT_EQUAL_HEX32(0, gw_route_resolve(&t, 9, 5, 0, &h));
	TEST_ASSERT_EQUAL(2, h.line);
	TEST_ASSERT_EQUAL(0x20, h.node);
	TEST_ASSERT_TRUE(h.via_router);
	/* unknown, out of range, broken entry */
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, gw_route_resolve(&t, 4, 5, 0, &h));
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, gw_route_resolve(&t, 0, 5, 0, &h));
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, gw_route_resolve(&t, 300, 5, 0, &h));
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, gw_route_resolve(&t, 10, 5, 0, &h));
	/* back where it came from: from line 0 to net 1 (line 0); from line 2
	 * to net 9 (router on line 2); a mailbox client (-1) may use both */
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, gw_route_resolve(&t, 1, 5, 0, &h));
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, gw_route_resolve(&t, 9, 5, 2, &h));
	TEST_ASSERT_EQUAL_HEX32(0, gw_route_resolve(&t, 1, 5, -1, &h));
	TEST_ASSERT_EQUAL(0, h.line);
	TEST_ASSERT_EQUAL_UINT64(1, t.r[1].count[GW_OUT_REFUSED]);
	TEST_ASSERT_EQUAL_UINT64(1, t.r[4].count[GW_OUT_REFUSED]);
	TEST_ASSERT_EQUAL_UINT64(1, t.r[9].count[GW_OUT_REFUSED]);
	TEST_ASSERT_EQUAL_STRING("router", gw_route_kind_to_string(GW_ROUTE_ROUTER));
	TEST_ASSERT_EQUAL_STRING("timed-out", gw_route_outcome_to_string(GW_OUT_TIMED_OUT));
}

static void test_route_counters_survive_recompile_of_unchanged_routes(void)
{
	gw_route_table t;
	uint32_t raw[GW_NET_MAX + 1] = { 0 };

	three_line_table(&t);
	gw_route_count(&t, 2, GW_OUT_ROUTED);
	gw_route_count(&t, 3, GW_OUT_ABORTED);
	gw_route_count(&t, 3, GW_OUT_TIMED_OUT);
	gw_route_count(&t, 200, GW_OUT_ROUTED); /* ignored */
	raw[1] = 0x01;
	raw[2] = 0x02;
	raw[3] = 0x0A01; /* net 3 now through router 10 on line 0 */
	gw_route_table_compile(&t, raw);
	TEST_ASSERT_EQUAL(2, t.compiles);
	TEST_ASSERT_EQUAL_UINT64(1, t.r[2].count[GW_OUT_ROUTED]);
	TEST_ASSERT_EQUAL_UINT64(0, t.r[3].count[GW_OUT_ABORTED]);
	TEST_ASSERT_EQUAL(GW_ROUTE_ROUTER, t.r[3].kind);
	TEST_ASSERT_EQUAL(GW_ROUTE_NONE, t.r[9].kind);
}

static void test_route_compile_from_od(void)
{
	co_od *od;
	gw_route_table t;
	gw_hop h;

	TEST_ASSERT_EQUAL(0, co_od_create(&od, 8));
	TEST_ASSERT_EQUAL(0,
			  co_od_add_array(od, GW_OBJ_ROUTES, CO_T_UNSIGNED32, 127, CO_ACC_RW, 0));
	TEST_ASSERT_EQUAL(0, co_od_set_u32(od, GW_OBJ_ROUTES, 5, 0x0302));
	gw_route_table_init(&t, 0, 2);
	gw_route_table_compile_od(&t, od);
	TEST_ASSERT_EQUAL_HEX32(0, gw_route_resolve(&t, 5, 9, 0, &h));
	TEST_ASSERT_EQUAL(1, h.line);
	TEST_ASSERT_EQUAL(3, h.node);
	co_od_destroy(od);
}

static void test_emcy_plan(void)
{
	gw_route_table t;
	gw_emcy_plan p;

	three_line_table(&t);
	/* nets 2 and 3: lines 1 and 2 */
	TEST_ASSERT_EQUAL_HEX16(0x6, gw_emcy_route_plan(&t, (1u << 1) | (1u << 2), &p));
	/* net 9 through the router on line 2, and net 3 on line 2: once */
	TEST_ASSERT_EQUAL_HEX16(0x4, gw_emcy_route_plan(&t, (1u << 8) | (1u << 2), &p));
	/* own network (line 0) is never echoed; net 4 is unknown */
	TEST_ASSERT_EQUAL_HEX16(0, gw_emcy_route_plan(&t, (1u << 0) | (1u << 3), &p));
	TEST_ASSERT_EQUAL(1, p.loops);
	TEST_ASSERT_EQUAL(1, p.unknown);
	TEST_ASSERT_EQUAL_HEX16(0, gw_emcy_route_plan(&t, 0, &p));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_netind_golden_frames);
	RUN_TEST(test_netind_decode_validates);
	RUN_TEST(test_route_entry_encoding);
	RUN_TEST(test_emcy_bits_and_forwarded_frame);
	RUN_TEST(test_route_resolve);
	RUN_TEST(test_route_counters_survive_recompile_of_unchanged_routes);
	RUN_TEST(test_route_compile_from_od);
	RUN_TEST(test_emcy_plan);
	return UNITY_END();
}
