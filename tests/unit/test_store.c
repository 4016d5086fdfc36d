/* SPDX-License-Identifier: MIT */
/*
 * Store/restore hooks, 1010h/1011h: signatures, capability reads, the
 * backend's answer on the wire (immediate and deferred), events.
 */
#include <errno.h>
#include <string.h>

#include "unity.h"

#include "core/co.h"
#include "core/sdo_server.h"
#include "core/store.h"
#include "tests/unit/support/test_bus.h"
#include "tests/unit/support/test_od_fixture.h"

static tb_bus bus;
static tb_port *p;

struct backend {
	int saves, restores;
	uint8_t last_sub;
	uint32_t answer;
};

static uint32_t be_save(void *ctx, uint8_t sub, const co_od_access *a)
{
	struct backend *b = ctx;
	(void)a;
	b->saves++;
	b->last_sub = sub;
	return b->answer;
}

static uint32_t be_restore(void *ctx, uint8_t sub, const co_od_access *a)
{
	struct backend *b = ctx;
	(void)a;
	b->restores++;
	b->last_sub = sub;
	return b->answer;
}

static const co_store_ops ops = { .save = be_save, .restore = be_restore };
static struct backend be;

void setUp(void)
{
	co_node_config cfg = { .node_id = 1 };

	memset(&be, 0, sizeof(be));
	tb_init(&bus);
	p = tb_add_node(&bus, &cfg, fx_od_new());
	TEST_ASSERT_NOT_NULL(p);
	TEST_ASSERT_EQUAL(
		0, co_store_attach(p->node, &ops, &be, 4, CO_STORE_CAP_CMD, CO_STORE_CAP_CMD));
}

void tearDown(void)
{
	tb_fini(&bus);
}

#define REQ(hex) tb_send_hex(&bus, 0x601, hex)
#define EXPECT(hex) TB_ASSERT_LAST(&bus, 0, 0x581, hex)

static void test_objects_created_and_reads_return_capabilities(void)
{
	REQ("40 10 10 00 00 00 00 00");
	EXPECT("4F 10 10 00 04 00 00 00");
	REQ("40 10 10 01 00 00 00 00");
	EXPECT("43 10 10 01 01 00 00 00");
	REQ("40 11 10 04 00 00 00 00");
	EXPECT("43 11 10 04 01 00 00 00");
	REQ("40 11 10 05 00 00 00 00");
	EXPECT("80 11 10 05 11 00 09 06");
	TEST_ASSERT_EQUAL(-EEXIST, co_store_attach(p->node, &ops, &be, 4, 1, 1));
}

static void test_save_and_load_signatures(void)
{
	REQ("23 10 10 02 73 61 76 65"); /* "save" comm parameters */
	EXPECT("60 10 10 02 00 00 00 00");
	TEST_ASSERT_EQUAL(1, be.saves);
	TEST_ASSERT_EQUAL(2, be.last_sub);
	const co_event *ev = tb_last_event(p, CO_EV_STORE);
	TEST_ASSERT_NOT_NULL(ev);
	TEST_ASSERT_EQUAL_HEX16(0x1010, ev->u.store.index);
	TEST_ASSERT_EQUAL(2, ev->u.store.sub);
	REQ("40 10 10 02 00 00 00 00"); /* the value is still the capability */
	EXPECT("43 10 10 02 01 00 00 00");

	REQ("23 11 10 01 6C 6F 61 64"); /* "load" */
	EXPECT("60 11 10 01 00 00 00 00");
	TEST_ASSERT_EQUAL(1, be.restores);
	TEST_ASSERT_EQUAL(1, tb_event_count(p, CO_EV_RESTORE));
}

static void test_wrong_signatures_refused(void)
{
	REQ("23 10 10 01 6C 6F 61 64"); /* "load" to 1010h */
	EXPECT("80 10 10 01 20 00 00 08");
	REQ("23 11 10 01 73 61 76 65"); /* "save" to 1011h */
	EXPECT("80 11 10 01 20 00 00 08");
	REQ("23 10 10 01 65 76 61 73"); /* byte order of the printed sheet */
	EXPECT("80 10 10 01 20 00 00 08");
	REQ("2B 10 10 01 73 61 00 00"); /* too short */
	EXPECT("80 10 10 01 13 00 07 06");
	TEST_ASSERT_EQUAL(0, be.saves + be.restores);
	TEST_ASSERT_EQUAL(0, tb_event_count(p, CO_EV_STORE));
}

static void test_backend_refusal_and_deferred_answer(void)
{
	be.answer = 0x08000020;
	REQ("23 10 10 01 73 61 76 65");
	EXPECT("80 10 10 01 20 00 00 08");
	be.answer = CO_OD_DEFERRED; /* e.g. a flash write that takes a while */
	size_t n = tb_count_from_id(&bus, 0, 0x581, 0);
	REQ("23 10 10 01 73 61 76 65");
	TEST_ASSERT_EQUAL(n, tb_count_from_id(&bus, 0, 0x581, 0));
	tb_advance(&bus, 300000);
	TEST_ASSERT_EQUAL(0, sdo_server_continue(p->node, 0, 0, NULL, 0, bus.now));
	tb_pump(&bus);
	EXPECT("60 10 10 01 00 00 00 00");
	REQ("40 10 10 01 00 00 00 00");
	EXPECT("43 10 10 01 01 00 00 00");
}

static void test_reset_comm_keeps_capabilities(void)
{
	co_node_reset_comm(p->node, bus.now);
	REQ("40 10 10 03 00 00 00 00");
	EXPECT("43 10 10 03 01 00 00 00");
}

static void test_attach_to_configured_objects(void)
{
	tb_fini(&bus);
	tb_init(&bus);
	co_node_config cfg = { .node_id = 1 };
	co_od *od = fx_od_new();
	/* The configuration created 1010h with two subs and no 1011h. */
	co_od_add_num(od, 0x1010, 0, CO_T_UNSIGNED8, CO_ACC_RO, 2, NULL);
	co_od_add_num(od, 0x1010, 1, CO_T_UNSIGNED32, CO_ACC_RW, 0, NULL);
	co_od_add_num(od, 0x1010, 2, CO_T_UNSIGNED32, CO_ACC_RW, 0, NULL);
	p = tb_add_node(&bus, &cfg, od);
	TEST_ASSERT_EQUAL(0, co_store_attach(p->node, NULL, NULL, 1,
					     CO_STORE_CAP_CMD | CO_STORE_CAP_AUTO, 0));
	REQ("40 10 10 02 00 00 00 00");
	EXPECT("43 10 10 02 03 00 00 00");
	REQ("40 11 10 00 00 00 00 00");
	EXPECT("4F 11 10 00 01 00 00 00");
	REQ("23 10 10 02 73 61 76 65"); /* no backend: accepted, event only */
	EXPECT("60 10 10 02 00 00 00 00");
	TEST_ASSERT_EQUAL(1, tb_event_count(p, CO_EV_STORE));
	TEST_ASSERT_EQUAL(-EINVAL, co_store_attach(p->node, NULL, NULL, 0, 1, 1));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_objects_created_and_reads_return_capabilities);
	RUN_TEST(test_save_and_load_signatures);
	RUN_TEST(test_wrong_signatures_refused);
	RUN_TEST(test_backend_refusal_and_deferred_answer);
	RUN_TEST(test_reset_comm_keeps_capabilities);
	RUN_TEST(test_attach_to_configured_objects);
	return UNITY_END();
}
