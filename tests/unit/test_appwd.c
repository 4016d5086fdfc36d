/* SPDX-License-Identifier: MIT */
/* The application watchdog's table and its reactions on the node
 * (core/appwd.h): declaration rules, arming at the first keep-alive,
 * deadlines to the microsecond, owners that leave, and the frames of the
 * EMCY, heartbeat-stop and safe-output reactions. */
#include <errno.h>
#include <string.h>

#include "core/appwd.h"
#include "core/emcy.h"
#include "core/heartbeat.h"
#include "core/nmt.h"
#include "core/od.h"
#include "core/pdo.h"
#include "tests/unit/support/errctrl_fixture.h"
#include "unity.h"

#define ID 5
#define MS 1000u

static co_appwd wd;
static ecf x;
static bool booted;

void setUp(void)
{
	co_appwd_init(&wd);
	booted = false;
}

void tearDown(void)
{
	if (booted)
		ecf_destroy(&x);
}

static void test_reaction_sets(void)
{
	TEST_ASSERT_TRUE(co_appwd_reactions_valid(CO_APPWD_EMCY));
	TEST_ASSERT_TRUE(co_appwd_reactions_valid(CO_APPWD_EMCY | CO_APPWD_NMT_STOP |
						  CO_APPWD_HB_STOP | CO_APPWD_SAFE_OUTPUTS));
	TEST_ASSERT_FALSE(co_appwd_reactions_valid(0));
	TEST_ASSERT_FALSE(co_appwd_reactions_valid(1u << 7));
	TEST_ASSERT_FALSE(co_appwd_reactions_valid(CO_APPWD_NMT_STOP | CO_APPWD_NMT_PREOP));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_CS_ENTER_PREOP, co_appwd_nmt_cs(CO_APPWD_NMT_PREOP));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_CS_STOP, co_appwd_nmt_cs(CO_APPWD_NMT_STOP));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_CS_RESET_COMM, co_appwd_nmt_cs(CO_APPWD_NMT_RESET_COMM));
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_CS_RESET_NODE, co_appwd_nmt_cs(CO_APPWD_NMT_RESET_NODE));
	TEST_ASSERT_EQUAL_HEX8(0, co_appwd_nmt_cs(CO_APPWD_EMCY));
	TEST_ASSERT_EQUAL_STRING("tripped", co_appwd_state_to_string(CO_APPWD_TRIPPED));
}

static void test_declare_bounds_and_table(void)
{
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_appwd_declare(&wd, 1, 10, 9, CO_APPWD_EMCY));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_appwd_declare(&wd, 1, 10, 60001, CO_APPWD_EMCY));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_appwd_declare(&wd, 1, 10, 100, 0));
	TEST_ASSERT_EQUAL_INT(-ENOENT, co_appwd_declare(&wd, 1, 10, 0, 0));
	for (uint32_t c = 1; c <= CO_APPWD_MAX; c++)
		TEST_ASSERT_EQUAL_INT(0, co_appwd_declare(&wd, c, 10, 100, CO_APPWD_EMCY));
	TEST_ASSERT_EQUAL_INT(-ENOSPC, co_appwd_declare(&wd, 99, 10, 100, CO_APPWD_EMCY));
	/* declaring again replaces, it takes no second entry */
	TEST_ASSERT_EQUAL_INT(0, co_appwd_declare(&wd, 2, 10, 200, CO_APPWD_HB_STOP));
	TEST_ASSERT_EQUAL_UINT32(200, co_appwd_find(&wd, 2)->interval_ms);
	TEST_ASSERT_EQUAL_INT(0, co_appwd_declare(&wd, 2, 10, 0, 0));
	TEST_ASSERT_NULL(co_appwd_find(&wd, 2));
	TEST_ASSERT_EQUAL_INT(0, co_appwd_declare(&wd, 99, 10, 100, CO_APPWD_EMCY));
	TEST_ASSERT_EQUAL_UINT64(4, wd.stats.refused);
}

/* Declared is not armed: no deadline until the first keep-alive, then
 * each keep-alive moves it; the trip comes at the deadline, not before,
 * and only once. */
