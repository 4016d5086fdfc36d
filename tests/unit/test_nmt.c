/* SPDX-License-Identifier: MIT */
/* NMT slave state machine, NMT master with 102Ah, 1029h error behaviour,
 * bus-off reaction (CiA 301 §7.3.2, §7.5.2.32, §7.5.2.33). */
#include <errno.h>
#include <string.h>

#include "core/commfault.h"
#include "core/emcy.h"
#include "core/heartbeat.h"
#include "core/nmt.h"
#include "tests/unit/support/errctrl_fixture.h"
#include "unity.h"

#define ID 5
#define HB_COB (0x700 + ID)

static ecf x;

void setUp(void) {}
void tearDown(void)
{
	ecf_destroy(&x);
}

static void nmt_cmd(uint8_t cs, uint8_t target)
{
	uint8_t d[2] = { cs, target };
	ecf_rx(&x, 0x000, 0, 2, d);
}

static void assert_frame1(const co_frame *f, uint32_t id, uint8_t b0)
{
	TEST_ASSERT_EQUAL_HEX32(id, f->id);
	TEST_ASSERT_EQUAL_UINT8(1, f->len);
	TEST_ASSERT_EQUAL_UINT8(0, f->flags);
	TEST_ASSERT_EQUAL_HEX8(b0, f->data[0]);
}

/* Boot-up [00] on 700h+id at start, and after every reset comm. */
static void test_bootup_at_start(void)
{
	ecf_create(&x, ID, NULL);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_INITIALISING, co_nmt_get_state(x.node));
	TEST_ASSERT_EQUAL_UINT(0, x.n_tx); /* nothing before the first tick */
	TEST_ASSERT_EQUAL_UINT64(0, co_node_next_deadline_us(x.node));
	co_node_tick(x.node, 0);
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	assert_frame1(&x.tx[0], HB_COB, 0x00);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));
	int e = ecf_ev_find(&x, 0, CO_EV_NMT_STATE);
	TEST_ASSERT_TRUE(e >= 0);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_INITIALISING, x.ev.ev[e].u.nmt.prev);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, x.ev.ev[e].u.nmt.state);
	/* A second tick does not boot again. */
	co_node_tick(x.node, 10);
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
}

static void test_bootup_after_reset_comm_command(void)
{
	ecf_boot(&x, ID);
	nmt_cmd(CO_NMT_CS_START, ID);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_OPERATIONAL, co_nmt_get_state(x.node));
	ecf_clear(&x);
	nmt_cmd(CO_NMT_CS_RESET_COMM, 0);
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	assert_frame1(&x.tx[0], HB_COB, 0x00);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));
	/* OP -> INIT (cause 82h) -> PRE-OP */
	TEST_ASSERT_EQUAL_UINT(2, ecf_ev_count(&x, CO_EV_NMT_STATE));
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_INITIALISING, x.ev.ev[0].u.nmt.state);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_CS_RESET_COMM, x.ev.ev[0].u.nmt.cs);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, x.ev.ev[1].u.nmt.state);
}

/* A reset command while still INITIALISING (before the first tick)
 * resets and boots; the state it was in is not announced again: one
 * event, INITIALISING -> PRE-OPERATIONAL. */
static void test_reset_while_initialising_announces_only_the_boot(void)
{
	ecf_create(&x, ID, NULL);
	nmt_cmd(CO_NMT_CS_RESET_COMM, 0);
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	assert_frame1(&x.tx[0], HB_COB, 0x00);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&x, CO_EV_NMT_STATE));
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_INITIALISING, x.ev.ev[0].u.nmt.prev);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, x.ev.ev[0].u.nmt.state);
}

/* The application resetting communication itself: the boot-up follows at
 * the next tick, after every service has reset. */
static void test_bootup_after_app_reset_comm(void)
{
	ecf_boot(&x, ID);
	x.now = 1000;
	co_node_reset_comm(x.node, x.now);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_INITIALISING, co_nmt_get_state(x.node));
	TEST_ASSERT_EQUAL_UINT(0, x.n_tx);
	TEST_ASSERT_TRUE(co_node_next_deadline_us(x.node) <= 1000);
	ecf_advance(&x, 1000);
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	assert_frame1(&x.tx[0], HB_COB, 0x00);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));
}

