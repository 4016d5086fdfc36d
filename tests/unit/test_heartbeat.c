/* SPDX-License-Identifier: MIT */
/* Heartbeat producer (1017h) and consumer (1016h), boot-up reception
 * (CiA 301 §7.2.8.3.2.2, §7.2.8.3.2.3, 1016h/1017h). */
#include <errno.h>
#include <string.h>

#include "core/emcy.h"
#include "core/heartbeat.h"
#include "core/nmt.h"
#include "tests/unit/support/errctrl_fixture.h"
#include "unity.h"

#define ID 5
#define HB_COB (0x700 + ID)
#define MS 1000u

static ecf x;

void setUp(void) {}
void tearDown(void)
{
	ecf_destroy(&x);
}

static void assert_last_sdo(const uint8_t exp[8])
{
	const co_frame *f = ecf_tx_last(&x, 0x580 + ID);
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_UINT8(8, f->len);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(exp, f->data, 8);
}

/* 1017h over SDO; the first heartbeat goes out at once. */
static void test_1017_sdo_write_first_hb_at_once(void)
{
	ecf_boot(&x, ID);
	x.now = 50 * MS;
	const uint8_t req[8] = { 0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0x00, 0x00 };
	const uint8_t rsp[8] = { 0x60, 0x17, 0x10, 0x00, 0x00, 0x00, 0x00, 0x00 };
	ecf_sdo_req(&x, req);
	assert_last_sdo(rsp);
	int hb = ecf_tx_find(&x, 0, HB_COB);
	TEST_ASSERT_TRUE(hb >= 0);
	TEST_ASSERT_EQUAL_UINT8(1, x.tx[hb].len);
	TEST_ASSERT_EQUAL_HEX8(0x7F, x.tx[hb].data[0]);
	TEST_ASSERT_EQUAL_UINT64(50 * MS, x.tx_t[hb]);
	/* Next one a period later, not before. */
	ecf_advance(&x, 1050 * MS - 1);
	TEST_ASSERT_EQUAL_UINT(1, ecf_tx_count(&x, HB_COB));
	ecf_advance(&x, 1050 * MS);
	TEST_ASSERT_EQUAL_UINT(2, ecf_tx_count(&x, HB_COB));
	ecf_advance(&x, 3050 * MS);
	TEST_ASSERT_EQUAL_UINT(4, ecf_tx_count(&x, HB_COB));
	/* 0 stops the producer at once. */
	const uint8_t off[8] = { 0x2B, 0x17, 0x10, 0x00, 0, 0, 0, 0 };
	ecf_sdo_req(&x, off);
	ecf_advance(&x, 10000 * MS);
	TEST_ASSERT_EQUAL_UINT(4, ecf_tx_count(&x, HB_COB));
}

/* After the boot-up the heartbeat follows one period later; a
 * STOPPED node still sends it (04). */
static void test_producer_after_boot_and_in_stopped(void)
{
	co_od *od = NULL;
	co_od_create(&od, 32);
	/* default 100 ms; the standard set keeps what exists */
	TEST_ASSERT_EQUAL_INT(0,
			      co_od_add_num(od, 0x1017, 0, CO_T_UNSIGNED16, CO_ACC_RW, 100, NULL));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_comm_defaults_hb(od, 4, 0));
	ecf_create(&x, ID, od);
	ecf_advance(&x, 0);
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	TEST_ASSERT_EQUAL_HEX8(0x00, x.tx[0].data[0]); /* boot-up only */
	ecf_advance(&x, 100 * MS);
	TEST_ASSERT_EQUAL_UINT(2, x.n_tx);
	TEST_ASSERT_EQUAL_HEX8(0x7F, x.tx[1].data[0]);
	TEST_ASSERT_EQUAL_UINT64(100 * MS, x.tx_t[1]);
	co_nmt_local_cmd(x.node, CO_NMT_CS_STOP, x.now);
	ecf_advance(&x, 200 * MS);
	TEST_ASSERT_EQUAL_HEX8(0x04, x.tx[x.n_tx - 1].data[0]);
	TEST_ASSERT_EQUAL_UINT64(200 * MS, x.tx_t[x.n_tx - 1]);
}