static void test_armed_at_first_keepalive(void)
{
	co_appwd_entry fired[CO_APPWD_MAX];

	TEST_ASSERT_EQUAL_INT(-ENOENT, co_appwd_keepalive(&wd, 7, 0));
	TEST_ASSERT_EQUAL_INT(0, co_appwd_declare(&wd, 7, 70, 100, CO_APPWD_EMCY));
	TEST_ASSERT_EQUAL_UINT64(CO_NO_DEADLINE, co_appwd_next_deadline(&wd));
	TEST_ASSERT_EQUAL_size_t(0, co_appwd_poll(&wd, 10000000u, fired, CO_APPWD_MAX));
	TEST_ASSERT_EQUAL_INT(0, co_appwd_keepalive(&wd, 7, 1000000u));
	TEST_ASSERT_EQUAL_UINT64(1100000u, co_appwd_next_deadline(&wd));
	TEST_ASSERT_EQUAL_INT(0, co_appwd_keepalive(&wd, 7, 1050000u));
	TEST_ASSERT_EQUAL_UINT64(1150000u, co_appwd_next_deadline(&wd));
	TEST_ASSERT_EQUAL_size_t(0, co_appwd_poll(&wd, 1149999u, fired, CO_APPWD_MAX));
	TEST_ASSERT_EQUAL_size_t(1, co_appwd_poll(&wd, 1150000u, fired, CO_APPWD_MAX));
	TEST_ASSERT_EQUAL_UINT32(7, fired[0].owner);
	TEST_ASSERT_EQUAL_UINT32(70, fired[0].pid);
	TEST_ASSERT_EQUAL_UINT64(1150000u, fired[0].deadline_us);
	TEST_ASSERT_EQUAL_size_t(0, co_appwd_poll(&wd, 9000000u, fired, CO_APPWD_MAX));
	TEST_ASSERT_EQUAL_UINT64(CO_NO_DEADLINE, co_appwd_next_deadline(&wd));
	TEST_ASSERT_TRUE(co_appwd_any_tripped(&wd));
	/* a keep-alive after the trip renews nothing: the owner declares again */
	TEST_ASSERT_EQUAL_INT(-ESTALE, co_appwd_keepalive(&wd, 7, 9000000u));
	TEST_ASSERT_EQUAL_UINT64(1, wd.stats.late_keepalives);
	TEST_ASSERT_EQUAL_INT(0, co_appwd_declare(&wd, 7, 70, 100, CO_APPWD_EMCY));
	TEST_ASSERT_FALSE(co_appwd_any_tripped(&wd));
	TEST_ASSERT_EQUAL_INT(0, co_appwd_keepalive(&wd, 7, 9000000u));
	TEST_ASSERT_EQUAL_UINT64(9100000u, co_appwd_next_deadline(&wd));
	TEST_ASSERT_EQUAL_UINT64(1, wd.stats.trips);
}

/* An owner that leaves: armed, it still trips at its deadline (a killed
 * process tells nobody) and its entry is freed then; declared only, it is
 * freed at once. A new client of the same process is another owner. */
static void test_owner_gone(void)
{
	co_appwd_entry fired[CO_APPWD_MAX];

	TEST_ASSERT_EQUAL_INT(0, co_appwd_declare(&wd, 1, 11, 100, CO_APPWD_EMCY));
	TEST_ASSERT_EQUAL_INT(0, co_appwd_declare(&wd, 2, 12, 100, CO_APPWD_EMCY));
	TEST_ASSERT_EQUAL_INT(0, co_appwd_keepalive(&wd, 1, 0));
	co_appwd_owner_gone(&wd, 1);
	co_appwd_owner_gone(&wd, 2);
	TEST_ASSERT_NULL(co_appwd_find(&wd, 2));
	TEST_ASSERT_NULL(co_appwd_find(&wd, 1)); /* gone: not its own any more */
	TEST_ASSERT_EQUAL_UINT64(100000u, co_appwd_next_deadline(&wd));
	TEST_ASSERT_EQUAL_size_t(1, co_appwd_poll(&wd, 100000u, fired, CO_APPWD_MAX));
	TEST_ASSERT_TRUE(fired[0].gone);
	TEST_ASSERT_FALSE(co_appwd_any_tripped(&wd));
	for (unsigned i = 0; i < CO_APPWD_MAX; i++)
		TEST_ASSERT_EQUAL_UINT8(CO_APPWD_FREE, wd.e[i].state);
}