/* Commands to our id and to 0 -> heartbeat byte 05/04/7F. */
static void test_commands_and_heartbeat_byte(void)
{
	ecf_boot(&x, ID);
	TEST_ASSERT_EQUAL_INT(0, co_hb_producer_set(x.node, 10, 0));
	ecf_clear(&x);

	nmt_cmd(CO_NMT_CS_START, ID);
	ecf_advance(&x, 10000);
	assert_frame1(&x.tx[x.n_tx - 1], HB_COB, CO_NMT_OPERATIONAL);

	nmt_cmd(CO_NMT_CS_STOP, 0);
	ecf_advance(&x, 20000);
	assert_frame1(&x.tx[x.n_tx - 1], HB_COB, CO_NMT_STOPPED);

	nmt_cmd(CO_NMT_CS_ENTER_PREOP, ID);
	ecf_advance(&x, 30000);
	assert_frame1(&x.tx[x.n_tx - 1], HB_COB, CO_NMT_PRE_OPERATIONAL);

	/* Another node's command, a bad length, an unknown cs: ignored. */
	nmt_cmd(CO_NMT_CS_START, ID + 1);
	uint8_t three[3] = { CO_NMT_CS_START, ID, 0 };
	ecf_rx(&x, 0x000, 0, 3, three);
	nmt_cmd(0x03, ID);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));
	TEST_ASSERT_EQUAL_UINT64(2, co_nmt_get_stats(x.node)->cmd_invalid);

	/* STOPPED ignores "stop" again and goes to OP only by start. */
	nmt_cmd(CO_NMT_CS_STOP, ID);
	nmt_cmd(CO_NMT_CS_START, 0);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_OPERATIONAL, co_nmt_get_state(x.node));
}

/* Reset comm restores the default COB-IDs (and the other 1xxxh). */
static void test_reset_comm_restores_defaults(void)
{
	ecf_boot(&x, ID);
	uint32_t v = 0;
	co_od_set_u32(x.od, 0x1014, 0, 0x80000000u | (0x80 + ID));
	co_od_set_u32(x.od, 0x1014, 0, 0x95);
	co_od_set_u16(x.od, 0x1017, 0, 250);
	co_od_add_num(x.od, 0x2000, 0, CO_T_UNSIGNED8, CO_ACC_RW, 7, NULL);
	co_od_set_u8(x.od, 0x2000, 0, 9);
	nmt_cmd(CO_NMT_CS_RESET_COMM, ID);
	co_od_get_u32(x.od, 0x1014, 0, &v);
	TEST_ASSERT_EQUAL_HEX32(0x80 + ID, v);
	uint16_t hb = 1;
	co_od_get_u16(x.od, 0x1017, 0, &hb);
	TEST_ASSERT_EQUAL_UINT16(0, hb);
	uint8_t app = 0;
	co_od_get_u8(x.od, 0x2000, 0, &app);
	TEST_ASSERT_EQUAL_UINT8(9, app); /* application area untouched */

	/* Reset node: the application area too, and a boot-up. */
	ecf_clear(&x);
	nmt_cmd(CO_NMT_CS_RESET_NODE, 0);
	co_od_get_u8(x.od, 0x2000, 0, &app);
	TEST_ASSERT_EQUAL_UINT8(7, app);
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	assert_frame1(&x.tx[0], HB_COB, 0x00);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_CS_RESET_NODE, x.ev.ev[0].u.nmt.cs);
}

/* The application vetoes OPERATIONAL -> stays PRE-OP. */
static int veto_calls;
static bool veto(void *ctx, co_node *node, uint8_t from, uint8_t to)
{
	(void)ctx;
	(void)node;
	veto_calls++;
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, from);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_OPERATIONAL, to);
	return false;
}

static void test_veto_operational(void)
{
	ecf_boot(&x, ID);
	veto_calls = 0;
	co_nmt_set_veto(x.node, veto, NULL);
	nmt_cmd(CO_NMT_CS_START, ID);
	TEST_ASSERT_EQUAL_INT(1, veto_calls);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));
	TEST_ASSERT_EQUAL_UINT(0, ecf_ev_count(&x, CO_EV_NMT_STATE));
	TEST_ASSERT_EQUAL_INT(-EPERM, co_nmt_local_cmd(x.node, CO_NMT_CS_START, 0));
	TEST_ASSERT_EQUAL_UINT64(2, co_nmt_get_stats(x.node)->vetoed);
	/* Stop is not subject to the veto. */
	nmt_cmd(CO_NMT_CS_STOP, ID);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_STOPPED, co_nmt_get_state(x.node));
	co_nmt_set_veto(x.node, NULL, NULL);
	TEST_ASSERT_EQUAL_INT(0, co_nmt_local_cmd(x.node, CO_NMT_CS_START, 0));
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_OPERATIONAL, co_nmt_get_state(x.node));
}