/* 1016h node 7 at 500 ms. */
static void test_consumer_start_loss_1029_emcy(void)
{
	ecf_boot(&x, ID);
	TEST_ASSERT_EQUAL_INT(0, co_hb_consumer_set(x.node, 7, 500, 0));
	uint32_t v = 0;
	co_od_get_u32(x.od, 0x1016, 1, &v);
	TEST_ASSERT_EQUAL_HEX32(0x000701F4, v);
	co_nmt_local_cmd(x.node, CO_NMT_CS_START, 0);
	ecf_clear(&x);

	/* No monitoring before the first heartbeat. */
	TEST_ASSERT_EQUAL_INT(CO_HB_MON_WAITING, co_hb_consumer_status(x.node, 7));
	ecf_advance(&x, 5000 * MS);
	TEST_ASSERT_EQUAL_UINT(0, ecf_ev_count(&x, CO_EV_HB_LOST));

	ecf_rx1(&x, 0x707, 0x05);
	int e = ecf_ev_find(&x, 0, CO_EV_HB_STARTED);
	TEST_ASSERT_TRUE(e >= 0);
	TEST_ASSERT_EQUAL_UINT8(7, x.ev.ev[e].u.errctrl.node);
	TEST_ASSERT_EQUAL_UINT16(500, x.ev.ev[e].u.errctrl.time_ms);
	TEST_ASSERT_EQUAL_INT(CO_HB_MON_ACTIVE, co_hb_consumer_status(x.node, 7));

	/* A heartbeat 400 ms later restarts the window. */
	ecf_advance(&x, 5400 * MS);
	ecf_rx1(&x, 0x707, 0x05);
	/* (the old 5500 ms deadline may still wake us early: allowed) */
	TEST_ASSERT_TRUE(co_node_next_deadline_us(x.node) <= 5900 * MS);
	ecf_advance(&x, 5900 * MS - 1);
	TEST_ASSERT_EQUAL_UINT(0, ecf_ev_count(&x, CO_EV_HB_LOST));
	TEST_ASSERT_EQUAL_UINT64(5900 * MS, co_node_next_deadline_us(x.node));
	TEST_ASSERT_EQUAL_UINT(0, x.n_tx);
	ecf_advance(&x, 5900 * MS);
	e = ecf_ev_find(&x, 0, CO_EV_HB_LOST);
	TEST_ASSERT_TRUE(e >= 0);
	TEST_ASSERT_EQUAL_UINT8(7, x.ev.ev[e].u.errctrl.node);
	TEST_ASSERT_EQUAL_UINT64(5900 * MS, x.ev.ev[e].now_us);
	/* EMCY 8130h, register generic|communication, node in byte 3 */
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	const uint8_t emcy[8] = { 0x30, 0x81, 0x11, 0x07, 0, 0, 0, 0 };
	TEST_ASSERT_EQUAL_HEX32(0x80 + ID, x.tx[0].id);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(emcy, x.tx[0].data, 8);
	/* 1029h default: OPERATIONAL -> PRE-OPERATIONAL */
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_PRE_OPERATIONAL, co_nmt_get_state(x.node));
	TEST_ASSERT_EQUAL_INT(CO_HB_MON_LOST, co_hb_consumer_status(x.node, 7));
	TEST_ASSERT_EQUAL_UINT(1, co_hb_lost_count(x.node));
	uint64_t lost[2];
	co_hb_lost_nodes(x.node, lost);
	TEST_ASSERT_EQUAL_HEX64(1ull << 7, lost[0]);
	TEST_ASSERT_EQUAL_HEX64(0, lost[1]);
	/* Reported once. */
	ecf_advance(&x, 9000 * MS);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&x, CO_EV_HB_LOST));

	/* It comes back: HB_STARTED again, error reset EMCY 0000h. */
	ecf_clear(&x);
	ecf_rx1(&x, 0x707, 0x05);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&x, CO_EV_HB_STARTED));
	TEST_ASSERT_EQUAL_UINT(0, co_hb_lost_count(x.node));
	co_hb_lost_nodes(x.node, lost);
	TEST_ASSERT_EQUAL_HEX64(0, lost[0] | lost[1]);
	const uint8_t reset[8] = { 0, 0, 0, 0, 0, 0, 0, 0 };
	TEST_ASSERT_EQUAL_UINT(1, x.n_tx);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(reset, x.tx[0].data, 8);
	TEST_ASSERT_EQUAL_UINT8(0, co_emcy_error_register(x.node));
}

/* 1029h:1 = 2 (stopped) on a heartbeat loss. */
static void test_consumer_loss_stopped(void)
{
	ecf_boot(&x, ID);
	co_od_set_u8(x.od, 0x1029, 1, CO_NMT_ERR_STOPPED);
	co_hb_consumer_set(x.node, 9, 100, 0);
	ecf_rx1(&x, 0x709, 0x7F);
	ecf_advance(&x, 100 * MS);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&x, CO_EV_HB_LOST));
	TEST_ASSERT_EQUAL_UINT8(CO_NMT_STOPPED, co_nmt_get_state(x.node));
	/* EMCY went out before the node stopped. */
	TEST_ASSERT_EQUAL_UINT(1, ecf_tx_count(&x, 0x80 + ID));
}