/* Several entries due at once, more than the caller takes: the rest trip
 * at the next call. */
static void test_poll_cap(void)
{
	co_appwd_entry fired[1];

	for (uint32_t c = 1; c <= 3; c++) {
		TEST_ASSERT_EQUAL_INT(0, co_appwd_declare(&wd, c, c, 10, CO_APPWD_EMCY));
		TEST_ASSERT_EQUAL_INT(0, co_appwd_keepalive(&wd, c, 0));
	}
	TEST_ASSERT_EQUAL_size_t(1, co_appwd_poll(&wd, 20000u, fired, 1));
	TEST_ASSERT_EQUAL_size_t(1, co_appwd_poll(&wd, 20000u, fired, 1));
	TEST_ASSERT_EQUAL_size_t(1, co_appwd_poll(&wd, 20000u, fired, 1));
	TEST_ASSERT_EQUAL_size_t(0, co_appwd_poll(&wd, 20000u, fired, 1));
}

/* ---- reactions on a node ----------------------------------------------- */

/* A node with 2000h:01 (U16) and 2000h:02 (U8), both mapped by TPDO 1
 * (18Bh, event-driven), and 2001h:00 mapped by nothing. */
static void boot_node(void)
{
	co_od *od = ecf_od_std(ID);
	static const uint32_t map[] = { 0x20000110u, 0x20000208u };
	co_pdo_desc t = { .dir = CO_PDO_TX,
			  .nr = 1,
			  .cob_id = 0x180u + ID,
			  .tt = 254,
			  .map_subs = 2,
			  .n_map = 2,
			  .map = map };
	TEST_ASSERT_EQUAL_INT(0, co_od_add_num(od, 0x2000, 1, CO_T_UNSIGNED16,
					       CO_ACC_RW | CO_ACC_TPDO, 0x1234, NULL));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_num(od, 0x2000, 2, CO_T_UNSIGNED8,
					       CO_ACC_RW | CO_ACC_TPDO, 0x56, NULL));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_num(od, 0x2001, 0, CO_T_UNSIGNED8, CO_ACC_RW, 1, NULL));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_pdo(od, &t));
	ecf_create(&x, ID, od);
	booted = true;
	ecf_advance(&x, 0);
	TEST_ASSERT_EQUAL_INT(0, co_nmt_local_cmd(x.node, CO_NMT_CS_START, 0));
	TEST_ASSERT_EQUAL_INT(0, co_hb_producer_set(x.node, 100, 0));
	ecf_clear(&x);
}

static const co_safe_output outs[] = {
	{ .index = 0x2000, .sub = 1, .len = 2, .value = { 0x00, 0x00 } },
	{ .index = 0x2000, .sub = 2, .len = 1, .value = { 0xAA } },
	{ .index = 0x2001, .sub = 0, .len = 1, .value = { 0x00 } },
	{ .index = 0x2FFF, .sub = 0, .len = 1, .value = { 0x00 } }, /* no such object */
};

/* The EMCY reaction is the golden frame 80h+id [00 62 81 00 00 00 00 00];
 * the safe values are in the OD and TPDO 1 left with both, before
 * the EMCY; acknowledging sends the error reset. */