/* Master: 102Ah spaces NMT frames; queued, not dropped. */
static void test_master_inhibit(void)
{
	ecf_boot(&x, ID);
	co_od_set_u16(x.od, 0x102A, 0, 20); /* 2 ms */
	x.now = 1000;
	TEST_ASSERT_EQUAL_INT(0, co_nmt_master_send(x.node, 3, CO_NMT_CS_START, x.now));
	TEST_ASSERT_EQUAL_INT(0, co_nmt_master_send(x.node, 4, CO_NMT_CS_START, x.now));
	TEST_ASSERT_EQUAL_INT(0, co_nmt_master_send(x.node, 0, CO_NMT_CS_STOP, x.now));
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	TEST_ASSERT_EQUAL_UINT(2, co_nmt_master_pending(x.node));
	TEST_ASSERT_EQUAL_HEX32(0x000, x.tx[0].id);
	TEST_ASSERT_EQUAL_UINT8(2, x.tx[0].len);
	TEST_ASSERT_EQUAL_HEX8(0x01, x.tx[0].data[0]);
	TEST_ASSERT_EQUAL_HEX8(0x03, x.tx[0].data[1]);
	TEST_ASSERT_EQUAL_UINT64(3000, co_node_next_deadline_us(x.node));
	ecf_advance(&x, 2999);
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	ecf_advance(&x, 3000);
	TEST_ASSERT_EQUAL_UINT(2, x.n_tx);
	TEST_ASSERT_EQUAL_UINT64(3000, x.tx_t[1]);
	TEST_ASSERT_EQUAL_HEX8(0x04, x.tx[1].data[1]);
	ecf_advance(&x, 10000);
	TEST_ASSERT_EQUAL_UINT(3, x.n_tx);
	TEST_ASSERT_EQUAL_UINT64(5000, x.tx_t[2]);
	TEST_ASSERT_EQUAL_HEX8(0x02, x.tx[2].data[0]);
	TEST_ASSERT_EQUAL_HEX8(0x00, x.tx[2].data[1]);
	/* Without the self flag the broadcast stop did not touch us. */
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));

	/* Bounded queue: -ENOBUFS, counted. */
	for (unsigned i = 0; i <= CO_NMT_MASTER_QUEUE_LEN; i++)
		TEST_ASSERT_EQUAL_INT(0, co_nmt_master_send(x.node, 9, 1, x.now));
	TEST_ASSERT_EQUAL_INT(-ENOBUFS, co_nmt_master_send(x.node, 9, 1, x.now));
	TEST_ASSERT_EQUAL_UINT64(1, co_nmt_get_stats(x.node)->master_overflow);
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_nmt_master_send(x.node, 128, 1, x.now));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_nmt_master_send(x.node, 1, 0x03, x.now));
}

/* Master: a command to all with the self flag applies to us, after the
 * frame. */
static void test_master_self(void)
{
	ecf_boot(&x, ID);
	TEST_ASSERT_EQUAL_INT(
		0, co_nmt_master_send_ex(x.node, 0, CO_NMT_CS_START, CO_NMT_SEND_SELF, 0));
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_OPERATIONAL, co_nmt_get_state(x.node));
	TEST_ASSERT_EQUAL_HEX8(0x01, x.tx[0].data[0]);
	/* Reset comm to all incl. us: the NMT frame, then our boot-up. */
	ecf_clear(&x);
	co_nmt_master_send_ex(x.node, 0, CO_NMT_CS_RESET_COMM, CO_NMT_SEND_SELF, 0);
	TEST_ASSERT_EQUAL_UINT(2, x.n_tx);
	TEST_ASSERT_EQUAL_HEX32(0x000, x.tx[0].id);
	assert_frame1(&x.tx[1], HB_COB, 0x00);
	/* Self flag with one target only: not applied to us. */
	co_nmt_master_send_ex(x.node, 7, CO_NMT_CS_STOP, CO_NMT_SEND_SELF, 0);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));
}

/* 1029h:1 on a communication error. */
static void test_error_behaviour(void)
{
	ecf_boot(&x, ID);
	/* 0: PRE-OP, only from OPERATIONAL */
	TEST_ASSERT_EQUAL_INT(CO_NMT_ERR_PREOP, co_nmt_comm_error(x.node, 0));
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));
	co_nmt_local_cmd(x.node, CO_NMT_CS_STOP, 0);
	co_nmt_comm_error(x.node, 0);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_STOPPED, co_nmt_get_state(x.node));
	co_nmt_local_cmd(x.node, CO_NMT_CS_START, 0);
	co_nmt_comm_error(x.node, 0);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));
	/* 1: no change */
	co_od_set_u8(x.od, 0x1029, 1, 1);
	co_nmt_local_cmd(x.node, CO_NMT_CS_START, 0);
	TEST_ASSERT_EQUAL_INT(CO_NMT_ERR_NO_CHANGE, co_nmt_comm_error(x.node, 0));
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_OPERATIONAL, co_nmt_get_state(x.node));
	/* 2: STOPPED */
	co_od_set_u8(x.od, 0x1029, 1, 2);
	TEST_ASSERT_EQUAL_INT(CO_NMT_ERR_STOPPED, co_nmt_comm_error(x.node, 0));
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_STOPPED, co_nmt_get_state(x.node));
	int e = ecf_ev_find(&x, 0, CO_EV_NMT_STATE);
	TEST_ASSERT_TRUE(e >= 0);
	TEST_ASSERT_EQUAL_UINT8(0, x.ev.ev[x.ev.n - 1].u.nmt.cs);
}