/* Boot-up from an unmonitored node -> BOOTUP; state change -> HB_STATE. */
static void test_bootup_and_state_from_any_node(void)
{
	ecf_boot(&x, ID);
	ecf_rx1(&x, 0x77F, 0x00);
	int e = ecf_ev_find(&x, 0, CO_EV_BOOTUP);
	TEST_ASSERT_TRUE(e >= 0);
	TEST_ASSERT_EQUAL_UINT8(127, x.ev.ev[e].u.errctrl.node);
	ecf_rx1(&x, 0x77F, 0x7F);
	ecf_rx1(&x, 0x77F, 0x7F); /* same state: no event */
	ecf_rx1(&x, 0x77F, 0x05);
	TEST_ASSERT_EQUAL_UINT(2, ecf_ev_count(&x, CO_EV_HB_STATE));
	e = ecf_ev_find(&x, 0, CO_EV_HB_STATE);
	e = ecf_ev_find(&x, (unsigned)e + 1, CO_EV_HB_STATE);
	TEST_ASSERT_EQUAL_UINT8(0x7F, x.ev.ev[e].u.errctrl.prev);
	TEST_ASSERT_EQUAL_UINT8(0x05, x.ev.ev[e].u.errctrl.state);
	TEST_ASSERT_EQUAL_UINT8(0x05, co_hb_remote_state(x.node, 127));
	TEST_ASSERT_EQUAL_UINT8(CO_HB_STATE_UNKNOWN, co_hb_remote_state(x.node, 3));
	/* Not monitored: no HB_STARTED, never lost. */
	TEST_ASSERT_EQUAL_UINT(0, ecf_ev_count(&x, CO_EV_HB_STARTED));
	ecf_advance(&x, 60000 * MS);
	TEST_ASSERT_EQUAL_UINT(0, ecf_ev_count(&x, CO_EV_HB_LOST));
}

/* A monitored node that reboots goes back to "waiting", no loss. */
static void test_bootup_of_monitored_node(void)
{
	ecf_boot(&x, ID);
	co_hb_consumer_set(x.node, 7, 200, 0);
	ecf_rx1(&x, 0x707, 0x05);
	ecf_advance(&x, 100 * MS);
	ecf_rx1(&x, 0x707, 0x00);
	TEST_ASSERT_EQUAL_INT(CO_HB_MON_WAITING, co_hb_consumer_status(x.node, 7));
	ecf_advance(&x, 2000 * MS);
	TEST_ASSERT_EQUAL_UINT(0, ecf_ev_count(&x, CO_EV_HB_LOST));
	ecf_rx1(&x, 0x707, 0x7F);
	TEST_ASSERT_EQUAL_UINT(2, ecf_ev_count(&x, CO_EV_HB_STARTED));
}

/* Consumer_set fails when 1016h is full, fills a free slot otherwise. */
static void test_consumer_set_full(void)
{
	ecf_boot(&x, ID);
	for (uint8_t n = 1; n <= 4; n++)
		TEST_ASSERT_EQUAL_INT(
			0, co_hb_consumer_set(x.node, (uint8_t)(10 + n), (uint16_t)(100 * n), 0));
	TEST_ASSERT_EQUAL_INT(-ENOSPC, co_hb_consumer_set(x.node, 20, 100, 0));
	/* Updating a node already present needs no free slot. */
	TEST_ASSERT_EQUAL_INT(0, co_hb_consumer_set(x.node, 12, 999, 0));
	uint32_t v = 0;
	co_od_get_u32(x.od, 0x1016, 2, &v);
	TEST_ASSERT_EQUAL_HEX32((12u << 16) | 999, v);
	/* Freeing one (time 0) makes room. */
	co_od_set_u32(x.od, 0x1016, 3, 0);
	TEST_ASSERT_EQUAL_INT(0, co_hb_consumer_set(x.node, 20, 150, 0));
	co_od_get_u32(x.od, 0x1016, 3, &v);
	TEST_ASSERT_EQUAL_HEX32((20u << 16) | 150, v);
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_hb_consumer_set(x.node, 0, 150, 0));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_hb_consumer_set(x.node, 128, 150, 0));
}