static void test_react_emcy_and_safe_outputs(void)
{
	static const uint8_t emcy[8] = { 0x00, 0x62, 0x81, 0, 0, 0, 0, 0 };
	static const uint8_t reset[8] = { 0x00, 0x00, 0x00, 0, 0, 0, 0, 0 };
	static const uint8_t tpdo[3] = { 0x00, 0x00, 0xAA };
	co_appwd_effects fx = { 0 };
	uint16_t v16 = 0;

	boot_node();
	uint32_t done = co_appwd_react(x.node, CO_APPWD_EMCY | CO_APPWD_SAFE_OUTPUTS, outs, 4, &fx,
				       10 * MS);
	TEST_ASSERT_EQUAL_HEX32(CO_APPWD_EMCY | CO_APPWD_SAFE_OUTPUTS, done);
	TEST_ASSERT_EQUAL_INT(0, co_od_get_u16(x.od, 0x2000, 1, &v16));
	TEST_ASSERT_EQUAL_HEX16(0, v16);
	/* triggered once per safe output it maps, the first frame with both */
	TEST_ASSERT_EQUAL_UINT(2, ecf_tx_count(&x, 0x180 + ID));
	TEST_ASSERT_EQUAL_UINT(1, ecf_tx_count(&x, 0x80 + ID));
	int p = ecf_tx_find(&x, 0, 0x180 + ID), e = ecf_tx_find(&x, 0, 0x80 + ID);
	TEST_ASSERT_TRUE(p >= 0 && e > p);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(tpdo, x.tx[p].data, 3);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(emcy, x.tx[e].data, 8);
	TEST_ASSERT_TRUE(fx.emcy);

	ecf_clear(&x);
	co_appwd_acknowledge(x.node, &fx, 20 * MS);
	ecf_advance(&x, 20 * MS);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(reset, ecf_tx_last(&x, 0x80 + ID)->data, 8);
	TEST_ASSERT_FALSE(fx.emcy);
}

/* HB_STOP: no heartbeat after the trip; acknowledged, 1017h is what it was
 * and the heartbeats come again. */
static void test_react_heartbeat_stop(void)
{
	co_appwd_effects fx = { 0 };
	uint16_t ms = 0;

	boot_node();
	ecf_advance(&x, 250 * MS);
	TEST_ASSERT_TRUE(ecf_tx_count(&x, 0x700 + ID) >= 2);
	TEST_ASSERT_EQUAL_HEX32(CO_APPWD_HB_STOP,
				co_appwd_react(x.node, CO_APPWD_HB_STOP, NULL, 0, &fx, 250 * MS));
	ecf_clear(&x);
	ecf_advance(&x, 1000 * MS);
	TEST_ASSERT_EQUAL_UINT(0, ecf_tx_count(&x, 0x700 + ID));
	/* a second trip keeps the value saved by the first */
	co_appwd_react(x.node, CO_APPWD_HB_STOP, NULL, 0, &fx, 1000 * MS);
	co_appwd_acknowledge(x.node, &fx, 1000 * MS);
	TEST_ASSERT_EQUAL_INT(0, co_od_get_u16(x.od, 0x1017, 0, &ms));
	TEST_ASSERT_EQUAL_UINT16(100, ms);
	ecf_advance(&x, 1250 * MS);
	TEST_ASSERT_TRUE(ecf_tx_count(&x, 0x700 + ID) >= 2);
}

/* Safe outputs outside OPERATIONAL: the values are written, no PDO goes
 * (CiA 301: PDOs only in OPERATIONAL). */
static void test_safe_outputs_preoperational(void)
{
	uint8_t v = 0;

	boot_node();
	TEST_ASSERT_EQUAL_INT(0, co_nmt_local_cmd(x.node, CO_NMT_CS_ENTER_PREOP, 0));
	ecf_clear(&x);
	TEST_ASSERT_EQUAL_size_t(3, co_appwd_safe_outputs_apply(x.node, outs, 4, 5 * MS));
	TEST_ASSERT_EQUAL_INT(0, co_od_get_u8(x.od, 0x2000, 2, &v));
	TEST_ASSERT_EQUAL_HEX8(0xAA, v);
	TEST_ASSERT_EQUAL_UINT(0, ecf_tx_count(&x, 0x180 + ID));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_reaction_sets);
	RUN_TEST(test_declare_bounds_and_table);
	RUN_TEST(test_armed_at_first_keepalive);
	RUN_TEST(test_owner_gone);
	RUN_TEST(test_poll_cap);
	RUN_TEST(test_react_emcy_and_safe_outputs);
	RUN_TEST(test_react_heartbeat_stop);
	RUN_TEST(test_safe_outputs_preoperational);
	return UNITY_END();
}