static void test_error_behaviour_without_1029(void)
{
	co_od *od = NULL;
	TEST_ASSERT_EQUAL_INT(0, co_od_create(&od, 8));
	ecf_create(&x, ID, od);
	co_node_tick(x.node, 0);
	co_nmt_local_cmd(x.node, CO_NMT_CS_START, 0);
	TEST_ASSERT_EQUAL_INT(CO_NMT_ERR_PREOP, co_nmt_comm_error(x.node, 0));
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));
}

/* Bus-off (the line runtime reports it from the driver's error frames,
 * core/commfault.h) -> 1029h; after the recovery EMCY 8140h, then the
 * error reset since no error is left. */
static void test_bus_off(void)
{
	ecf_boot(&x, ID);
	co_nmt_local_cmd(x.node, CO_NMT_CS_START, 0);
	ecf_clear(&x);
	x.now = 5000;
	TEST_ASSERT_EQUAL_INT(0, co_commfault_bus_state(x.node, CO_BUS_LEVEL_BUS_OFF, x.now));
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));
	TEST_ASSERT_EQUAL_UINT(0, x.n_tx); /* nothing sent while bus-off */
	x.now = 9000;
	TEST_ASSERT_EQUAL_INT(0, co_commfault_bus_state(x.node, CO_BUS_LEVEL_ACTIVE, x.now));
	TEST_ASSERT_EQUAL_UINT(2, x.n_tx);
	const uint8_t exp[8] = { 0x40, 0x81, 0x11, 0, 0, 0, 0, 0 };
	const uint8_t reset[8] = { 0 };
	TEST_ASSERT_EQUAL_HEX32(0x80 + ID, x.tx[0].id);
	TEST_ASSERT_EQUAL_UINT8(8, x.tx[0].len);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(exp, x.tx[0].data, 8);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(reset, x.tx[1].data, 8);
	/* A second "active" without a bus-off sends nothing. */
	TEST_ASSERT_EQUAL_INT(0, co_commfault_bus_state(x.node, CO_BUS_LEVEL_ACTIVE, x.now));
	TEST_ASSERT_EQUAL_UINT(2, x.n_tx);
}

static void test_unconfigured_node_stays_initialising(void)
{
	ecf_create(&x, 255, ecf_od_std(1));
	co_node_tick(x.node, 0);
	TEST_ASSERT_EQUAL_UINT(0, x.n_tx);
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_INITIALISING, co_nmt_get_state(x.node));
}

static void test_strings(void)
{
	memset(&x, 0, sizeof(x));
	TEST_ASSERT_EQUAL_STRING("pre-operational", co_nmt_state_to_string(0x7F));
	TEST_ASSERT_EQUAL_STRING("operational", co_nmt_state_to_string(5));
	TEST_ASSERT_EQUAL_STRING("stopped", co_nmt_state_to_string(4));
	TEST_ASSERT_EQUAL_STRING("initialising", co_nmt_state_to_string(0));
	TEST_ASSERT_EQUAL_STRING("?", co_nmt_state_to_string(3));
	TEST_ASSERT_EQUAL_STRING("reset-comm", co_nmt_cs_to_string(0x82));
	TEST_ASSERT_EQUAL_STRING("nmt-state", co_event_kind_to_string(CO_EV_NMT_STATE));
	TEST_ASSERT_EQUAL_STRING("emcy-rx", co_event_kind_to_string(CO_EV_EMCY_RX));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_bootup_at_start);
	RUN_TEST(test_bootup_after_reset_comm_command);
	RUN_TEST(test_bootup_after_app_reset_comm);
	RUN_TEST(test_reset_while_initialising_announces_only_the_boot);
	RUN_TEST(test_commands_and_heartbeat_byte);
	RUN_TEST(test_reset_comm_restores_defaults);
	RUN_TEST(test_veto_operational);
	RUN_TEST(test_master_inhibit);
	RUN_TEST(test_master_self);
	RUN_TEST(test_error_behaviour);
	RUN_TEST(test_error_behaviour_without_1029);
	RUN_TEST(test_bus_off);
	RUN_TEST(test_unconfigured_node_stays_initialising);
	RUN_TEST(test_strings);
	return UNITY_END();
}