/* 1016h over SDO: duplicate node -> 0x06040043; a valid write applies. */
static void test_1016_sdo_validation(void)
{
	ecf_boot(&x, ID);
	const uint8_t w1[8] = { 0x23, 0x16, 0x10, 0x01, 0xF4, 0x01, 0x07, 0x00 };
	const uint8_t ok1[8] = { 0x60, 0x16, 0x10, 0x01, 0, 0, 0, 0 };
	ecf_sdo_req(&x, w1);
	assert_last_sdo(ok1);
	const uint8_t w2[8] = { 0x23, 0x16, 0x10, 0x02, 0x64, 0x00, 0x07, 0x00 };
	const uint8_t ab2[8] = { 0x80, 0x16, 0x10, 0x02, 0x43, 0x00, 0x04, 0x06 };
	ecf_sdo_req(&x, w2);
	assert_last_sdo(ab2);
	uint32_t v = 1;
	co_od_get_u32(x.od, 0x1016, 2, &v);
	TEST_ASSERT_EQUAL_HEX32(0, v);
	/* Reserved bits 31..24 */
	const uint8_t w3[8] = { 0x23, 0x16, 0x10, 0x02, 0x64, 0x00, 0x08, 0x01 };
	const uint8_t ab3[8] = { 0x80, 0x16, 0x10, 0x02, 0x30, 0x00, 0x09, 0x06 };
	ecf_sdo_req(&x, w3);
	assert_last_sdo(ab3);
	/* The SDO-written entry monitors at once. */
	TEST_ASSERT_EQUAL_INT(CO_HB_MON_WAITING, co_hb_consumer_status(x.node, 7));
	ecf_rx1(&x, 0x707, 0x7F);
	ecf_advance(&x, x.now + 500 * MS);
	TEST_ASSERT_EQUAL_UINT(1, ecf_ev_count(&x, CO_EV_HB_LOST));
}

/* Reset comm: the consumer goes back to waiting, losses are forgotten. */
static void test_reset_comm_clears_monitoring(void)
{
	co_od *od = NULL;
	co_od_create(&od, 32);
	/* 1016h:1 defaults to node 7, 100 ms */
	TEST_ASSERT_EQUAL_INT(0, co_od_add_num(od, 0x1016, 0, CO_T_UNSIGNED8, CO_ACC_RO, 2, NULL));
	TEST_ASSERT_EQUAL_INT(
		0, co_od_add_num(od, 0x1016, 1, CO_T_UNSIGNED32, CO_ACC_RW, 0x00070064, NULL));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_num(od, 0x1016, 2, CO_T_UNSIGNED32, CO_ACC_RW, 0, NULL));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_comm_defaults_hb(od, 4, 0));
	TEST_ASSERT_EQUAL_INT(0, co_od_add_comm_defaults_emcy(od, ID, 4, 0, 0));
	ecf_create(&x, ID, od);
	ecf_advance(&x, 0);
	ecf_rx1(&x, 0x707, 0x05);
	ecf_advance(&x, 100 * MS);
	TEST_ASSERT_EQUAL_UINT(1, co_hb_lost_count(x.node));
	TEST_ASSERT_TRUE(co_emcy_is_active(x.node, CO_EMCY_LIFE_GUARD));
	co_nmt_local_cmd(x.node, CO_NMT_CS_RESET_COMM, x.now);
	TEST_ASSERT_EQUAL_UINT(0, co_hb_lost_count(x.node));
	TEST_ASSERT_FALSE(co_emcy_is_active(x.node, CO_EMCY_LIFE_GUARD));
	TEST_ASSERT_EQUAL_INT(CO_HB_MON_WAITING, co_hb_consumer_status(x.node, 7));
}

static void test_strings(void)
{
	memset(&x, 0, sizeof(x));
	TEST_ASSERT_EQUAL_STRING("lost", co_hb_mon_to_string(CO_HB_MON_LOST));
	TEST_ASSERT_EQUAL_STRING("hb-lost", co_event_kind_to_string(CO_EV_HB_LOST));
	TEST_ASSERT_EQUAL_STRING("bootup", co_event_kind_to_string(CO_EV_BOOTUP));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_1017_sdo_write_first_hb_at_once);
	RUN_TEST(test_producer_after_boot_and_in_stopped);
	RUN_TEST(test_consumer_start_loss_1029_emcy);
	RUN_TEST(test_consumer_loss_stopped);
	RUN_TEST(test_bootup_and_state_from_any_node);
	RUN_TEST(test_bootup_of_monitored_node);
	RUN_TEST(test_consumer_set_full);
	RUN_TEST(test_1016_sdo_validation);
	RUN_TEST(test_reset_comm_clears_monitoring);
	RUN_TEST(test_strings);
	return UNITY_END();
}
